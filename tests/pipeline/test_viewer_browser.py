"""index.html of a `fenestra reconstruct` folder (pipeline.export.viewer) in a real headless
browser (Chromium, `make sysdeps`; tests/headless_browser.py), opened from file://: the embedded
model.glb loads (GLTFLoader's onLoad ran, with the GLB's meshes), the WebGL canvas drew it, the
overlay image decodes, the table lists the windows of windows.json with their K and scale sources,
nothing is fetched from the network; without a model the page says why.

The input is the README's quick start, the bundled curtain-wall photo examples/curtainwall/img017.jpg
with its calibration and pane masks (3 panes; the export's coordinates are not relied on).
"""
from __future__ import annotations

import hashlib
import json
import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh

from headless_browser import Browser, find_browser

import fenestra
from fenestra.pipeline.export import viewer

ROOT = Path(__file__).resolve().parents[2]
EX = ROOT / "examples" / "curtainwall"
LOAD_WAIT_MS = 40_000

# the page's state once the model has loaded or failed (or LOAD_WAIT_MS passed): see viewer.py
PAGE_STATE = """new Promise(resolve => {
  const t0 = Date.now();
  const tick = async () => {
    const b = document.body;
    if (b.dataset.model === "loading" && Date.now() - t0 < %d) { setTimeout(tick, 50); return; }
    const img = document.getElementById("overlay");
    if (img) await img.decode().catch(() => null);
    const rows = [...document.querySelectorAll("#windows tbody tr")].map(r => [...r.cells].map(c => c.textContent));
    const refs = [...document.querySelectorAll("[src],[href]")].map(e => e.getAttribute("src") || e.getAttribute("href"));
    resolve({model: b.dataset.model, meshes: Number(b.dataset.meshes || 0), textured: Number(b.dataset.textured || 0),
             title: document.title, note: (document.getElementById("model-note") || {}).textContent || "",
             overlay: img && {width: img.naturalWidth, height: img.naturalHeight},
             head: [...document.querySelectorAll("#windows thead th")].map(c => c.textContent), rows, refs,
             scriptSrc: document.querySelectorAll("script[src]").length});
  };
  tick();
})""" % LOAD_WAIT_MS

# what the 3D canvas shows: the share of its pixels that differ from the background, and how many
# distinct colours it holds (the photo texture: many)
CANVAS_STATE = """(() => {
  const c = document.querySelector("#view canvas");
  if (!c) return null;
  const k = document.createElement("canvas");
  k.width = c.width; k.height = c.height;
  const g = k.getContext("2d");
  g.drawImage(c, 0, 0);
  const d = g.getImageData(0, 0, k.width, k.height).data;
  let drawn = 0; const colours = new Set();
  for (let i = 0; i < d.length; i += 4) {
    if (Math.abs(d[i] - 238) + Math.abs(d[i + 1] - 238) + Math.abs(d[i + 2] - 238) > 24) drawn++;
    colours.add((d[i] >> 3) << 10 | (d[i + 1] >> 3) << 5 | (d[i + 2] >> 3));
  }
  return {width: c.width, height: c.height, drawn: drawn / (d.length / 4), colours: colours.size};
})()"""


def reconstruct(out: Path, export: bool = True):
    options = fenestra.PhotoOptions(snapper="none", known=fenestra.Known(window_width_m=0.0932), export=export)
    return fenestra.reconstruct_photo(EX / "img017.jpg", out, K_json=EX / "K.json", masks=EX / "panes017.png",
                                      options=options)


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> dict:
    return {}


@pytest.fixture(scope="module")
def folders(tmp_path_factory, results) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("viewer")
    results["model"] = reconstruct(root / "model")
    reconstruct(root / "no-export", export=False)
    # a photo whose one detection (a 2 x 2 px blob) fails: export on, nothing exported, no model.glb
    photo, masks = root / "blank.png", root / "blank-masks.png"
    cv2.imwrite(str(photo), np.full((240, 320, 3), 128, np.uint8))
    inst = np.zeros((240, 320), np.uint16)
    inst[100:102, 100:102] = 1
    cv2.imwrite(str(masks), inst)
    fenestra.reconstruct_photo(photo, root / "empty", masks=masks, options=fenestra.PhotoOptions(snapper="none"))
    return {"model": root / "model", "no-export": root / "no-export", "empty": root / "empty"}


