"""Why learned detections miss windows on renders, and which post-processing separates touching ones.

    .venv/bin/python tools/instance_separation.py --data out/renders/duplex-* [--data ...] \
        [--weights fenestra/pipeline/models/default.pt] [--post nearest,watershed,...] [--markdown]

The network runs once per view (640x480 renders: the network's own input size); each candidate
post-processing (``CANDIDATES``: a PostConfig each, fenestra/pipeline/detectors/winnet.py) then turns the
same maps into instances. Per house and candidate: the evaluable ground-truth windows (the bench's
default rules: >= 90 % visible, all corners in frame, shortest side >= 12 px, incidence <= 80 deg),
how many are **missed** (no detection at score >= 0.5 matched one-to-one at mask IoU >= 0.5), and
why (first rule that holds, in this order):

- ``no_void``: under half the window's pixels reach the void threshold (the network does not fire);
- ``merged``: the detection overlapping it most also covers >= half of another ground-truth window;
- ``ignore``: the window's pixels lie in an ignore region (glazing drawn over it);
- ``poor_mask``: a detection overlaps it, IoU < 0.5 (fragment, spill);
- ``low_score``: a detection with IoU >= 0.5 exists below the score threshold;
- ``other``.

Candidates ``corner-cuts*`` cut void blobs along the separators EffWin's corner heatmaps draw
between neighbouring windows (winnet.separator_cuts), with the gates named in their suffix
(``sv``: cut_min_void_frac, ``h``: cut_min_height_frac, ``p``: cut_min_peak, ``dip``: cut_min_dip).

Also: the matched windows' mask-fit corner error (pipeline.quad.mask_to_quad, every corner pooled,
median px), false positives, and for merged windows the gap to the nearest other window (px).
"""
from __future__ import annotations

import argparse
import glob
import re
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy import ndimage

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from fenestra.bench.matching import iou_matrix, match  # noqa: E402
from fenestra.rendered_view import read_view  # noqa: E402
from fenestra.pipeline.detectors import DETECTORS, load_model  # noqa: E402
from fenestra.pipeline.detectors.winnet import PostConfig, instances_from_maps  # noqa: E402
from fenestra.pipeline.detectors.oracle import oracle_detections  # noqa: E402
from fenestra.pipeline.quad import mask_to_quad  # noqa: E402

SCORE = 0.5  # the shipped threshold (pipeline.detectors.detect's default)
HARD_NEGATIVE_CLASSES = (3, 5)  # spb_facades: signboard, door
REASONS = ("no_void", "merged", "ignore", "poor_mask", "low_score", "other")
BEFORE = {"void_threshold": 0.5, "core_threshold": 0.5, "min_area_px": 30, "min_core_px": 4,
          "separation": "nearest", "split_levels": ()}  # the post-processing before issue #23
# name -> overrides of the checkpoint's PostConfig (the candidates of issue #23, item 1)
CANDIDATES: dict[str, dict | None] = {
    "oracle": None,                                           # the exact masks (pipeline oracle), for scale
    "nearest": {},                                            # before issue #23: nearest core seed
    "core0.7": {"core_threshold": 0.7},
    "core0.8": {"core_threshold": 0.8},
    "void0.6": {"void_threshold": 0.6},
    "void0.4": {"void_threshold": 0.4},
    "void0.3": {"void_threshold": 0.3},
    "watershed": {"separation": "watershed"},                 # core-seeded watershed on the void map
    "nearest-blob": {"separation": "nearest-blob"},           # nearest seed within the pixel's void blob
    "split": {"split_levels": (0.7, 0.8, 0.9, 0.95)},         # core blobs split by the core map's tree
    "split-watershed": {"split_levels": (0.7, 0.8, 0.9, 0.95), "separation": "watershed"},
    "split6-watershed": {"split_levels": (0.6, 0.7, 0.8, 0.9, 0.95, 0.98), "separation": "watershed"},
    "split6-min20-ws": {"split_levels": (0.6, 0.7, 0.8, 0.9, 0.95, 0.98), "separation": "watershed",
                        "split_min_px": 20},
    "voidsplit-ws": {"split_levels": (0.6, 0.7, 0.8, 0.9, 0.95, 0.98), "separation": "watershed",
                     "split_map": "void"},
    "voidsplit-min20-ws": {"split_levels": (0.6, 0.7, 0.8, 0.9, 0.95, 0.98), "separation": "watershed",
                           "split_map": "void", "split_min_px": 20},
}
# void blobs cut along the separators the corner heatmaps draw between neighbouring windows: each
# candidate's settings are spelled in its name (corner_cut_settings)
CUT_SUFFIXES = {"sv": "cut_min_void_frac", "v": "cut_min_void_frac", "p": "cut_min_peak", "h": "cut_min_height_frac",
                "dip": "cut_min_dip", "gap": "cut_max_gap_px"}
