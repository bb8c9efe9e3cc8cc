"""`fenestra reconstruct` / pipeline.reconstruct_photo on photos without intrinsics: always an
answer with its source, detections and failures always written (issue 24).

The street photos are the spb_facades test split in ../shared/real (not shipped: skipped when absent)."""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh

from fenestra.pipeline.cli import run_reconstruct

from spb import SPB, needs_spb as spb_mark

ROOT = Path(__file__).resolve().parents[2]
needs_spb = spb_mark(Path("images") / "img_185.jpg")


def test_blank_photo_without_K_is_written_with_its_failures(tmp_path):
    """A photo with no usable façade: no EXIF, no vanishing points; the prior answers, the one
    (too small) detection is written with its failure, and the overlay exists."""
    photo, masks = tmp_path / "blank.png", tmp_path / "masks.png"
    cv2.imwrite(str(photo), np.full((240, 320, 3), 128, np.uint8))
    inst = np.zeros((240, 320), np.uint16)
    inst[100:102, 100:102] = 1  # a 2 x 2 px blob: no quad
    cv2.imwrite(str(masks), inst)
    doc = run_reconstruct(photo, tmp_path / "out", masks=masks, snapper="none").to_json()
    saved = json.loads((tmp_path / "out" / "windows.json").read_text())
    assert saved["K_source"]["source"] == "prior" and saved["K_source"] == doc["K_source"]
    lo, hi = saved["K_source"]["interval_px"]
    assert lo < saved["K"][0][0] < hi
    assert len(saved["windows"]) == 1 and saved["windows"][0]["failure"]
    assert (tmp_path / "out" / "overlay.png").is_file()


@needs_spb
def test_street_photo_without_K_always_gives_an_output(tmp_path):
    """img_185 stopped with "focal length unobservable" and wrote nothing (issue 24)."""
    doc = run_reconstruct(SPB / "images" / "img_185.jpg", tmp_path / "out", export=False).to_json()
    saved = json.loads((tmp_path / "out" / "windows.json").read_text())
    assert saved["K_source"]["source"] in ("exif", "vanishing points", "prior")
    assert saved["K_source"]["interval_px"][0] <= doc["K"][0][0] <= saved["K_source"]["interval_px"][1]
    assert len(saved["windows"]) >= 5 and (tmp_path / "out" / "overlay.png").is_file()
    # each posed window's aspect interval holds its fit's 90 % interval (and the aspect ratios at the
    # ends of the focal interval: on this near-frontal façade they fall inside it), both about the
    # measured aspect ratio (``measured`` where its row's sill and head lines regularized it)
    posed = [w for w in saved["windows"] if w["failure"] is None and w["uncertainty"]]
    assert posed and all(w["aspect_interval"][0] <= w["uncertainty"]["aspect_lo"]
                         <= (w["measured"] or w)["aspect_ratio"]
                         <= w["uncertainty"]["aspect_hi"] <= w["aspect_interval"][1] for w in posed)
    keys = ["level", "sigma_px", "aspect_sd", "aspect_lo", "aspect_hi", "rot_deg", "trans_rel", "ill_conditioned"]
    assert all(list(w["uncertainty"]) == keys + ([] if w["plausible"] else ["widened"]) for w in posed)  # flagged: widened


def test_aspect_interval_joins_the_fit_and_the_focal_envelope():
    from fenestra.pipeline.readout import aspect_interval  # noqa: PLC0415

    from dataclasses import replace  # noqa: PLC0415

    from fenestra.pipeline.types import Failure, Uncertainty, WindowResult  # noqa: PLC0415

    w = WindowResult(index=3, score=0.9, quad_mask=None, quad_snapped=None, aspect_ratio=0.70, aspect_case=None,
                     focal_estimate_px=None, R=None, t=None, height_m=1.0, quad_reprojected=None, failure=None,
                     uncertainty=Uncertainty(0.9, 0.5, 0.012, 0.68, 0.72, 1.0, 0.02, False))
    assert aspect_interval(w, {}) == pytest.approx((0.68, 0.72))
    assert aspect_interval(w, {3: (0.61, 0.71)}) == pytest.approx((0.61, 0.72))  # f at the interval's ends
    assert aspect_interval(replace(w, failure=Failure("quad", None, "x"), aspect_ratio=None), {}) is None


