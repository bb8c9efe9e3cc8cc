"""One session, two callers (issue 33): `fenestra reconstruct` (reconstruct_photo) and the bench
(evaluate_view) give the same windows for the CLI's method.

On 20 rendered views of a bundled house, with K given (a K.json beside the photo, as a user gives
it) and with K withheld (the focal chain), every bench row of the CLI method that reconstructed a
window is found in the photo's windows.json with the very same snapped quad, and agrees with it
on the aspect ratio, the rotation, the K used and where it came from, the metric size (the
façade model's scale) and the export decision. The aspect ratio as measured (a window whose row's
sill and head lines regularized it, pipeline.row_lines, keeps its measured values in windows.json's
``measured``); the metric size as exported (the regularized window a BIM user gets). The truth the rows are measured against (corners,
window sizes, poses) is read from view.json here, independently of the code under test.

Both callers run with one torch thread (the bench's workers do; a user's run uses the machine's
cores, and torch's float reductions, so the networks' last bits, depend on the thread count).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from fenestra.conventions import DEFAULTS, rotation_error_deg
from fenestra.methods import Method

N_VIEWS = 20


@pytest.fixture(scope="module")
def view_dirs(tmp_path_factory) -> list[Path]:
    from fenestra.renders.dataset import DatasetConfig, render_dataset

    root = render_dataset(DatasetConfig(scene="fzk-haus", n_views=N_VIEWS, seed=5,
                                        out_root=str(tmp_path_factory.mktemp("renders"))), progress=False)
    dirs = sorted(p for p in (Path(root) / "views").iterdir() if (p / "view.json").is_file())
    assert len(dirs) == N_VIEWS
    return dirs


def truth(view_dir: Path) -> dict:
    """{window id: (corners px (4, 2), (width, height) m, true window-to-camera R)} from view.json."""
    meta = json.loads((view_dir / "view.json").read_text())
    R_cam = np.asarray(meta["R"], dtype=np.float64)
    out = {}
    for w in meta["windows"]:
        Cw = np.asarray(w["corners_world"], dtype=np.float64)  # TL TR BR BL
        x = (Cw[1] - Cw[0]) / np.linalg.norm(Cw[1] - Cw[0])  # along the wall
        y = (Cw[0] - Cw[3]) / np.linalg.norm(Cw[0] - Cw[3])  # up
        R_win = R_cam @ np.column_stack([x, y, np.cross(x, y)])
        out[w["id"]] = (np.asarray(w["corners_px"], dtype=np.float64),
                        (float(np.linalg.norm(Cw[1] - Cw[0])), float(np.linalg.norm(Cw[0] - Cw[3]))), R_win)
    return out


@pytest.mark.parametrize("withhold_K", [False, True], ids=["K given", "K withheld"])
def test_reconstruct_photo_gives_the_bench_rows_of_the_cli_method(view_dirs, tmp_path, monkeypatch, withhold_K):
    from fenestra import PhotoOptions, reconstruct_photo
    from fenestra.bench.evaluate import EvalOptions, evaluate_view
    from fenestra.bench.render_adapter import read_rendered_view

    from fenestra.pipeline.detectors import set_cpu_threads

    monkeypatch.setenv("OMP_NUM_THREADS", "1")  # what the bench's workers have (bench.executors.thread_env)
    set_cpu_threads(1)
    method = Method(DEFAULTS.detector, DEFAULTS.snapper, DEFAULTS.pose, withhold_K=withhold_K)
    compared, regularized, sources = 0, 0, set()
    for vd in view_dirs:
        meta = json.loads((vd / "view.json").read_text())
        K_json = None
        if not withhold_K:
            K_json = tmp_path / f"{vd.name}-K.json"
            K_json.write_text(json.dumps({"K": meta["K"], "width": meta["width"], "height": meta["height"]}))
        doc = reconstruct_photo(vd / "image.png", K_json=K_json, options=PhotoOptions()).to_json()
        rows = evaluate_view(read_rendered_view(vd, "fzk-haus", meta["renderer"]), (method,), EvalOptions()).rows
        gt = truth(vd)
        for row in (r for r in rows if r["status"] == "ok"):
            quad_gt, (w_gt, h_gt), R_gt = gt[row["window_id"]]
            same = [w for w in doc["windows"] if w["quad_snapped"] is not None and np.mean(np.linalg.norm(
                np.asarray(w["quad_snapped"]) - quad_gt, axis=1)) == row["corner_err_px_snap"]]
            assert len(same) == 1, (vd.name, row["window_id"], len(same))
            w = same[0]
            m = w["measured"] or w  # the window as measured, before its row's regularization
            assert w["failure"] is None and m["aspect_ratio"] == row["aspect_est"]
            assert rotation_error_deg(np.asarray(w["R"]), R_gt) == pytest.approx(row["rot_err_deg"], abs=1e-9)
            assert doc["K"][0][0] == row["K_focal_px"] and doc["K_source"]["source"] == row["K_source"]
            assert abs(w["width_m"] - w_gt) == pytest.approx(row["width_err_m"], abs=1e-12)  # the BIM errors: as exported
            assert abs(w["height_m"] - h_gt) == pytest.approx(row["height_err_m"], abs=1e-12)
            assert w["height_measured_m"] == m["height_m"]
            regularized += w["measured"] is not None and w["height_m"] != m["height_m"]
            assert float(w["exported"]) == row["exported"] and w["scale_assumed"] == (row["scale_source"] == "assumed")
            compared += 1
            sources.add(row["K_source"])
    assert compared >= N_VIEWS  # the test compared windows (28 with K given at seed 5), not nothing
    assert regularized > 0  # some rows measured a window whose exported height differs from its measured one
    assert sources == {"K"} if not withhold_K else "K" not in sources


def test_model_storeys_are_the_houses_floors(view_dirs, tmp_path, monkeypatch):
    """Every view through `fenestra reconstruct` with K and the house's storey height given: model.ifc's
    storeys are named Ground floor, Floor 1, ... at least MIN_STOREY_M apart, every IfcWindow and IfcDoor is
    contained in one, and every exported whole window of the main wall (the one with most) is in floor k
    where k is the FZK-Haus storey its sill stands in (its IFC's IfcBuildingStorey elevations, read here:
    the ground floor's windows on the ground floor; the roof storey's are dormers and roof windows, on
    other planes)."""
    import ifcopenshell  # noqa: PLC0415

    from fenestra import PhotoOptions, reconstruct_photo
    from fenestra.conventions import MIN_STOREY_M
    from fenestra.pipeline.detectors import set_cpu_threads
    from fenestra.pipeline.facade_model import Known

    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    set_cpu_threads(1)
    house = ifcopenshell.open(str(Path(__file__).resolve().parents[2] / "fenestra" / "scenes" / "ifc" / "AC20-FZK-Haus.ifc"))
    levels = sorted(float(s.Elevation) for s in house.by_type("IfcBuildingStorey"))
    storey_m = levels[1] - levels[0]
    compared = 0
    for vd in view_dirs:
        meta = json.loads((vd / "view.json").read_text())
        K_json = tmp_path / f"{vd.name}-K.json"
        K_json.write_text(json.dumps({"K": meta["K"], "width": meta["width"], "height": meta["height"]}))
        out = tmp_path / vd.name
        doc = reconstruct_photo(vd / "image.png", out, K_json=K_json,
                                options=PhotoOptions(known=Known(storey_m=storey_m))).to_json()
        storeys = json.loads((out / "export.json").read_text())["storeys"]
        floors = storeys["floors"]
        assert [f["name"] for f in floors] == ["Ground floor"] + [f"Floor {k}" for k in range(1, len(floors))]
        assert all(b["elevation_m"] - a["elevation_m"] >= MIN_STOREY_M for a, b in zip(floors, floors[1:]))
        ifc = ifcopenshell.open(str(out / "model.ifc"))
        assert len(ifc.by_type("IfcBuildingStorey")) == len(floors)
        for e in list(ifc.by_type("IfcWindow")) + list(ifc.by_type("IfcDoor")):
            assert len(e.ContainedInStructure) == 1 and e.ContainedInStructure[0].RelatingStructure.is_a("IfcBuildingStorey")
        floor_of = {i: k for k, f in enumerate(floors) for i in f["windows"]}
        true_storey = {}
        for w in meta["windows"]:  # the house's storey each labelled window's sill stands in
            sill = min(np.asarray(w["corners_world"], dtype=np.float64)[:, 2])
            true_storey[w["id"]] = max(k for k, e in enumerate(levels) if e <= sill + 0.01)
        gt = truth(vd)
        main = storeys["main_wall"]
        pairs = []
        for w in doc["windows"]:
            if not w["exported"] or w["partial"] or w["wall"] != main or w["quad_snapped"] is None:
                continue
            err = {k: np.mean(np.linalg.norm(np.asarray(w["quad_snapped"]) - q, axis=1)) for k, (q, _, _) in gt.items()}
            k = min(err, key=err.get)
            if err[k] < 5.0:
                pairs.append((true_storey[k], floor_of[w["index"]]))
        assert all(storey == floor for storey, floor in pairs), (vd.name, pairs)
        compared += len(pairs)
    assert compared >= N_VIEWS  # windows were compared (26 at seed 5), not none