@pytest.fixture(scope="module")
def browser(tmp_path_factory):
    # 1280 x 800: the page is taller than the window (a scroll bar takes width from the 3D view as it loads)
    b = Browser(find_browser(), tmp_path_factory.mktemp("chromium-profile"), PAGE_STATE,
                viewport={"width": 1280, "height": 800})
    yield b
    b.close()


def assert_model_shown(state: dict, canvas: dict | None, glb: Path) -> None:
    """The check of a page with a model: the GLB loaded (onLoad with the GLB's meshes and a decoded
    texture) and the canvas drew it. Fails for a page whose GLB did not load."""
    assert state["model"] == "loaded", f"model.glb did not load: data-model={state['model']!r} {state['note']!r}"
    scene = trimesh.load(str(glb), force="scene")
    n = len(scene.graph.nodes_geometry)  # one three.js mesh per glTF mesh node (one primitive each)
    assert state["meshes"] == n and n > 0, (state["meshes"], n)
    assert state["title"].endswith(f"| 3D model: {n} meshes")
    assert state["textured"] >= 1  # the photo texture was decoded
    assert canvas is not None and canvas["width"] > 100 and canvas["height"] > 100
    assert canvas["drawn"] > 0.05, canvas  # the model covers part of the view, not the background alone
    assert canvas["colours"] > 50, canvas  # the photo texture, not flat shading alone


def test_the_viewer_shows_the_glb_in_3d_and_fetches_nothing(folders, browser):
    out = folders["model"]
    browser.call("Network.enable", session=True)
    state = browser.open((out / "index.html").as_uri())
    requests = [e["params"]["request"]["url"] for e in browser.events if e.get("method") == "Network.requestWillBeSent"]
    browser.call("Network.disable", session=True)
    assert_model_shown(state, browser.evaluate(CANVAS_STATE), out / "model.glb")
    assert state["overlay"]["width"] > 0 and state["overlay"]["height"] > 0  # overlay.png, beside the page
    assert state["scriptSrc"] == 0  # the scripts are inline
    assert not [u for u in state["refs"] if re.match(r"^[a-z][a-z0-9+.-]*:", u) and not u.startswith("data:")]
    assert all(not re.match(r"^[a-z][a-z0-9+.-]*:", u) or u.split(":")[0] in ("file", "data", "blob") for u in requests)
    for name in state["refs"]:  # every file the page links is in the folder
        assert (out / name).is_file(), name


def test_the_table_lists_the_windows_of_windows_json(folders, browser):
    out = folders["model"]
    doc = json.loads((out / "windows.json").read_text())
    state = browser.open((out / "index.html").as_uri())
    head = state["head"]
    col = {name: head.index(name) for name in ("#", "status", "K source", "scale source")}
    assert len(doc["windows"]) == 3 and len(state["rows"]) == len(doc["windows"])
    for row, w in zip(state["rows"], doc["windows"]):
        assert row[col["#"]] == str(w["index"])
        assert row[col["K source"]] == w["K_source"] == doc["K_source"]["source"]
        assert row[col["scale source"]] == w["scale_source"] == "known window width 0.0932 m"
        assert row[col["status"]] == ("in the model" if w["exported"] else "not in the model")


def test_the_page_is_an_output_like_the_others(folders):
    """index.html is written into the staged folder, so the manifest lists it with its digest, and
    windows.json's export block names it."""
    for name, out in folders.items():
        manifest = json.loads((out / ".fenestra-output.json").read_text())["files"]
        page = out / "index.html"
        assert manifest["index.html"] == hashlib.sha256(page.read_bytes()).hexdigest(), name
        assert json.loads((out / "windows.json").read_text())["export"]["files"]["viewer"] == "index.html"
    # bounded: the bundle, the GLB in base64 and the table
    model = folders["model"]
    bound = viewer.THREE_BUNDLE.stat().st_size + 4 / 3 * (model / "model.glb").stat().st_size + 200_000
    assert (model / "index.html").stat().st_size < bound


def test_the_check_fails_when_the_glb_does_not_load(folders, browser, tmp_path):
    """The same page with its embedded GLB damaged: the page reports the error and the check above fails."""
    page = (folders["model"] / "index.html").read_text()
    broken = re.sub(r'(<script id="fenestra-glb"[^>]*>)[^<]*', lambda m: m.group(1) + "Z2xURgIAAAA=", page)
    assert broken != page
    for f in ("overlay.png", "model.glb"):
        shutil.copy(folders["model"] / f, tmp_path / f)
    (tmp_path / "index.html").write_text(broken)
    state = browser.open((tmp_path / "index.html").as_uri())
    assert state["model"] == "error" and "could not be shown" in state["note"]
    with pytest.raises(AssertionError, match="did not load"):
        assert_model_shown(state, browser.evaluate(CANVAS_STATE), folders["model"] / "model.glb")


