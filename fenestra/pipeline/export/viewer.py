"""index.html: one page per ``fenestra reconstruct`` output folder that shows what the folder holds.

    from fenestra.pipeline.export.viewer import viewer_html, write_viewer
    html = viewer_html(read, files, glb=glb_bytes)   # pure: the page (a str) of a pipeline.readout.PhotoReadout
    write_viewer(out, read, files)                   # out/index.html, written atomically

The page shows the photo with the overlay (``overlay.png``), the model (``model.glb``) in 3D with
orbit controls (drag: turn, wheel: zoom, right-drag: pan), or, when there is no model, why not (the
export was off, it failed, no window was exported, the GLB is too large to embed), and one row per
window of windows.json with its status, sizes, K source and scale source; then links to the other files.

Opened from ``file://``, with nothing fetched from the network:

- three.js is vendored and pinned (``vendor/``: r187 reduced to WebGLRenderer, GLTFLoader and
  OrbitControls, one classic script; vendor/README.md says how it was made) and inlined in the page:
  Chromium loads no ES module from ``file://`` (the origin is ``null``), a classic inline script runs;
- the GLB is inlined too (base64, decoded in the page and given to ``GLTFLoader.parse``): a page
  from ``file://`` may not ``fetch()`` the files beside it in Chromium;
- ``overlay.png`` is referenced by name (an ``<img>`` loads a file beside the page): it is the
  photo's size, which the page need not copy.

Bounded: the page is the bundle (VENDOR_BYTES, some 0.6 MB), the GLB in base64 (4/3 of its size; its
texture is capped at pipeline.export.EXPORT_MAX_PX, so a GLB is at most some 50 MB) and a table row
per window; a GLB over VIEWER_MAX_GLB_BYTES is linked, not embedded, and the page says so.

The page's state, for tests and scripts: ``<body data-model>`` is ``loading`` until the GLB is parsed,
then ``loaded`` (with ``data-meshes``, the meshes in the scene, and ``data-textured``, those with a
decoded photo texture; ``document.title`` gains "| 3D model: N meshes"), ``error`` (the reason in the
page) or ``none`` (no model embedded).
"""
from __future__ import annotations

import base64
import html
from functools import lru_cache
from pathlib import Path

from fenestra.pipeline.readout import PhotoReadout
from fenestra.files import write_atomic

VENDOR = Path(__file__).resolve().parent / "vendor"
THREE_BUNDLE = VENDOR / "three-viewer.min.js"
VIEWER_MAX_GLB_BYTES = 64 * 2**20  # a larger model.glb is linked from the page, not embedded in it
PAGE = "index.html"


@lru_cache(maxsize=1)
def three_bundle() -> str:
    """The vendored three.js bundle (vendor/three-viewer.min.js), checked to be inlinable."""
    js = THREE_BUNDLE.read_text(encoding="utf-8")
    if "</script" in js.lower() or "<!--" in js:  # would end the inline <script> early
        raise ValueError(f"{THREE_BUNDLE} holds '</script' or '<!--': it cannot be inlined in the page")
    return js


def _e(v) -> str:
    return html.escape(str(v), quote=True)


def _num(v, fmt: str = ".3f") -> str:
    return "-" if v is None else format(float(v), fmt)


def no_model_reason(read: PhotoReadout, files: dict[str, str]) -> str | None:
    """Why the folder holds no model.glb (one sentence), or None when it holds one."""
    if "glb" in files:
        return None
    if read.export is not None and read.export.failure:
        return f"No 3D model: the export failed ({read.export.failure})."
    if "ifc" not in files:
        return "No 3D model: the model export was off (windows.json and the overlay only)."
    if not read.windows:
        return "No 3D model: no window was detected in the photo."
    return (f"No 3D model: none of the {read.detected} detected windows was exported ({read.flagged} flagged "
            f"implausible, {read.failed} failed; --export-all exports the flagged), and glTF holds no empty scene.")


