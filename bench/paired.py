"""Paired comparison of two methods on the same windows of a results table.

    from bench.paired import paired_comparison
    c = paired_comparison(df, "oracle/hough/lm", "oracle/harris/lm")   # c["median_diff"] < 0: hough better

Part of the results contract that bench/ writes and reports/ reads: both the report and the
sim-to-real table (bench.real.simreal) call it, so it lives on the producing side.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import wilcoxon

PAIR_KEY = ("house", "view", "window_id")


def paired_comparison(df: pd.DataFrame, a: str, b: str, column: str = "corner_err_px_snap"
                      ) -> dict:
    """Paired statistics of methods a and b on the same evaluable windows with both estimates.

    Returns {"n", "median_a", "median_b", "median_diff" (a - b, per window), "a_better" (fraction
    of windows where a < b), "p_value" (two-sided Wilcoxon signed-rank; NaN if n < 5 or all
    differences are zero)}.
    """
    ev = df[df["evaluable"].astype(bool)]
    key = [k for k in PAIR_KEY if k in ev.columns]
    A = ev[ev["method"] == a].set_index(key)[column]
    B = ev[ev["method"] == b].set_index(key)[column]
    j = pd.concat([A.rename("a"), B.rename("b")], axis=1, join="inner").dropna()
    d = (j["a"] - j["b"]).to_numpy(float)
    p = float("nan")
    if d.size >= 5 and np.any(d != 0):
        p = float(wilcoxon(j["a"], j["b"], zero_method="wilcox").pvalue)
    return {"n": int(d.size), "median_a": float(j["a"].median()) if d.size else float("nan"),
            "median_b": float(j["b"].median()) if d.size else float("nan"),
            "median_diff": float(np.median(d)) if d.size else float("nan"),
            "a_better": float(np.mean(d < 0)) if d.size else float("nan"), "p_value": p}
