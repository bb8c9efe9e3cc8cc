"""Paired comparison of two methods on the same windows of a results table.

    from fenestra.bench.paired import paired_comparison
    c = paired_comparison(df, "oracle/hough/lm", "oracle/harris/lm")   # c["median_diff"] < 0: hough better

Part of the results contract that bench/ writes and reports/ reads: both the report and the
sim-to-real table (bench.real.simreal) call it, so it lives on the producing side.
"""
from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.stats import wilcoxon

PAIR_KEY = ("house", "view", "window_id")


class PairedTable:
    """A results table's evaluable rows, split by method once and indexed by window
    (``PAIR_KEY``), so that many paired comparisons of its methods each cost only their own rows
    (a report compares hundreds of pairs of a table with a million rows)."""

    def __init__(self, df: pd.DataFrame) -> None:
        ev = df[df["evaluable"].astype(bool)]
        self.key = [k for k in PAIR_KEY if k in ev.columns]
        self._empty = ev.iloc[:0].set_index(self.key)
        self._by = {m: g.set_index(self.key) for m, g in ev.groupby("method", sort=False)}

    def rows(self, method: str) -> pd.DataFrame:
        """The method's evaluable rows, indexed by window (none if the table lacks the method)."""
        return self._by.get(method, self._empty)

    def compare(self, a: str, b: str, column: str = "corner_err_px_snap") -> dict:
        """:func:`paired_comparison` of methods a and b of this table."""
        A, B = self.rows(a)[column], self.rows(b)[column]
        j = pd.concat([A.rename("a"), B.rename("b")], axis=1, join="inner").dropna()
        d = (j["a"] - j["b"]).to_numpy(float)
        p = float("nan")
        if d.size >= 5 and np.any(d != 0):
            p = float(wilcoxon(j["a"], j["b"], zero_method="wilcox").pvalue)
        return {"n": int(d.size), "median_a": float(j["a"].median()) if d.size else float("nan"),
                "median_b": float(j["b"].median()) if d.size else float("nan"),
                "median_diff": float(np.median(d)) if d.size else float("nan"),
                "a_better": float(np.mean(d < 0)) if d.size else float("nan"), "p_value": p}


def paired_comparison(df: pd.DataFrame | PairedTable, a: str, b: str, column: str = "corner_err_px_snap"
                      ) -> dict:
    """Paired statistics of methods a and b on the same evaluable windows with both estimates.

    df: a results table, or its :class:`PairedTable` (made once for many comparisons).
    Returns {"n", "median_a", "median_b", "median_diff" (a - b, per window), "a_better" (fraction
    of windows where a < b), "p_value" (two-sided Wilcoxon signed-rank; NaN if n < 5 or all
    differences are zero)}.
    """
    table = df if isinstance(df, PairedTable) else PairedTable(df)
    return table.compare(a, b, column)
