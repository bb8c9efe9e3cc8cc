"""The model card's real-photo rows: the shipped detectors on the St Petersburg street photos.

    .venv/bin/python tools/model_card_real.py [--spb ../shared/real/spb_facades] [--detectors default,winnet] \
        [--doc fenestra/pipeline/models/README.md --block real-photos] [--readme README.md]

Runs ``training.evaluate.evaluate_boxes`` (what ``fenestra evaluate-detector --yolo DIR --part P``
prints) for each detector on (a) the validation part of ``SPB/train`` (every 5th photo by sorted
name: the photos ``make train`` leaves out) and (b) the test photos ``SPB`` (``--part all``: every
photo of the folder), and writes one Markdown row per data x detector: whether the photos are held
out from the detector's weights (:func:`held_out`, from what the weights record), photos, window
boxes, COCO bbox AP and AP50 (percent), the detections kept at the shipped threshold
(pipeline.detectors.detect's default score) and how many of them lie on a labelled door or
signboard (``training.evaluate.hard_negative_share``). The photos are not part of the repository;
without them the tool says so in one line and exits 2.

Held out (issue #36): ``SPB/train`` held copies of the test photos until 2026-11-28 (559 photos, 445
after the cleaning; ../shared/real/README.md), and the validation part is recomputed on the cleaned
folder, so weights trained before the cleaning have trained on photos of both sets. A figure is
called held out only when the weights prove it: trained on no real photo, or listing the photos
they trained on (``meta["real_photos"]``, written by training since the cleaning) with none of the
evaluated photos among them (by name or by the file's sha256). Otherwise it is a training-set figure.

``--readme`` also writes the README's ``detector`` block: the CLI's default detector on the photos
above beside its figures on the rendered building families it never saw, read from the generated
docs/results/summary.json (``make docs``: run that first) and, over seeds with their spread, from
docs/results/seed_spread.json (``tools/seed_spread.py --json``).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SPB = ROOT.parent / "shared" / "real" / "spb_facades"
# data label -> (folder under --spb, part of training.dataset.real_box_photos)
SETS = {"spb train, validation part": ("train", "val"),
        "spb test set": (".", "all")}
CLEANED = "2026-11-28"  # the day the test photos' copies left SPB/train (../shared/real/README.md)


def photo_records(photos) -> tuple[set[str], set[str]]:
    """(names, sha256 of the bytes) of photo files."""
    import hashlib  # noqa: PLC0415

    return {p.name for p in photos}, {hashlib.sha256(p.read_bytes()).hexdigest() for p in photos}


def held_out(train_config: dict, meta: dict, photos) -> dict:
    """Whether ``photos`` (paths) are held out from weights with this training config and meta:
    ``{"held_out": bool, "why": str}``. Held out when the weights trained on no real photo, or list
    theirs (``meta["real_photos"]``: "NAME SHA256" each) and none of ``photos`` is among them by name
    or sha256; weights that trained on real photos without listing them are not known to hold
    anything out (those trained before the cleaning had the test photos' copies in their folder)."""
    if not train_config.get("real_data") or not train_config.get("real_fraction"):
        return {"held_out": True, "why": "yes: trained on no real photo"}
    listed = meta.get("real_photos")
    if listed is None:
        return {"held_out": False, "why": f"**no**: trained on real photos it does not list, from `{train_config['real_data']}` "
                f"before its cleaning ({CLEANED}; it held these photos): a training-set figure"}
    names, shas = photo_records(photos)
    seen = [r for r in listed if r.split(" ")[0] in names or r.split(" ")[-1] in shas]
    if seen:
        return {"held_out": False, "why": f"**no**: {len(seen)} of these photos trained it: a training-set figure"}
    return {"held_out": True, "why": f"yes: none of its {len(listed)} training photos"}


def row(data: str, result: dict) -> str:
    """One table row of an ``evaluate_boxes`` result (with its ``held_out`` verdict)."""
    h, b = result["hard_negatives"], result["bbox"]
    share = "-" if h["n_det_at_threshold"] == 0 else f"{100 * h['hard_negative_share']:.1f} %"
    return (f"| {data} | `{result['detector']}` | {result['held_out']['why']} | {result['n_images']} | {result['n_gt']} | "
            f"{100 * b['AP']:.1f} | {100 * b['AP50']:.1f} | {h['n_det_at_threshold']} | {h['n_hard_negative']} ({share}) |")


def table(results: list[tuple[str, dict]]) -> list[str]:
    """The Markdown table of (data label, ``evaluate_boxes`` result) pairs, in their order."""
    threshold = {r["hard_negatives"]["threshold"] for _, r in results}
    return ["| data | detector | held out from its weights? | photos | boxes | bbox AP | AP50 | detections at score >= "
            f"{'/'.join(f'{t:g}' for t in sorted(threshold))} | on a door/signboard (n, %) |",
            "|---|---|---|---|---|---|---|---|---|"] + [row(d, r) for d, r in results]


def spread_text(spread: dict | None, detector: str) -> str:
    """The README's seed-spread clause: the held-out families' figures over the seeds of
    docs/results/seed_spread.json (tools/seed_spread.py --json), median [min–max]; "" without one."""
    from lab.docs.roles import ROLE_GROUPS  # noqa: PLC0415

    label = ROLE_GROUPS["held out"]
    group = ((spread or {}).get("houses") or {}).get(label)
    if group is None or not str(spread.get("method", "")).startswith(detector + "/"):
        return ""
    f = group["figures"]

    def mm(key: str, scale: float, unit: str, dec: int) -> str:
        v = f.get(key) or {}
        if "median" not in v:
            return "-"
        return f"{scale * v['median']:.{dec}f}{unit} [{scale * v['min']:.{dec}f}–{scale * v['max']:.{dec}f}]"

    houses = ", ".join(f"`{h}`" for h, v in spread["houses"].items() if v["role"] == "held out" and h != label)
    return (f" Over seeds {', '.join(map(str, spread['seeds']))} ({houses}; {spread['views_per_house']} views per house and "
            f"seed, a look drawn per {spread['look_per']}; `{spread['command']}`), median [min–max] over the seeds: found "
            f"{mm('detection_rate', 100, ' %', 0)}, quads {mm('quad_rate', 100, ' %', 0)}, all four corners within 5 px "
            f"{mm('all_corners_close', 100, ' %', 0)}, corner median {mm('snap_median', 1, ' px', 2)}, rotation median "
            f"{mm('rot_median', 1, '°', 2)}.")


def detector_line(results: list[tuple[str, dict]], summary: dict, detector: str, spread: dict | None = None) -> str:
    """The README's sentence on ``detector``: renders of the building families it never saw (the
    "held-out families" row of summary.json's synthetic per-house part, its recommended snapper and
    pose; with ``spread``, docs/results/seed_spread.json, the same over seeds with min–max), and
    the real photos. Same-generator and trained-on houses are not quoted (issue #36)."""
    ph = summary["synthetic"]["per_house"][detector]
    from lab.docs.roles import ROLE_GROUPS  # noqa: PLC0415

    rows = {r["house"]: r for r in ph["rows"]}
    held = rows[ROLE_GROUPS["held out"]]
    real = {data: r for data, r in results if r["detector"] == detector}
    val, test = (next(r for d, r in real.items() if d.startswith(k)) for k in ("spb train, validation part", "spb test"))

    def ap(r: dict) -> str:
        return f"bbox AP50 {100 * r['bbox']['AP50']:.1f}, AP {100 * r['bbox']['AP']:.1f}"

    held_names = [r["house"] for r in ph["rows"] if r.get("role") == "held out" and not r.get("together")]
    pv = summary["synthetic"].get("provenance", {})
    looks = ("a look drawn per view" if pv.get("look_per") == "view" else "one random look per house")
    houses = ", ".join(f"`{h}`" for h in held_names)
    text = (f"The default detector `{detector}` ([model card](fenestra/pipeline/models/README.md)), on renders of building "
            f"families it never saw ({houses}: neither they nor their generator trained it; `make bench`, seed "
            f"{pv.get('seed')}: {looks}): it finds {100 * held['detection_rate']:.0f} % of the "
            f"evaluable windows, with all four corners within 5 px for {100 * held['all_corners_close']:.0f} % of "
            f"them after `{ph['snapper']}` snapping (corner error median {held['snap_median']:.2f} px; exact masks "
            f"{held['exact_snap_median']:.2f} px) and an aspect-ratio error p90 of {100 * held['aspect_p90']:.1f} % "
            f"under `{ph['pose']}`.")
    text += spread_text(spread, detector)
    share = test["hard_negatives"]
    text += (f" On real street photos "
             f"(St Petersburg, window boxes): {ap(val)} on the {val['n_images']} validation photos, {ap(test)} on the "
             f"{test['n_images']} test photos, where {100 * share['hard_negative_share']:.1f} % of its detections lie on a "
             f"door or signboard")
    if val["held_out"]["held_out"] and test["held_out"]["held_out"]:
        text += ", photos its weights never trained on."
    else:
        text += (f". These are **training-set figures**: the shipped weights were trained on the photo folder before its "
                 f"cleaning ({CLEANED}), which held copies of the test photos and every photo of the recomputed "
                 f"validation part; figures on these photos are held out only for weights trained after the cleaning "
                 f"(model card, Metrics).")
    return text + " Beyond one city, and on curtain walls, it is weaker (model card, Failure modes)."


def measure(spb: Path, detectors: list[str]) -> list[tuple[str, dict]]:
    """``evaluate_boxes`` of every detector on every set of SETS."""
    from fenestra.pipeline.detectors import DETECTORS, read_weights  # noqa: PLC0415
    from fenestra.training.dataset import real_box_photos  # noqa: PLC0415
    from fenestra.training.evaluate import evaluate_boxes  # noqa: PLC0415

    ckpts = {det: read_weights(DETECTORS[det].model.weights) for det in detectors}
    out = []
    for data, (sub, part) in SETS.items():
        photos = real_box_photos(spb / sub, part)
        for det in detectors:
            verdict = held_out(ckpts[det].get("train_config") or {}, ckpts[det].get("meta") or {}, photos)
            out.append((data, {**evaluate_boxes(det, spb / sub, part), "held_out": verdict}))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spb", type=Path, default=SPB, help="the spb_facades folder (train/ and the test photos)")
    ap.add_argument("--detectors", default="default,winnet")
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="real-photos")
    ap.add_argument("--readme", type=Path, default=None, help="also write this README's `detector` block")
    ap.add_argument("--summary", type=Path, default=ROOT / "docs" / "results" / "summary.json")
    ap.add_argument("--spread", type=Path, default=ROOT / "docs" / "results" / "seed_spread.json",
                    help="tools/seed_spread.py --json output: the held-out families over seeds")
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
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)
    if a.readme is not None:
        import json  # noqa: PLC0415

        from fenestra.conventions import DEFAULTS  # noqa: PLC0415
        from lab.docs.blocks import write_block  # noqa: PLC0415

        spread = json.loads(a.spread.read_text()) if a.spread.is_file() else None
        line = detector_line(results, json.loads(a.summary.read_text()), DEFAULTS.detector, spread)
        print(line)
        write_block(a.readme, "detector", f"<!-- `python tools/model_card_real.py {' '.join(sys.argv[1:])}` -->\n"
                    + line + "\n")


if __name__ == "__main__":
    main()