def window_rows(read: PhotoReadout) -> list[list[str]]:
    """The window table's cells (plain text) per window, in detection order:
    # | status | score | confidence | aspect ratio [interval] | width x height m | wall | K source |
    scale source | why (failure, flags, why not exported: each reason once)."""
    rows = []
    for w in read.windows:
        iv = w.aspect_interval
        aspect = _num(w.aspect_ratio) + ("" if not iv else f" [{iv[0]:.3f}, {iv[1]:.3f}]")
        size = "-" if w.width_m is None or w.height_m is None else f"{w.width_m:.3f} x {w.height_m:.3f}"
        if w.partial:
            seen = "" if w.visible_fraction is None else f", {100 * w.visible_fraction:.0f} % of it seen"
            size += f" (cut by the photo's {', '.join(w.cut)} edge{seen})"
        scale = (w.scale_source or "-") + (" (assumed)" if w.scale_assumed and "assumed" not in (w.scale_source or "")
                                           else "")
        rows.append([str(w.index), w.status + (", partial" if w.partial else ""), _num(w.score, ".2f"),
                     _num(w.confidence, ".2f"), aspect, size, "-" if w.wall is None else str(w.wall), w.K_source or "-",
                     scale, "; ".join(w.reasons) or "-"])
    return rows


COLUMNS = ("#", "status", "score", "confidence", "aspect w/h [interval]", "width x height, m", "wall", "K source",
           "scale source", "why")

STYLE = """
body{font:14px/1.4 system-ui,sans-serif;margin:16px;color:#222;background:#fafafa}
h1{font-size:20px;margin:0 0 4px} .meta{margin:0 0 12px;color:#444}
.panels{display:grid;grid-template-columns:1fr 1fr;gap:12px;align-items:start}
figure{margin:0;background:#fff;border:1px solid #ccc;padding:6px}
figcaption{font-size:12px;color:#555;margin-top:4px}
#overlay{max-width:100%;max-height:520px;display:block;margin:auto}
#view{width:100%;height:520px;position:relative;background:#eee}
#view canvas{display:block;width:100%;height:100%}
.note{padding:12px;background:#fff3cd;border:1px solid #e0c060}
table{border-collapse:collapse;margin-top:14px;background:#fff;font-size:13px}
th,td{border:1px solid #ccc;padding:3px 6px;text-align:left;vertical-align:top}
th{background:#eee} td.n{text-align:right}
.failed{color:#b00} .warn{color:#a60}
"""

