"""Where the focal length came from on a bench run's K-withheld rows, and how far off it was (prints
figures; not a test).

    .venv/bin/python tools/focal_sources.py out/bench/wide-fov

Per detector of the run's K-withheld methods (``+noK``), one line per view (a view's focal length is
one answer, shared by its windows): the share of views per focal source (``K_source``: vanishing
points, prior, ...), and per source the relative focal error |f / f_true - 1| (median, p90), over
all houses and over the houses held out from that detector's training
(``lab.docs.roles.house_role``). Views without an evaluable window with a focal estimate
are left out (their count is printed).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

COLUMNS = ["house", "view", "detector", "method", "K_source", "focal_err_rel", "evaluable"]


def view_rows(results: pd.DataFrame) -> pd.DataFrame:
    """One row per (detector, method, house, view) of the K-withheld methods: its K source and focal
    error (the view's windows share them: the first evaluable window's)."""
    r = results[results.method.str.endswith("+noK") & results.evaluable & results.focal_err_rel.notna()]
    return r.groupby(["detector", "method", "house", "view"], as_index=False).first()


def source_lines(views: pd.DataFrame, label: str) -> list[str]:
    """Text lines: views per source and each source's focal error median / p90 (percent)."""
    if views.empty:
        return [f"  {label}: no view"]
    out = [f"  {label}: {len(views)} views"]
    for src, g in views.groupby("K_source"):
        e = 100 * g.focal_err_rel.to_numpy(float)
        out.append(f"    {src}: {len(g)} views ({100 * len(g) / len(views):.0f} %), focal error median "
                   f"{np.median(e):.1f} % p90 {np.percentile(e, 90):.1f} %")
    e = 100 * views.focal_err_rel.to_numpy(float)
    out.append(f"    chosen, all views: median {np.median(e):.1f} % p90 {np.percentile(e, 90):.1f} %")
    return out


def main(argv: list[str] | None = None) -> list[str]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="a finished bench run folder (results.parquet)")
    a = ap.parse_args(argv)
    path = a.run / "results.parquet"
    if not path.is_file():
        raise SystemExit(f"error: {path} not found: give a finished bench run folder")
    from lab.docs.roles import house_role  # noqa: PLC0415

    views = view_rows(pd.read_parquet(path, columns=COLUMNS))
    if views.empty:
        raise SystemExit(f"error: {a.run} has no K-withheld (+noK) rows with a focal estimate")
    lines = []
    for (det, method), g in views.groupby(["detector", "method"]):
        held = g[[house_role(det, h) == "held out" for h in g.house]]
        lines += [f"{method}:", *source_lines(g, "all houses"), *source_lines(held, "held-out houses")]
    print("\n".join(lines))
    return lines


if __name__ == "__main__":
    sys.exit(main() and 0)
