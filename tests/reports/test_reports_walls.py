"""fenestra/reports/walls.py on a hand-made results table with known answers."""
import numpy as np
import pandas as pd

from fenestra.reports.walls import calibration_rows, focal_rows, paired_rows, wall_sections


def _table():
    rows = []
    for i in range(5):
        base = {"house": "h", "view": f"{i:06d}", "window_id": "w", "evaluable": True, "detector": "oracle",
                "snapper": "none", "status": "ok"}
        rows.append({**base, "pose": "lm", "rot_err_deg": float(i + 1), "aspect_err_rel": 0.1 * (i + 1),
                     "focal_err_rel": np.nan, "aspect_in90": np.nan})
        rows.append({**base, "pose": "wall", "rot_err_deg": 0.5 * (i + 1), "aspect_err_rel": 0.01 * (i + 1),
                     "focal_err_rel": np.nan, "aspect_in90": float(i < 4), "rot_in90": 1.0, "trans_in90": 0.0,
                     "aspect_ci90_rel": 0.02, "rot_ci90_deg": 3.0})
        rows.append({**base, "pose": "wall+lines", "rot_err_deg": 0.25 * (i + 1) if i != 2 else 5.0,
                     "aspect_err_rel": 0.01 * (i + 1), "focal_err_rel": np.nan, "aspect_in90": np.nan})
        rows.append({**base, "pose": "wall+noK", "rot_err_deg": np.nan, "aspect_err_rel": np.nan,
                     "focal_err_rel": 0.01 * (i + 1) if i < 4 else np.nan, "aspect_in90": np.nan,
                     "status": "ok" if i < 4 else "failed"})
    df = pd.DataFrame(rows)
    df["method"] = df["detector"] + "/" + df["snapper"] + "/" + df["pose"]
    return df


def test_paired_focal_and_calibration_rows():
    df = _table()
    (row,) = paired_rows(df, "wall")
    assert row[:4] == ["oracle/none", 5, 3.0, 1.5]
    assert row[4] == np.percentile([1, 2, 3, 4, 5], 90) and row[5] == np.percentile([0.5, 1, 1.5, 2, 2.5], 90)
    assert row[8] == 1.0  # wall better on every window
    (f,) = focal_rows(df)
    assert f[0] == "oracle/none/wall+noK" and f[1] == 4 and f[2] == 0.025 and f[4] == 0.2
    (c,) = calibration_rows(df)
    assert c[:5] == ["oracle/none/wall", 5, 0.8, 1.0, 0.0]
    (lines,) = paired_rows(df, "wall+lines", "wall")
    assert lines[:4] == ["oracle/none", 5, 1.5, 1.0] and lines[8] == 0.8  # better on 4 of 5 windows
    # lm vs wall, lm vs wall+lines, wall vs wall+lines, focal, calibration
    assert [s[0] for s in wall_sections(df)].count("table") == 5