CUT_CANDIDATES = ("corner-cuts", "corner-cuts-ws", "corner-cuts-p0.3", "corner-cuts-p0.1", "corner-cuts-gap6",
                  "corner-cuts-gap14", "corner-cuts-v0.7", "corner-cuts-p0.3-v0.7", "corner-cuts-p0.4-v0.7",
                  "corner-cuts-p0.4", "corner-cuts-sv0.7", "corner-cuts-sv0.9", "corner-cuts-sv0.7-dip0.01",
                  "corner-cuts-sv0.7-dip0.02", "corner-cuts-sv0.9-p0.3", "corner-cuts-sv0.9-p0.25",
                  "corner-cuts-sv0.9-h0.5", "corner-cuts-sv0.9-h0.6", "corner-cuts-sv0.9-h0.75", "corner-cuts-sv0.9-h1",
                  "corner-cuts-sv0.7-h0.75", "corner-cuts-sv0.8-h0.75", "corner-cuts-sv0.9-h0",
                  "corner-cuts-dip0.01", "corner-cuts-dip0.02", "corner-cuts-dip0.05", "corner-cuts-v0.3-dip0.02",
                  "corner-cuts-p0.3-dip0.02")


def corner_cut_settings(name: str) -> dict:
    """PostConfig overrides of a ``corner-cuts[-ws][-<key><value>]...`` candidate (keys: CUT_SUFFIXES;
    ``ws``: watershed join, else nearest-blob), e.g. ``corner-cuts-sv0.9-h0.75``."""
    parts = name.removeprefix("corner-cuts").split("-")[1:]
    out = {"separation": "watershed" if "ws" in parts else "nearest-blob", "corner_cuts": True}
    for part in (p for p in parts if p != "ws"):
        m = re.fullmatch(r"([a-z]+)([0-9.]+)", part)
        if m is None or m.group(1) not in CUT_SUFFIXES:
            raise ValueError(f"candidate {name!r}: unknown setting {part!r} (keys: {sorted(CUT_SUFFIXES)})")
        out[CUT_SUFFIXES[m.group(1)]] = float(m.group(2))
    return out


CANDIDATES.update({n: corner_cut_settings(n) for n in CUT_CANDIDATES})


def training_houses(script: Path = Path(__file__).resolve().parent.parent / "lab" / "scripts" / "make_data.sh"
                    ) -> tuple[str, ...]:
    """The bundled houses the shipped detectors trained on, read from the data script's
    ``for house in ...; do`` loop (procedural houses are named by seed there, not here)."""

    m = re.search(r"^for house in ([\w\s-]+); do", script.read_text(), re.M)
    if m is None:
        raise SystemExit(f"{script}: no 'for house in ...; do' loop naming the training houses")
    return tuple(m.group(1).split())


def evaluable(w: dict, shape: tuple[int, int]) -> bool:
    """The bench's default evaluability of a rendered window (fenestra/bench/evaluate.py, default profile)."""
    H, W = shape
    q = np.asarray(w["corners_px"], dtype=np.float64)
    in_frame = bool(np.all((q[:, 0] >= -0.5) & (q[:, 0] <= W - 0.5) & (q[:, 1] >= -0.5) & (q[:, 1] <= H - 0.5)))
    side = float(np.min(np.linalg.norm(q - np.roll(q, -1, axis=0), axis=1)))
    return (w["visible_fraction"] >= 0.9 and in_frame and side >= 12.0 and w["incidence_deg"] <= 80.0
            and w["visible_px"] > 0)


