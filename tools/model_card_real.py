"""The model card's real-photo rows: the shipped detectors on the St Petersburg street photos.

    .venv/bin/python tools/model_card_real.py [--spb ../shared/real/spb_facades] [--detectors default,winnet] \
        [--doc fenestra/pipeline/models/README.md --block real-photos] [--readme README.md]

Runs ``training.evaluate.evaluate_boxes`` (what ``fenestra evaluate-detector --yolo DIR --part P``
prints) for each detector on (a) the validation part of ``SPB/train`` (every 5th photo by sorted
name: the photos training never sees) and (b) the test photos ``SPB`` (``--part all``: every photo
of the folder), and writes one Markdown row per data x detector: photos, window boxes, COCO bbox AP
and AP50 (percent), the detections kept at the shipped threshold (pipeline.detectors.detect's
default score) and how many of them lie on a labelled door or signboard
(``training.evaluate.hard_negative_share``). The photos are not part of the repository; without
them the tool says so in one line and exits 2.

``--readme`` also writes the README's ``detector`` block: the CLI's default detector on the photos
above beside its figures on the rendered houses it never saw and on ``duplex``'s adjacent windows,
read from the generated docs/results/summary.json (``make docs``: run that first).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SPB = ROOT.parent / "shared" / "real" / "spb_facades"
# data label -> (folder under --spb, part of training.dataset.real_box_photos)
SETS = {"spb train, validation part (never trained on)": ("train", "val"),
        "spb test set (never trained on)": (".", "all")}


def row(data: str, result: dict) -> str:
    """One table row of an ``evaluate_boxes`` result."""
    h, b = result["hard_negatives"], result["bbox"]
    share = "-" if h["n_det_at_threshold"] == 0 else f"{100 * h['hard_negative_share']:.1f} %"
    return (f"| {data} | `{result['detector']}` | {result['n_images']} | {result['n_gt']} | {100 * b['AP']:.1f} | "
            f"{100 * b['AP50']:.1f} | {h['n_det_at_threshold']} | {h['n_hard_negative']} ({share}) |")


def table(results: list[tuple[str, dict]]) -> list[str]:
    """The Markdown table of (data label, ``evaluate_boxes`` result) pairs, in their order."""
    threshold = {r["hard_negatives"]["threshold"] for _, r in results}
    return ["| data | detector | photos | boxes | bbox AP | AP50 | detections at score >= "
            f"{'/'.join(f'{t:g}' for t in sorted(threshold))} | on a door/signboard (n, %) |",
            "|---|---|---|---|---|---|---|---|"] + [row(d, r) for d, r in results]


def detector_line(results: list[tuple[str, dict]], summary: dict, detector: str) -> str:
    """The README's sentence on ``detector``: renders of unseen houses (the per-house rows of
    summary.json's synthetic part: its recommended snapper and pose), duplex, and the real photos."""
    ph = summary["synthetic"]["per_house"][detector]
    rows = {r["house"]: r for r in ph["rows"]}
    unseen, duplex = rows["unseen houses"], rows.get("duplex")
    real = {data: r for data, r in results if r["detector"] == detector}
    val, test = (next(r for d, r in real.items() if d.startswith(k)) for k in ("spb train", "spb test"))

    def ap(r: dict) -> str:
        return f"bbox AP50 {100 * r['bbox']['AP50']:.1f}, AP {100 * r['bbox']['AP']:.1f}"

    houses = ", ".join(f"`{r['house']}`" for r in ph["rows"] if not r["trained"] and not r.get("together"))
    text = (f"The default detector `{detector}` ([model card](fenestra/pipeline/models/README.md)), on renders of houses it "
            f"never trained on ({houses}; `make bench`): it finds {100 * unseen['detection_rate']:.0f} % of the "
            f"evaluable windows, with all four corners within 5 px for {100 * unseen['all_corners_close']:.0f} % of "
            f"them after `{ph['snapper']}` snapping (corner error median {unseen['snap_median']:.2f} px; exact masks "
            f"{unseen['exact_snap_median']:.2f} px) and an aspect-ratio error p90 of {100 * unseen['aspect_p90']:.1f} % "
            f"under `{ph['pose']}`")
    if duplex is not None:
        text += (f"; on `duplex`, whose windows stand a few px apart, it finds {100 * duplex['detection_rate']:.0f} % "
                 f"of them")
    share = test["hard_negatives"]
    text += (f". On real street photos it never trained on (St Petersburg, window boxes): {ap(val)} on the "
             f"{val['n_images']} validation photos, {ap(test)} on the {test['n_images']} test photos, where "
             f"{100 * share['hard_negative_share']:.1f} % of its detections lie on a door or signboard. Beyond one "
             f"city, and on curtain walls, it is weaker (model card, Failure modes).")
    return text


def measure(spb: Path, detectors: list[str]) -> list[tuple[str, dict]]:
    """``evaluate_boxes`` of every detector on every set of SETS."""
    from fenestra.training.evaluate import evaluate_boxes  # noqa: PLC0415

    return [(data, evaluate_boxes(det, spb / sub, part)) for data, (sub, part) in SETS.items() for det in detectors]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spb", type=Path, default=SPB, help="the spb_facades folder (train/ and the test photos)")
    ap.add_argument("--detectors", default="default,winnet")
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="real-photos")
    ap.add_argument("--readme", type=Path, default=None, help="also write this README's `detector` block")
    ap.add_argument("--summary", type=Path, default=ROOT / "docs" / "results" / "summary.json")
    a = ap.parse_args()
    missing = [a.spb / sub / "images" for sub, _ in SETS.values() if not (a.spb / sub / "images").is_dir()]
    if missing:
        print(f"no St Petersburg photos: {', '.join(map(str, missing))} not found (give --spb)", file=sys.stderr)
        sys.exit(2)
    from fenestra.training.evaluate import HARD_NEGATIVE_OVERLAP  # noqa: PLC0415

    results = measure(a.spb, a.detectors.split(","))
    lines = [f"`python tools/model_card_real.py {' '.join(sys.argv[1:])}` (`fenestra evaluate-detector --yolo "
             f"DIR --part val|all`; scores in percent, COCO bbox; a detection is on a door/signboard when its box "
             f"IoU or its intersection over the detection's area with a labelled one exceeds {HARD_NEGATIVE_OVERLAP})", ""]
    text = "\n".join(lines + table(results)) + "\n"
    print(text)
    if a.doc is not None:
        from fenestra.reports.markdown import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)
    if a.readme is not None:
        import json  # noqa: PLC0415

        from fenestra.conventions import DEFAULTS  # noqa: PLC0415
        from fenestra.reports.markdown import write_block  # noqa: PLC0415

        line = detector_line(results, json.loads(a.summary.read_text()), DEFAULTS.detector)
        print(line)
        write_block(a.readme, "detector", f"<!-- `python tools/model_card_real.py {' '.join(sys.argv[1:])}` -->\n"
                    + line + "\n")


if __name__ == "__main__":
    main()