SCRIPT = """
(() => {
  const body = document.body, note = document.getElementById("model-note");
  const src = document.getElementById("fenestra-glb");
  if (!src) return;
  const fail = why => {
    body.dataset.model = "error";
    note.textContent = "The 3D model could not be shown: " + why;
    note.hidden = false;
  };
  window.addEventListener("error", e => {  // (a ResizeObserver notice is no failure)
    if (body.dataset.model === "loading" && !/ResizeObserver/.test(e.message || "")) fail(e.message);
  });
  try {
    const T = FenestraThree, box = document.getElementById("view");
    const renderer = new T.WebGLRenderer({antialias: true, preserveDrawingBuffer: true});
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    box.appendChild(renderer.domElement);
    const scene = new T.Scene();
    scene.background = new T.Color(0xeeeeee);
    scene.add(new T.HemisphereLight(0xffffff, 0x777777, 2.0));
    const sun = new T.DirectionalLight(0xffffff, 1.5);
    sun.position.set(1, 2, 3);
    scene.add(sun);
    const camera = new T.PerspectiveCamera(40, 1, 0.01, 1000);
    const controls = new T.OrbitControls(camera, renderer.domElement);
    const draw = () => renderer.render(scene, camera);
    const resize = () => {
      const w = Math.max(1, box.clientWidth), h = Math.max(1, box.clientHeight);
      renderer.setSize(w, h, false);  // the canvas's CSS size is the box's (100 %): no resize feedback
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
      draw();
    };
    controls.addEventListener("change", draw);
    new ResizeObserver(() => requestAnimationFrame(resize)).observe(box);
    const text = atob(src.textContent.trim()), bytes = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
    new T.GLTFLoader().parse(bytes.buffer, "", gltf => {
      const model = gltf.scene;
      let meshes = 0, textured = 0;
      model.traverse(o => {
        if (!o.isMesh) return;
        meshes++;
        const m = o.material;
        if (m && m.map) {  // the photo texture: shown as it is, not lit
          o.material = new T.MeshBasicMaterial({map: m.map, side: m.side, transparent: m.transparent,
                                                opacity: m.opacity});
          if (m.map.image && (m.map.image.width || 0) > 0) textured++;
        }
      });
      scene.add(model);
      // frame the model: seen from near the photo's camera (the export world's origin), turned a little
      const bounds = new T.Box3().setFromObject(model), centre = bounds.getCenter(new T.Vector3());
      const radius = Math.max(bounds.getBoundingSphere(new T.Sphere()).radius, 1e-3);
      const dir = new T.Vector3().sub(centre);
      if (!(dir.length() > 1e-9) || !isFinite(dir.length())) dir.set(0, 0, 1);
      dir.normalize().applyAxisAngle(new T.Vector3(0, 1, 0), 0.5);  // turned 29 deg about y (up): depth shows
      dir.y += 0.25;
      dir.normalize();
      const dist = 1.15 * radius / Math.sin(camera.fov * Math.PI / 360);
      camera.position.copy(centre).addScaledVector(dir, dist);
      camera.near = dist / 100;
      camera.far = dist * 100;
      controls.target.copy(centre);
      controls.update();
      resize();
      body.dataset.meshes = String(meshes);
      body.dataset.textured = String(textured);
      body.dataset.model = "loaded";
      document.title += " | 3D model: " + meshes + " meshes";
    }, err => fail((err && err.message) || String(err)));
  } catch (e) {
    fail((e && e.message) || String(e));
  }
})();
"""


def viewer_html(read: PhotoReadout, files: dict[str, str], glb: bytes | None = None,
                glb_note: str | None = None) -> str:
    """The page of one output folder (a str): ``read`` the photo's pipeline.readout.PhotoReadout,
    ``files`` {kind: file name} of the folder (``overlay``, ``glb``, ``ifc``, ...: windows.json's
    ``export.files``), ``glb`` the bytes of model.glb to embed (None: no 3D view; ``glb_note`` then
    says why, else :func:`no_model_reason`). Pure: reads nothing but the vendored three.js bundle
    (when a GLB is embedded)."""
    before, data, after = viewer_parts(read, files, glb, glb_note)
    return before + data.decode("ascii") + after