@dataclass(frozen=True)
class ViewMaps:
    house: str
    instances: np.ndarray
    ignore: np.ndarray | None
    windows: tuple[dict, ...]  # evaluable windows' view.json entries
    maps: np.ndarray  # (6, H, W) or (2, H, W) probabilities


def load_views(dirs: list[Path], predict, cache: Path | None = None) -> list[ViewMaps]:
    """Every view of the dataset folders with its maps (float16 .npz per view in ``cache`` if given)."""
    out = []
    for d in dirs:
        for v in sorted((d / "views").iterdir()):
            view = read_view(v)
            wins = tuple(w for w in view.windows if evaluable(w, view.instances.shape))
            f = None if cache is None else cache / d.name / f"{v.name}.npz"
            if f is not None and f.is_file():
                maps = np.load(f)["maps"].astype(np.float32)
            else:
                maps = predict(view.image)
                if f is not None:
                    f.parent.mkdir(parents=True, exist_ok=True)
                    np.savez(f, maps=maps.astype(np.float16))
            out.append(ViewMaps(view.meta["scene"], view.instances, view.ignore, wins, maps))
    return out


def _gap_px(inst: np.ndarray, iid: int) -> float:
    """Distance (px) from window ``iid``'s mask to the nearest pixel of another window."""
    others = (inst > 0) & (inst != iid)
    if not others.any():
        return float("inf")
    d = ndimage.distance_transform_edt(~others)
    return float(d[inst == iid].min())


def view_outcomes(vm: ViewMaps, post: PostConfig | None, dets_fn) -> list[dict]:
    """Per evaluable window: {"house", "missed", "reason", "corner_err" (4,) or None, "gap_px"}, and
    one {"fp": n} row with the view's false positives. post None: the exact masks (``oracle``)."""
    all_dets = oracle_detections(vm.instances) if post is None else dets_fn(vm.maps, post)
    post = post or PostConfig()
    dets = [d for d in all_dets if d.score >= SCORE]
    ids = [w["instance_id"] for w in vm.windows]
    gts = [vm.instances == i for i in ids]
    every_gt = [vm.instances == i for i in np.unique(vm.instances) if i]
    m = match(iou_matrix([d.mask for d in dets], gts)) if dets and gts else None
    matched = m.det_for_gt() if m else {}
    void = vm.maps[0] >= post.void_threshold
    rows = []
    for g, (w, gm) in enumerate(zip(vm.windows, gts)):
        row = {"house": vm.house, "missed": g not in matched, "reason": "", "corner_err": None, "gap_px": None}
        if g in matched:
            q = mask_to_quad(dets[matched[g][0]].mask)
            if q.quad is not None:
                row["corner_err"] = np.linalg.norm(q.quad - np.asarray(w["corners_px"]), axis=1)
        else:
            row["reason"] = _miss_reason(gm, every_gt, dets, all_dets, void, vm.ignore)
            if row["reason"] == "merged":
                row["gap_px"] = _gap_px(vm.instances, w["instance_id"])
        rows.append(row)
    rows.append({"house": vm.house, "fp": _false_positives(dets, every_gt, vm.ignore), "n_det": len(dets)})
    return rows


def _false_positives(dets, every_gt, ignore) -> int:
    """Detections matched (one-to-one, IoU >= 0.5) to no window of the view, evaluable or not,
    and not mostly (>= 50 %) inside an ignore region."""
    if not dets:
        return 0
    unmatched = match(iou_matrix([d.mask for d in dets], every_gt)).false_positives if every_gt \
        else range(len(dets))
    return sum(1 for i in unmatched
               if ignore is None or (ignore[dets[i].mask] > 0).mean() < 0.5)


