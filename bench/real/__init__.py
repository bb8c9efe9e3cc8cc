"""The real-photo benchmark: labelled photographs scored beside the synthetic renders.

    contract.py   RealView / RealWindow: the per-view contract every adapter yields
    adapters.py   ADAPTERS = {"coco", "yolo", "labelmap", "curtainwall"}: folder -> RealViews
    metrics.py    truth-free and partial-truth metrics (relative pane size, reprojection consistency)
    evaluate.py   one RealView x every method -> rows (one per labelled window per method)
    profile.py    the ``real`` profile (bench/profiles/real.toml, ``kind = "real"``)
    runner.py     run_real(): results table, summary.json, report, as the synthetic runner
    simreal.py    the sim-to-real table: method rankings on renders vs photos, rank correlation
"""
