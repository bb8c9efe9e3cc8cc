"""The model card's real-photo rows: the shipped detectors on the St Petersburg street photos.

    .venv/bin/python tools/model_card_real.py [--spb ../shared/real/spb_facades] [--detectors default,winnet] \
        [--doc pipeline/models/README.md --block real-photos]

Runs ``training.evaluate.evaluate_boxes`` (what ``fenestra evaluate-detector --yolo DIR --part P``
prints) for each detector on (a) the validation part of ``SPB/train`` (every 5th photo by sorted
name: the photos training never sees) and (b) the test photos ``SPB`` (``--part all``: every photo
of the folder), and writes one Markdown row per data x detector: photos, window boxes, COCO bbox AP
and AP50 (percent), the detections kept at the shipped threshold (pipeline.detectors.detect's
default score) and how many of them lie on a labelled door or signboard
(``training.evaluate.hard_negative_share``). The photos are not part of the repository; without
them the tool says so in one line and exits 2.
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


def measure(spb: Path, detectors: list[str]) -> list[tuple[str, dict]]:
    """``evaluate_boxes`` of every detector on every set of SETS."""
    from training.evaluate import evaluate_boxes  # noqa: PLC0415

    return [(data, evaluate_boxes(det, spb / sub, part)) for data, (sub, part) in SETS.items() for det in detectors]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spb", type=Path, default=SPB, help="the spb_facades folder (train/ and the test photos)")
    ap.add_argument("--detectors", default="default,winnet")
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="real-photos")
    a = ap.parse_args()
    missing = [a.spb / sub / "images" for sub, _ in SETS.values() if not (a.spb / sub / "images").is_dir()]
    if missing:
        print(f"no St Petersburg photos: {', '.join(map(str, missing))} not found (give --spb)", file=sys.stderr)
        sys.exit(2)
    from training.evaluate import HARD_NEGATIVE_OVERLAP  # noqa: PLC0415

    results = measure(a.spb, a.detectors.split(","))
    lines = [f"`python tools/model_card_real.py {' '.join(sys.argv[1:])}` (`fenestra evaluate-detector --yolo "
             f"DIR --part val|all`; scores in percent, COCO bbox; a detection is on a door/signboard when its box "
             f"IoU or its intersection over the detection's area with a labelled one exceeds {HARD_NEGATIVE_OVERLAP})", ""]
    text = "\n".join(lines + table(results)) + "\n"
    print(text)
    if a.doc is not None:
        from reports.markdown import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)


if __name__ == "__main__":
    main()