def _miss_reason(gm, every_gt, dets, all_dets, void, ignore) -> str:
    area = gm.sum()
    if void[gm].mean() < 0.5:
        return "no_void"
    inter = [int((d.mask & gm).sum()) for d in dets]
    if dets and max(inter) > 0:
        best = dets[int(np.argmax(inter))].mask
        covered = sum(1 for o in every_gt if (best & o).sum() >= 0.5 * o.sum())
        if covered >= 2:
            return "merged"
    if ignore is not None and (ignore[gm] > 0).mean() >= 0.5:
        return "ignore"
    if dets and max(inter) > 0:
        return "poor_mask"
    if any(((d.mask & gm).sum() / ((d.mask | gm).sum())) >= 0.5 for d in all_dets if d.score < SCORE):
        return "low_score"
    return "other" if area else "other"


def summarise(rows: list[dict]) -> dict:
    wins = [r for r in rows if "missed" in r]
    fps = [r for r in rows if "fp" in r]
    errs = [r["corner_err"] for r in wins if r["corner_err"] is not None]
    gaps = [r["gap_px"] for r in wins if r["gap_px"] is not None]
    return {"n": len(wins), "missed": sum(r["missed"] for r in wins),
            "reasons": {k: sum(r["reason"] == k for r in wins) for k in REASONS},
            "corner_med": float(np.median(np.concatenate(errs))) if errs else float("nan"),
            "within5": sum(bool(np.all(e <= 5.0)) for e in errs),
            "fp": sum(r["fp"] for r in fps), "n_det": sum(r["n_det"] for r in fps),
            "merged_gap_med": float(np.median(gaps)) if gaps else float("nan")}


# ---------------------------------------------------------------- real photos (YOLO boxes)

def real_photos(yolo: Path, part: str, predict, cache: Path | None = None) -> list[tuple]:
    """(name, (H, W), scale, maps, window boxes, door/signboard boxes) per photo of ``part``: the
    network's maps (C, h, w) float16 of the photo as pipeline.detectors.detect feeds the network
    (long side <= 1024 px; void, core and, for EffWin, its four corner maps); cached in ``cache``
    (an .npz per photo) when given."""
    from fenestra.yolo import yolo_boxes  # noqa: PLC0415
    from fenestra.images import read_image  # noqa: PLC0415
    from fenestra.pipeline.detectors import downscale, input_scale  # noqa: PLC0415
    from fenestra.training.dataset import photo_labels, real_box_photos  # noqa: PLC0415

    out = []
    for p in real_box_photos(yolo, part):
        image = read_image(p)
        H, W = image.shape[:2]
        text = photo_labels(p)[0]
        wins = yolo_boxes(text, W, H, (0,), p.name)
        negs = yolo_boxes(text, W, H, HARD_NEGATIVE_CLASSES, p.name)
        scale = input_scale((H, W))
        f = None if cache is None else cache / f"{p.stem}.npz"
        if f is not None and f.is_file():
            maps = np.load(f)["maps"]
        else:
            maps = predict(image if scale == 1.0 else downscale(image, scale)).astype(np.float16)
            if f is not None:
                f.parent.mkdir(parents=True, exist_ok=True)
                np.savez(f, maps=maps)
        out.append((p.name, (H, W), scale, maps, wins, negs))
    return out


# door rules (issue #23, item 5): drop a detection whose box reaches the bottom fraction of the
# photo (street level) and is taller than wide by the ratio: (bottom fraction, min height / width)
DOOR_RULES = {"door-rule-0.85-1.8": (0.85, 1.8), "door-rule-0.8-1.5": (0.8, 1.5), "door-rule-0.9-2.2": (0.9, 2.2)}


def looks_like_door(box, H: int, rule: tuple[float, float]) -> bool:
    x0, y0, x1, y1 = box
    return y1 >= rule[0] * H and (y1 - y0) >= rule[1] * max(x1 - x0, 1e-9)


def real_detections(photos, post: PostConfig) -> list[list[tuple[float, np.ndarray]]]:
    """Per photo, (score, full-resolution box) of every instance at score >= 0.05 (as evaluate-detector,
    without its box verifier); the corner maps, where the photo's maps hold them, go to the cuts."""
    from fenestra.pipeline.detectors import box_to_full  # noqa: PLC0415

    return [[(d.score, box_to_full(d.box, scale)) for d in instances_from_maps(
        maps[0].astype(np.float32), maps[1].astype(np.float32), post,
        maps[2:].astype(np.float32) if len(maps) > 2 else None) if d.score >= 0.05]
        for _, _, scale, maps, _, _ in photos]