def viewer_parts(read: PhotoReadout, files: dict[str, str], glb: bytes | None = None,
                 glb_note: str | None = None) -> tuple[str, bytes, str]:
    """:func:`viewer_html` in three parts, (the page up to the GLB, the GLB in base64 (ASCII
    bytes; empty without a GLB), the rest), so that a writer holds one base64 copy of the GLB, not
    three (the bytes, a str of them, the page's str)."""
    photo = Path(str(read.photo or "photo")).name
    k = read.resolved.chosen
    lo, hi = k.interval_px
    meta = [f"K source: {_e(k.source)}" + (f" ({_e(k.detail)})" if k.detail else "")
            + f", f = {_num(k.focal_px, '.0f')} px [{_num(lo, '.0f')}, {_num(hi, '.0f')}]",
            "scale source: " + (_e("; ".join(read.scale_sources)) or "none")
            + (" (assumed)" if read.scale_assumed and not any("assumed" in s for s in read.scale_sources) else "")]
    W, H = read.image_size
    meta.append(f"photo {int(W)} x {int(H)} px" + (", undistorted" if read.distortion is not None else ""))
    warnings = [f'<li class="warn">warning: {_e(w)}</li>' for w in read.warnings]
    if read.geometry_failure:
        warnings.append(f'<li class="failed">geometry failed: {_e(read.geometry_failure)}</li>')

    overlay = files.get("overlay")
    left = (f'<figure><a href="{_e(overlay)}"><img id="overlay" src="{_e(overlay)}" alt="the photo with the '
            f'reconstructed windows drawn on it"></a><figcaption>{_e(overlay)}: quads (yellow: mask fit, magenta: '
            'snapped), the reprojected 3D windows (green), flagged (orange) and failed (red) windows; the panel '
            'lists each window</figcaption></figure>' if overlay else '<p class="note">No overlay.</p>')
    if glb is not None:
        right = (f'<figure><div id="view" title="drag: turn, wheel: zoom, right-drag: pan"></div>'
                 f'<p id="model-note" class="note" hidden></p><figcaption>{_e(files.get("glb", "model.glb"))} '
                 '(drag: turn, wheel: zoom, right-drag: pan)</figcaption></figure>')
        state = "loading"
    else:
        why = glb_note or no_model_reason(read, files) or "No 3D model embedded."
        right = f'<figure><p id="model-note" class="note">{_e(why)}</p></figure>'
        state = "none"

    rows = "".join("<tr" + (' class="failed"' if r[1] == "failed" else "") + ">"
                   + "".join(f'<td{" class=n" if i in (0, 2, 3) else ""}>{_e(c)}</td>' for i, c in enumerate(r))
                   + "</tr>" for r in window_rows(read))
    head = "".join(f"<th>{_e(c)}</th>" for c in COLUMNS)
    n = read.detected
    table = (f'<table id="windows"><caption>{n} window{"s" if n != 1 else ""} (windows.json)</caption>'
             f"<thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>")
    names = ["windows.json", *sorted({v for k, v in files.items() if v and v != PAGE})]
    links = " ".join(f'<a href="{_e(f)}">{_e(f)}</a>' for f in dict.fromkeys(names))

    glb_open, data, scripts = "", b"", ""
    if glb is not None:
        glb_open = '<script id="fenestra-glb" type="application/octet-stream">'
        data = base64.b64encode(glb)
        scripts = f"</script>\n<script>{three_bundle()}</script>\n<script>{SCRIPT}</script>"
    before = (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
              f'<meta name="viewport" content="width=device-width, initial-scale=1">'
              f"<title>Fenestra: {_e(photo)}</title><style>{STYLE}</style></head>\n"
              f'<body data-model="{state}"><h1>Fenestra: {_e(photo)}</h1>'
              f'<p class="meta">{" &middot; ".join(meta)}</p>'
              + (f"<ul>{''.join(warnings)}</ul>" if warnings else "")
              + f'<div class="panels">{left}{right}</div>\n{table}\n<p>Files: {links}</p>\n{glb_open}')
    return before, data, f"{scripts}\n</body></html>\n"


def write_viewer(out: str | Path, read: PhotoReadout, files: dict[str, str],
                 max_glb_bytes: int = VIEWER_MAX_GLB_BYTES) -> Path:
    """Write ``out``/index.html (atomically: fenestra.files.write_atomic; the GLB's base64 held once) for the folder's files
    (``files``: {kind: name}, as :func:`viewer_html`); model.glb is read from ``out`` and embedded
    when it is at most ``max_glb_bytes``, else linked with a note. Returns the path."""

    out = Path(out)
    glb, note = None, None
    if files.get("glb"):
        path = out / files["glb"]
        n = path.stat().st_size
        if n <= max_glb_bytes:
            glb = path.read_bytes()
        else:
            note = (f"{files['glb']} ({n / 2**20:.0f} MiB) is larger than this page embeds "
                    f"({max_glb_bytes / 2**20:.0f} MiB): open it in a glTF viewer.")
    parts = viewer_parts(read, files, glb, note)
    del glb

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            # a file name that is not UTF-8 (surrogate-escaped) shows as U+FFFD / "?", never fails the page
            f.write(parts[0].encode("utf-8", "replace"))
            f.write(parts[1])
            f.write(parts[2].encode("utf-8", "replace"))

    return write_atomic(out / PAGE, write)


__all__ = ["viewer_html", "viewer_parts", "write_viewer", "no_model_reason", "window_rows", "VIEWER_MAX_GLB_BYTES", "PAGE"]
