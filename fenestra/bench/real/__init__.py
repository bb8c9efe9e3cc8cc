"""The real-photo bench's own parts: labelled photographs scored beside the synthetic renders.

    adapters.py   ADAPTERS = {"coco", "yolo", "labelmap", "curtainwall"}: folder -> bench.views.LabelledViews
    profile.py    the ``real`` profile (fenestra/bench/profiles/real.toml, ``kind = "real"``): datasets, methods
    simreal.py    the sim-to-real table: method rankings on renders vs photos, rank correlation

Everything else is the bench's one path: bench.views (the labelled view), bench.evaluate
(evaluate_view), bench.runner (run_benchmark), bench.detection_ap, bench.metrics.
"""