def real_scores(photos, dets_per_photo, rule: tuple[float, float] | None = None) -> dict:
    """bbox COCO scores and the hard-negative share at the shipped threshold
    (training.evaluate.hard_negative_share) of the detections, after the door rule if given."""
    from fenestra.coco import coco_ground_truth, coco_result, coco_scores, gt_annotation  # noqa: PLC0415
    from fenestra.training.evaluate import hard_negative_share  # noqa: PLC0415

    images, anns, results, shipped = [], [], [], []
    for k, ((name, (H, W), _, _, wins, negs), dets) in enumerate(zip(photos, dets_per_photo), 1):
        images.append((name, H, W))
        anns += [gt_annotation(name, box=b) for b in wins]
        if rule is not None:
            dets = [(sc, b) for sc, b in dets if not looks_like_door(b, H, rule)]
        results += [coco_result(k, sc, b) for sc, b in dets]
        shipped.append(([b for sc, b in dets if sc >= SCORE], negs, wins))
    scores = coco_scores(coco_ground_truth(images, anns), results, ("bbox",))
    return {**scores, **hard_negative_share(shipped)}


def table(results: dict[tuple[str, str], dict]) -> str:
    trained = training_houses()
    head = ("| candidate | house | trained on | evaluable | missed | " + " | ".join(REASONS)
            + " | corners within 5 px | mask-fit corner error median px | detections | false positives |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for (cand, house), s in results.items():
        flag = "-" if house == "all" else ("**yes**" if house in trained else "no (unseen)")
        lines.append(f"| {cand} | {house} | {flag} | {s['n']} | {s['missed']} ({100 * s['missed'] / max(s['n'], 1):.0f} %) | "
                     + " | ".join(str(s["reasons"][k]) for k in REASONS)
                     + f" | {100 * s['within5'] / max(s['n'], 1):.0f} % | {s['corner_med']:.2f} | {s['n_det']} | {s['fp']} |")
    return "\n".join(lines)


def candidate_post(cand: str, base: PostConfig, shipped: PostConfig) -> PostConfig | None:
    """The PostConfig of a candidate: ``shipped`` (the weights file's, with its architecture's
    defaults), the oracle's None, or the candidate's overrides of ``base``."""
    if cand == "shipped":
        return shipped
    return None if CANDIDATES[cand] is None else replace(base, **CANDIDATES[cand])


def real_report(yolo: Path, part: str, cands: list[str], base: PostConfig, shipped: PostConfig, predict,
                cache: Path | None) -> list[str]:
    photos = real_photos(yolo, part, predict, cache)
    lines = [f"{len(photos)} {part} photos of {yolo.name if yolo.name != 'train' else yolo.parent.name + '/train'}; "
             f"bbox AP at score >= 0.05 (as evaluate-detector); door/signboard share at score >= {SCORE}",
             "", "| candidate | bbox AP | AP50 | detections at 0.5 | on a door/signboard | of which match no window |",
             "|---|---|---|---|---|---|"]
    first = None
    for cand in cands:
        dets = real_detections(photos, candidate_post(cand, base, shipped))
        first = dets if first is None else first
        lines.append(_real_row(cand, real_scores(photos, dets)))
        print(lines[-1], flush=True)
    for name, rule in DOOR_RULES.items():
        lines.append(_real_row(f"{cands[0]} + {name}", real_scores(photos, first, rule)))
        print(lines[-1], flush=True)
    return lines


def _real_row(name: str, r: dict) -> str:
    return (f"| {name} | {100 * r['bbox_AP']:.1f} | {100 * r['bbox_AP50']:.1f} | {r['n_det_at_threshold']} | "
            f"{r['n_hard_negative']} ({100 * r['hard_negative_share']:.1f} %) | {r['n_hard_negative_no_window']} |")


def render_report(dirs: list[Path], cands: list[str], base: PostConfig, shipped: PostConfig, predict, dets_fn,
                  cache: Path | None) -> list[str]:
    views = load_views(dirs, predict, cache)
    houses = sorted({v.house for v in views})
    results = {}
    for cand in cands:
        post = candidate_post(cand, base, shipped)
        rows = [r for v in views for r in view_outcomes(v, post, dets_fn)]
        for h in houses + (["all"] if len(houses) > 1 else []):
            results[(cand, h)] = summarise([r for r in rows if h == "all" or r["house"] == h])
        print(f"{cand} done", flush=True)
    lines = [f"{len(views)} views of {', '.join(houses)} (640x480 raster); detections at score >= {SCORE}", "",
             table(results), ""]
    lines += [f"- {k[0]} @ {k[1]}: the missed windows' gap to their nearest neighbouring window, median "
              f"{v['merged_gap_med']:.1f} px" for k, v in results.items() if v["reasons"]["merged"] and k[0] == cands[0]]
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", action="append", default=[], help="rendered dataset folder (glob ok)")
    ap.add_argument("--yolo", type=Path, default=None, help="real photos with YOLO boxes (spb_facades/train)")
    ap.add_argument("--part", default="val", choices=("val",), help="which photos of --yolo (val only: "
                    "the 10 test photos are never tuned on)")
    ap.add_argument("--weights", default=None, help="weights file (default: the shipped default.pt)")
    ap.add_argument("--post", default="shipped", help="comma-separated candidates: shipped (the weights "
                    f"file's post-processing) or of {sorted(CANDIDATES)}")
    ap.add_argument("--base", default="before", choices=("shipped", "before"),
                    help="PostConfig the candidates override: the weights file's, or the one before issue #23")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--cache", type=Path, default=None, help="folder for the maps (.npz per photo or view, "
                    "under a subfolder named by the weights' network sha256, so other weights never reuse them)")
    ap.add_argument("--doc", type=Path, default=None, help="write the report into this Markdown file's block")
    ap.add_argument("--block", default=None, help="the block's name (<!-- NAME:begin --> ... <!-- NAME:end -->)")
    a = ap.parse_args()
    import torch  # noqa: PLC0415

    torch.set_num_threads(a.threads)
    mod, net, ckpt = load_model(DETECTORS["default"].model, a.weights, any_arch=True)
    shipped = mod.post_config(ckpt)
    if a.cache is not None:
        from fenestra.pipeline.detectors.verifier import network_fingerprint  # noqa: PLC0415

        a.cache = a.cache / (network_fingerprint(net.state_dict())[:16] + ("-mirror" if shipped.mirror else ""))
    base = shipped if a.base == "shipped" else PostConfig(**BEFORE)
    predict = (lambda im: mod.predict_maps(net, im, shipped.mirror)) if ckpt["arch"] == "effwin" \
        else (lambda im: np.stack(mod.predict_maps(net, im)))
    dets_fn = mod.detections_from_maps if ckpt["arch"] == "effwin" \
        else (lambda maps, post: mod.instances_from_maps(maps[0], maps[1], post))
    cands = a.post.split(",")
    unknown = [c for c in cands if c not in CANDIDATES and c != "shipped"]
    if unknown:
        raise SystemExit(f"unknown candidate(s) {unknown}; choose from {sorted(CANDIDATES)}")
    lines = [f"`python tools/instance_separation.py {' '.join(sys.argv[1:])}` (weights "
             f"{a.weights or 'fenestra/pipeline/models/default.pt'}, {ckpt['arch']}; candidates override {base}; "
             f"`shipped` = {shipped})", ""]
    if a.yolo is not None:
        if "oracle" in cands:
            raise SystemExit("the oracle needs instance maps: real photos have boxes only")
        lines += real_report(a.yolo, a.part, cands, base, shipped, predict, a.cache) + [""]
    dirs = [Path(p) for pat in a.data for p in sorted(glob.glob(pat))]
    if dirs:
        lines += render_report(dirs, cands, base, shipped, predict, dets_fn, a.cache)
    text = "\n".join(lines).rstrip() + "\n"
    print(text)
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)


if __name__ == "__main__":
    main()