def test_focal_envelope_follows_the_closed_form_aspect_at_the_focal_interval_ends():
    """A 1.2 x 1.6 m window seen 40 deg off-axis with f = 800 px: under f = 600 and 1000 px its
    quad's aspect ratio (Zhang & He, independent of the wall fit) moves; the envelope is those
    values shifted onto the window's own aspect ratio, and empty for an exact K."""
    from fenestra.conventions import look_at, project  # noqa: PLC0415
    from fenestra.pipeline.aspect import aspect_ratio  # noqa: PLC0415
    from fenestra.pipeline.session import focal_envelope  # noqa: PLC0415
    from fenestra.pipeline.types import WindowResult  # noqa: PLC0415

    K = np.array([[800.0, 0, 319.5], [0, 800.0, 239.5], [0, 0, 1]])
    R, t = look_at(np.array([5.0, 0.8, 6.0]), np.array([0.6, 0.8, 0.0]), up=(0.0, 1.0, 0.0))
    q = project(K, R, t, np.array([[0, 1.6, 0], [1.2, 1.6, 0], [1.2, 0, 0], [0, 0, 0.0]]))
    r = WindowResult(0, 0.9, q, q, 0.75, "general", None, np.eye(3), np.ones(3), 1.0, q, None)
    Kf = [np.diag([f, f, 1.0]) + np.array([[0, 0, 319.5], [0, 0, 239.5], [0, 0, 0]]) for f in (600.0, 1000.0)]
    truth = sorted(aspect_ratio(q, k).ratio for k in Kf)
    lo, hi = focal_envelope([r], K, (600.0, 1000.0))[0]
    assert aspect_ratio(q, K).ratio == pytest.approx(0.75, rel=1e-6)
    assert lo == pytest.approx(min(truth[0], 0.75)) and hi == pytest.approx(max(truth[1], 0.75))
    assert hi - lo > 0.02  # oblique: the focal length matters
    assert focal_envelope([r], K, (800.0, 800.0)) == {}


def test_quick_start_exports_its_panes_in_one_wall_with_property_sets(tmp_path):
    """The README's quick-start (1:25 curtain wall, 9.3 cm panes, smaller than any catalogue style)
    exported 0 windows; now every pane, voiding one IfcWall, with Pset_WindowCommon and Fenestra psets."""
    import ifcopenshell  # noqa: PLC0415
    import ifcopenshell.util.element  # noqa: PLC0415

    ex = ROOT / "examples" / "curtainwall"
    doc = run_reconstruct(ex / "img017.jpg", tmp_path / "out", K_json=ex / "K.json", masks=ex / "panes017.png",
                          snapper="linefit", width=0.0932).to_json()
    assert len(doc["windows"]) == 3 and all(w["exported"] for w in doc["windows"])
    f = ifcopenshell.open(str(tmp_path / "out" / "model.ifc"))
    walls, windows = f.by_type("IfcWall"), f.by_type("IfcWindow")
    assert len(walls) == 1 and len(windows) == 3
    voids = f.by_type("IfcRelVoidsElement")
    assert len(voids) == 3 and all(v.RelatingBuildingElement == walls[0] for v in voids)
    assert len(f.by_type("IfcRelFillsElement")) == 3
    psets = ifcopenshell.util.element.get_psets(windows[0])
    assert psets["Pset_WindowCommon"]["IsExternal"] is True
    fen = psets["Fenestra_Window"]
    assert fen["KSource"] == "K" and fen["ScaleSource"] == "known window width 0.0932 m" and not fen["ScaleAssumed"]
    assert fen["AspectLow"] < fen["AspectRatio"] < fen["AspectHigh"] and 0 < fen["Confidence"] <= 1
    w0 = doc["windows"][0]  # the user's K is exact: the interval is the fit's own
    assert w0["aspect_interval"] == pytest.approx([w0["uncertainty"]["aspect_lo"], w0["uncertainty"]["aspect_hi"]])
    assert ifcopenshell.util.element.get_psets(walls[0])["Fenestra_Wall"]["WindowCount"] == 3
    # OBJ and GLB hold the same one wall: one closed, photo-textured slab with the three panes' voids
    scene = trimesh.load(str(tmp_path / "out" / "model.glb"), force="scene")
    slabs = [n for n in scene.geometry if n.startswith("wall_")]
    assert len(slabs) == 1 and slabs[0].startswith("wall_w"), slabs  # the fitted wall, not a pane's fragment
    slab = scene.geometry[slabs[0]]
    assert slab.is_watertight and slab.volume > 0
    obj_walls = [ln for ln in (tmp_path / "out" / "model.obj").read_text().splitlines()
                 if ln.startswith(("o wall_", "g wall_"))]
    assert len(obj_walls) == 1, obj_walls


