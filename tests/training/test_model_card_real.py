"""tools/model_card_real.py: the model card's real-photo table, its rows from evaluate_boxes results."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))
sys.path.insert(0, str(Path(__file__).resolve().parent))
import model_card_real  # noqa: E402


def _result(detector: str, n_images: int, n_gt: int, ap: float, ap50: float, n_det: int, n_hard: int,
            held: bool = True) -> dict:
    return {"detector": detector, "n_images": n_images, "n_gt": n_gt, "bbox": {"AP": ap, "AP50": ap50},
            "held_out": {"held_out": held, "why": "yes: H" if held else "**no**: N"},
            "hard_negatives": {"n_det_at_threshold": n_det, "n_hard_negative": n_hard,
                               "hard_negative_share": n_hard / n_det if n_det else float("nan"), "threshold": 0.5}}


def test_table_rows_by_hand():
    lines = model_card_real.table([("val", _result("default", 112, 944, 0.51449, 0.82751, 700, 13)),
                                   ("test", _result("winnet", 10, 101, 0.2, 0.4149, 0, 0))])
    assert lines[0].endswith("| detections at score >= 0.5 | on a door/signboard (n, %) |")
    assert lines[2] == "| val | `default` | yes: H | 112 | 944 | 51.4 | 82.8 | 700 | 13 (1.9 %) |"  # 13 / 700 = 1.857 %
    assert lines[3] == "| test | `winnet` | yes: H | 10 | 101 | 20.0 | 41.5 | 0 | 0 (-) |"
    assert len(lines) == 4


def test_counts_on_a_small_yolo_folder(tmp_path):
    """The real evaluation on two photos: photos and window boxes as the builder wrote them."""
    from user_datasets import curtain_panes, write_yolo

    n = write_yolo(tmp_path / "y", curtain_panes(2))
    from fenestra.training.evaluate import evaluate_boxes

    r = {**evaluate_boxes("default", tmp_path / "y", "all"), "held_out": {"held_out": True, "why": "yes"}}
    cells = model_card_real.table([("d", r)])[2].strip("|").split("|")
    assert [c.strip() for c in cells[:5]] == ["d", "`default`", "yes", "2", str(n)]
    assert int(cells[8].split("(")[0]) <= int(cells[7]) == r["hard_negatives"]["n_det_at_threshold"]


def test_held_out_only_when_the_weights_prove_it(tmp_path):
    """Issue #36: a photo is held out from weights that trained on no real photo, or that list their
    photos without it (by name, or by the bytes' sha256 under another name); weights that trained
    on real photos without listing them (the shipped ones, trained before the folder's cleaning) are
    not known to hold anything out. The sha256 here is computed by hashlib on the file written."""
    import hashlib

    a, b = tmp_path / "img_1.jpg", tmp_path / "img_2.jpg"
    a.write_bytes(b"photo one"), b.write_bytes(b"photo two")
    real = {"real_data": "spb/train", "real_fraction": 0.25}
    held = model_card_real.held_out
    assert held({"real_data": None, "real_fraction": 0.0}, {}, [a])["held_out"]
    assert not held(real, {}, [a])["held_out"]  # no list: not known
    assert "before its cleaning" in held(real, {"real_photos": None}, [a])["why"]
    other = [f"img_9.jpg {hashlib.sha256(b'another photo').hexdigest()}"]
    assert held(real, {"real_photos": other}, [a, b]) == {"held_out": True, "why": "yes: none of its 1 training photos"}
    by_name = other + [f"img_2.jpg {hashlib.sha256(b're-encoded').hexdigest()}"]
    by_bytes = other + [f"renamed.jpg {hashlib.sha256(b'photo one').hexdigest()}"]
    for listed in (by_name, by_bytes):
        v = held(real, {"real_photos": listed}, [a, b])
        assert not v["held_out"] and v["why"].startswith("**no**: 1 of these photos"), v


def test_without_the_photos_one_line_and_exit_2(tmp_path):
    r = subprocess.run([sys.executable, str(ROOT / "tools" / "model_card_real.py"), "--spb", str(tmp_path / "none")],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert r.stdout == "" and len(r.stderr.strip().splitlines()) == 1 and "none" in r.stderr


def test_readme_detector_line_quotes_its_sources():
    """The README's detector sentence: the held-out-families row of the summary, its seed spread and
    the real-photo rows, each figure where it belongs (values chosen so that no two round alike);
    same-generator and trained-on houses are not quoted."""
    rows = [{"house": "duplex", "role": "trained on", "trained": True, "together": False, "detection_rate": 0.947},
            {"house": "samplehouse4", "role": "held out", "trained": False, "together": False, "detection_rate": 1.0},
            {"house": "office-a", "role": "held out", "trained": False, "together": False, "detection_rate": 0.97},
            {"house": "procedural-0", "role": "same generator", "trained": False, "together": False, "detection_rate": 0.98},
            {"house": "held-out families", "role": "held out", "trained": False, "together": True, "detection_rate": 0.991,
             "all_corners_close": 0.834, "snap_median": 0.7961, "exact_snap_median": 0.1251, "aspect_p90": 0.1144},
            {"house": "same generator", "role": "same generator", "trained": False, "together": True,
             "detection_rate": 0.5, "all_corners_close": 0.5, "snap_median": 9.9, "exact_snap_median": 0.1, "aspect_p90": 0.9}]
    summary = {"synthetic": {"per_house": {"default": {"snapper": "refine", "pose": "wall+lines", "rows": rows}},
                             "provenance": {"seed": 3, "look_per": "view"}}}
    results = [("spb train, validation part", _result("default", 112, 944, 0.512, 0.827, 1393, 28)),
               ("spb test set", _result("default", 10, 101, 0.536, 0.877, 133, 4)),
               ("spb test set", _result("winnet", 10, 101, 0.22, 0.447, 459, 91))]
    text = model_card_real.detector_line(results, summary, "default")
    assert ("(`samplehouse4`, `office-a`: neither they nor their generator trained it; "
            "`make bench`, seed 3: a look drawn per view)") in text
    assert "procedural" not in text and "duplex" not in text and "9.90" not in text
    one_look = {**summary, "synthetic": {**summary["synthetic"], "provenance": {"seed": 0, "look_per": "set"}}}
    assert "`make bench`, seed 0: one random look per house)" in model_card_real.detector_line(results, one_look, "default")
    assert "photos its weights never trained on" in text and "training-set" not in text
    assert "finds 99 % of the evaluable windows, with all four corners within 5 px for 83 %" in text
    assert "after `refine` snapping (corner error median 0.80 px; exact masks 0.13 px)" in text
    assert "aspect-ratio error p90 of 11.4 % under `wall+lines`" in text
    assert "bbox AP50 82.7, AP 51.2 on the 112 validation photos" in text
    assert "bbox AP50 87.7, AP 53.6 on the 10 test photos, where 3.0 % of its detections" in text  # 4 / 133
    assert "Over seeds" not in text  # no spread given
    fig = lambda values: {"seeds": values, "median": sorted(values)[1], "min": min(values), "max": max(values)}  # noqa: E731
    spread = {"method": "default/refine/wall+lines", "command": "python tools/seed_spread.py --json X", "seeds": [0, 1, 2],
              "views_per_house": 40, "look_per": "view",
              "houses": {"samplehouse4": {"role": "held out", "figures": {}},
                         "procedural-0": {"role": "same generator", "figures": {}},
                         "held-out families": {"role": "held out", "figures": {
                             "detection_rate": fig([0.93, 0.88, 0.97]), "quad_rate": fig([0.9, 0.85, 0.95]),
                             "all_corners_close": fig([0.71, 0.64, 0.77]), "snap_median": fig([1.13, 1.42, 0.96]),
                             "rot_median": fig([0.31, 0.45, 0.27])}}}}
    text = model_card_real.detector_line(results, summary, "default", spread)
    assert ("Over seeds 0, 1, 2 (`samplehouse4`; 40 views per house and seed, a look drawn per view; "
            "`python tools/seed_spread.py --json X`), median [min–max] over the seeds: found 93 % [88–97], "
            "quads 90 % [85–95], all four corners within 5 px 71 % [64–77], corner median 1.13 px [0.96–1.42], "
            "rotation median 0.31° [0.27–0.45].") in text
    assert "Over seeds" not in model_card_real.detector_line(results, summary, "default", {**spread, "method": "winnet/a/b"})
    # weights that trained on the test photos' folder: the same figures, called training-set figures
    results[1] = ("spb test set", _result("default", 10, 101, 0.536, 0.877, 133, 4, held=False))
    text = model_card_real.detector_line(results, summary, "default")
    assert "bbox AP50 87.7, AP 53.6 on the 10 test photos" in text and "never trained on)" not in text
    assert "These are **training-set figures**" in text