@pytest.mark.parametrize("case, says", [("no-export", "export was off"),
                                        ("empty", "none of the 1 detected windows was exported")])
def test_without_a_model_the_page_shows_the_overlay_and_says_why(folders, browser, case, says):
    out = folders[case]
    assert not (out / "model.glb").exists()
    state = browser.open((out / "index.html").as_uri())
    assert state["model"] == "none" and says in state["note"], state["note"]
    assert state["overlay"]["width"] > 0
    assert len(state["rows"]) == len(json.loads((out / "windows.json").read_text())["windows"])
    assert "fenestra-glb" not in (out / "index.html").read_text()  # no bundle, no model: a small page
    assert (out / "index.html").stat().st_size < 100_000


def test_viewer_html_escapes_what_it_quotes(folders, results):
    """A real reconstruction's readout with hostile text put into its photo name, a failure, the
    focal source's detail and the export's failure: the page quotes each one escaped."""
    from dataclasses import replace

    from fenestra.pipeline.photo import ExportReport

    read = results["model"].readout()
    w0 = replace(read.windows[0], failure="quad: x", failure_message="<script>x</script>")
    chosen = replace(read.resolved.chosen, detail="<i>")
    read = replace(read, photo="a<b>.jpg", windows=(w0, *read.windows[1:]),
                   resolved=replace(read.resolved, chosen=chosen), export=ExportReport(failure="ValueError: <bad>"))
    page = viewer.viewer_html(read, {"overlay": "overlay.png"})
    assert "<b>" not in page and "<script>x" not in page and "<i>" not in page and "&lt;bad&gt;" in page
    assert "&lt;script&gt;x&lt;/script&gt;" in page and "a&lt;b&gt;.jpg" in page
    assert viewer.no_model_reason(read, {"overlay": "overlay.png"}).startswith("No 3D model: the export failed")


def test_each_reason_is_said_once_and_a_partial_window_is_marked(folders, results):
    """The table's "why" says a flag once, though the export decision's reason repeats it; a
    failed window's reason is its failure's sentence alone; a window cut by the photo's edge says so."""
    from dataclasses import replace

    read = results["model"].readout()
    w = replace(read.windows[0], flags=("too thin",), not_exported="implausible: too thin", failure=None,
                partial=True, cut=("left",), visible_fraction=0.6)
    row = viewer.window_rows(replace(read, windows=(w,)))[0]
    assert row[-1] == "too thin" and row[1].endswith(", partial")
    failed = replace(w, failure="quad: not_quadrilateral: four lines explain 56%", failure_message="the window's "
                     "outline is not four-sided", not_exported="upstream failure: quad: not_quadrilateral")
    assert viewer.window_rows(replace(read, windows=(failed,)))[0][-1] == "the window's outline is not four-sided"
    assert "cut by the photo's left edge, 60 % of it seen" in row[5]


def test_the_vendored_three_js_is_the_pinned_one():
    """vendor/: the bundle its README describes (sha256), the version VERSION and the banner name,
    and three.js's licence beside it."""
    vendor = viewer.VENDOR
    readme = (vendor / "README.md").read_text()
    assert hashlib.sha256(viewer.THREE_BUNDLE.read_bytes()).hexdigest() in readme
    assert (vendor / "VERSION").read_text().splitlines()[0] == "three 0.187.0"
    assert viewer.three_bundle().startswith("/*! three.js r187 (npm three@0.187.0)")
    assert "MIT License" in (vendor / "LICENSE").read_text() and "three.js authors" in (vendor / "LICENSE").read_text()


def test_a_glb_over_the_limit_is_linked_not_embedded(folders, results, tmp_path):
    for f in ("overlay.png", "model.glb", "windows.json"):
        shutil.copy(folders["model"] / f, tmp_path / f)
    doc = json.loads((tmp_path / "windows.json").read_text())
    page = viewer.write_viewer(tmp_path, results["model"].readout(), doc["export"]["files"], max_glb_bytes=1000).read_text()
    assert "fenestra-glb" not in page and 'data-model="none"' in page
    assert "is larger than this page embeds" in page and '<a href="model.glb">' in page