def test_python_api_returns_what_windows_json_holds(tmp_path):
    """pipeline.reconstruct_photo (the documented API) gives the typed result whose to_json() is the
    dict the CLI writes as windows.json."""
    import fenestra as pipeline  # noqa: PLC0415  (the public API)

    assert "reconstruct_photo" in pipeline.__all__ and "windows.json" in pipeline.__doc__
    ex = ROOT / "examples" / "curtainwall"
    kw = dict(K_json=ex / "K.json", masks=ex / "panes017.png",
              options=pipeline.PhotoOptions(snapper="none", known=pipeline.Known(window_width_m=0.0932), export=False))
    result = pipeline.reconstruct_photo(ex / "img017.jpg", **kw)
    assert result.export is None and len(result.reconstruction.windows) == len(result.to_json()["windows"])
    doc = result.to_json()
    written = pipeline.reconstruct_photo(ex / "img017.jpg", tmp_path / "o", **kw).to_json()
    saved = json.loads((tmp_path / "o" / "windows.json").read_text())
    assert not (tmp_path / "o" / "model.ifc").exists()  # export=False: windows.json and the overlay only
    assert (tmp_path / "o" / "overlay.png").is_file()
    written.pop("export")
    saved.pop("export")
    for d in (doc, written, saved):  # the one thing that differs between runs: measured times
        for w in d["windows"]:
            w.pop("timings_ms")
    assert json.loads(json.dumps(doc)) == json.loads(json.dumps(written)) == saved
    assert all(w["exported"] is None for w in saved["windows"])


def test_expand_photos_files_folders_globs(tmp_path):
    from fenestra.errors import PipelineError  # noqa: PLC0415
    from fenestra.pipeline.cli import expand_photos, output_names  # noqa: PLC0415

    (tmp_path / "a").mkdir()
    for name in ("a/x.jpg", "a/y.PNG", "a/notes.txt", "z.jpg"):
        (tmp_path / name).write_bytes(b"")
    got = expand_photos([str(tmp_path / "a"), str(tmp_path / "*.jpg"), str(tmp_path / "a" / "x.jpg")])
    assert [p.relative_to(tmp_path).as_posix() for p in got] == ["a/x.jpg", "a/y.PNG", "z.jpg"]
    with pytest.raises(PipelineError, match="no photo found"):
        expand_photos([str(tmp_path / "missing*.jpg")])
    assert output_names([Path("a/x.jpg"), Path("b/x.jpg"), Path("c/y.jpg")]) == ["a_x", "b_x", "y"]


