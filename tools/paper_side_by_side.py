"""The paper's method beside its stand-in and the CLI's method, from kept runs: was `oracle-degraded` fair?

    .venv/bin/python tools/paper_side_by_side.py [--doc fenestra/pipeline/models/README.md --block paper-side-by-side]

Reads what tools/seed_spread.py wrote (``--json``) on profile heldout-paper, once per method over the
same seed runs: docs/results/seed_spread_paper.json (``maskrcnn/harris/lm``, the paper's method),
seed_spread_paper_standin.json (``oracle-degraded/harris/lm``, its stand-in) and
seed_spread_paper_cli.json (``default/refine/wall+lines``, the CLI's), and the bbox AP that
``fenestra evaluate-detector --yolo ../shared/real/spb_facades/train --part val --json`` wrote for
``maskrcnn`` and ``default`` (docs/results/spb_val_maskrcnn.json, spb_val_default.json), beside
the paper's Table 2. One table of the pooled "held-out families" row (median over the seeds
[min-max], tools/v8_side_by_side.py's columns), then one of the photos. No figure is typed.
With ``--doc``, also the block ``maskrcnn-training``: what the shipped weights' file says of its
training (iterations, seconds, views, photos, parameters, size).
"""
from __future__ import annotations

import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tools.v8_side_by_side import doc_arguments, rows, table_head  # noqa: E402

SPREADS = ("seed_spread_paper.json", "seed_spread_paper_standin.json", "seed_spread_paper_cli.json")
PHOTOS = (("maskrcnn", "spb_val_maskrcnn.json"), ("default", "spb_val_default.json"))


def photo_row(name: str, path: Path) -> str:
    """``| detector | photos | windows | AP | AP50 | AP75 |`` of one evaluate-detector JSON (its cost is
    tools/cost_side_by_side.py's: evaluate-detector's timing includes decoding the full-size photo)."""
    doc = json.loads(path.read_text())
    b = doc["bbox"]
    f = lambda x: "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.1f}"  # noqa: E731
    return f"| `{name}` | {doc['n_images']} | {doc['n_gt']} | **{f(b['AP'])}** | **{f(b['AP50'])}** | {f(b['AP75'])} |"


def paper_row(path: Path) -> str:
    t = json.loads(path.read_text())["paper_table2"]["bbox"]
    return f"| the paper's Mask R-CNN (Table 2, its own façade photos) | - | - | {t['AP']} | {t['AP50']} | {t['AP75']} |"


def training_text(weights: Path) -> str:
    """One paragraph from a Mask R-CNN weights file's own record (meta, train_config, state_dict)."""
    from fenestra.pipeline.detectors import read_weights  # noqa: PLC0415

    ckpt = read_weights(weights, ("maskrcnn",))
    meta, cfg = ckpt.get("meta", {}), ckpt.get("train_config", {})
    n_params = sum(v.numel() for v in ckpt["state_dict"].values() if v.is_floating_point())
    return (f"<!-- `python tools/paper_side_by_side.py {' '.join(sys.argv[1:])}` (from {weights.name}'s own record) -->\n"
            f"`{weights.name}`: {weights.stat().st_size / 1e6:.1f} MB fp16, {n_params / 1e6:.2f} M parameters "
            f"(buffers included); {meta.get('iterations_done')} iterations of batch {cfg.get('batch_size')} in "
            f"**{meta.get('train_seconds', 0) / 60:.0f} min** of training on {meta.get('device')} "
            f"({meta.get('threads')} thread(s), torch {meta.get('torch')}), on {meta.get('n_train_views')} rendered "
            f"views and {meta.get('n_train_real_photos')} real photos.\n")


def main() -> None:
    a = doc_arguments(__doc__, "paper-side-by-side")
    lines = [f"<!-- `python tools/paper_side_by_side.py {' '.join(sys.argv[1:])}` -->",
             "Renders of the held-out families (profile `heldout-paper`), median over the seeds [min–max]:", "",
             *table_head()]
    lines += [rows("bench held-out families", a.results / n) for n in SPREADS if (a.results / n).is_file()]
    photos = [(n, a.results / f) for n, f in PHOTOS if (a.results / f).is_file()]
    if photos:
        lines += ["", "Real street photos (spb validation part: every 5th photo of `spb_facades/train`, "
                  "trained on by neither detector), bbox AP in percent (`fenestra evaluate-detector`):", "",
                  "| detector | photos | windows | AP | AP50 | AP75 |", "|---|---|---|---|---|---|"]
        lines += [photo_row(n, p) for n, p in photos] + [paper_row(photos[0][1])]
    text = "\n".join(lines) + "\n"
    print(text)
    from lab.docs.blocks import write_block  # noqa: PLC0415

    weights = ROOT / "fenestra" / "pipeline" / "models" / "maskrcnn.pt"
    for doc in a.doc:
        write_block(doc, a.block, text)
        if weights.is_file():
            write_block(doc, "maskrcnn-training", training_text(weights))


if __name__ == "__main__":
    main()