def test_reconstruct_command_on_a_folder_writes_one_folder_per_photo_and_a_summary(tmp_path):
    """The command on a folder of two photos and one unreadable file: a progress bar, one output
    folder per readable photo, the bad one in the summary with its error, exit code 1."""
    import typer  # noqa: PLC0415
    from typer.testing import CliRunner  # noqa: PLC0415

    from fenestra.pipeline import cli as pipeline_cli  # noqa: PLC0415

    app = typer.Typer()
    pipeline_cli.register(app)
    folder = tmp_path / "photos"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for name in ("one.png", "two.png"):
        cv2.imwrite(str(folder / name), rng.integers(0, 255, (160, 200, 3), dtype=np.uint8))
    (folder / "broken.jpg").write_bytes(b"not a photo")
    res = CliRunner().invoke(app, ["reconstruct", str(folder), "--out", str(tmp_path / "out")])
    assert res.exit_code == 1, res.output
    rows = {Path(r["photo"]).name: r for r in json.loads((tmp_path / "out" / "summary.json").read_text())}
    assert set(rows) == {"one.png", "two.png", "broken.jpg"} and rows["broken.jpg"]["error"]
    for stem in ("one", "two"):
        assert rows[f"{stem}.png"]["error"] is None and rows[f"{stem}.png"]["K_source"] == "prior"
        assert (tmp_path / "out" / stem / "windows.json").is_file() and (tmp_path / "out" / stem / "overlay.png").is_file()
    assert "2 of 3 photos reconstructed" in res.output


def test_version_comes_from_the_package_metadata():
    from importlib.metadata import version  # noqa: PLC0415

    import fenestra  # noqa: PLC0415

    assert fenestra.__version__ == version("fenestra")


def test_overlay_draws_a_failed_detection_where_it_is_and_lists_it_in_the_panel():
    from fenestra.pipeline.export.overlay import COLOURS, draw_overlay  # noqa: PLC0415
    from fenestra.pipeline.types import Failure, WindowResult  # noqa: PLC0415

    photo = np.full((240, 320, 3), 128, np.uint8)
    failed = WindowResult(0, 0.7, None, None, None, None, None, None, None, 1.0, None,
                          Failure("quad", "too_small", "12 px"))
    K = np.array([[300.0, 0, 159.5], [0, 300.0, 119.5], [0, 0, 1]])
    img = draw_overlay(photo, K, [failed], boxes={0: (50, 120, 150, 200)}, header=["K: prior"])
    assert img.shape[0] >= 240 and img.shape[1] > 320  # the photo, then the side panel
    box_edge = img[160, 48:53]  # the left edge of the detection box, mid-height
    assert any(np.abs(p.astype(int) - COLOURS["failed"]).sum() < 60 for p in box_edge)
    assert np.array_equal(img[10:100, 200:300], photo[10:100, 200:300])  # nothing drawn away from it
    panel = img[:, 320:]
    red = np.abs(panel.astype(int) - COLOURS["failed"]).sum(axis=2) < 60
    assert red.sum() > 50  # the panel lists the failure (and the legend's red key)


def test_an_implausible_sign_is_flagged_and_left_out_unless_export_all(tmp_path):
    """Six 60 x 90 px windows and a 460 x 50 px sign (w/h 9.2) on one flat façade: the sign is flagged
    with its reasons and left out of model.ifc; --export-all keeps it (still flagged)."""
    import ifcopenshell  # noqa: PLC0415

    img, inst = np.full((480, 640, 3), 200, np.uint8), np.zeros((480, 640), np.uint16)
    boxes = [(x, y, x + 60, y + 90) for y in (100, 260) for x in (100, 250, 400)] + [(100, 380, 560, 430)]
    for i, (x0, y0, x1, y1) in enumerate(boxes, 1):
        img[y0:y1, x0:x1], inst[y0:y1, x0:x1] = 40, i
    cv2.imwrite(str(tmp_path / "p.png"), img)
    cv2.imwrite(str(tmp_path / "m.png"), inst)
    for export_all in (False, True):
        out = tmp_path / f"out{export_all}"
        doc = run_reconstruct(tmp_path / "p.png", out, masks=tmp_path / "m.png", snapper="none", export_all=export_all).to_json()
        sign = doc["windows"][6]
        assert sign["aspect_ratio"] == pytest.approx(460 / 50, rel=0.02)
        assert not sign["plausible"] and any("windows are 0.2 to 4)" in f for f in sign["flags"])
        assert sign["exported"] is export_all and all(w["exported"] for w in doc["windows"][:6])
        assert len(ifcopenshell.open(str(out / "model.ifc")).by_type("IfcWindow")) == 6 + export_all
        assert doc["scale"]["assumed"] and len(doc["walls"]) == 1
