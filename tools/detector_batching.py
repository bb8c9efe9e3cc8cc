"""Does batching views through a learned detector save CPU? (issue 34, item 3; prints figures, not a test)

    .venv/bin/python tools/detector_batching.py [--profile default] [--house fzk-haus] [--views 8] \
        [--batches 1,2,4,8] [--threads 1,2] [--reps 5] [--json docs/results/detector_batching.json] \
        [--doc docs/performance.md --block detector-batching] [--from-json docs/results/detector_batching.json]

The learned detectors the profile runs (its ``[methods]`` detectors that load a weights file and
whose weights are here, as ``fenestra bench`` would run them) each see ``--views`` views of one
house, rendered as the profile renders them (``[render]`` size, renderer and look; the bench's
fenestra.bench.render_adapter.dataset_config with fewer views, under ``out/detector-batching/renders``),
at the size the bench feeds them (the profile's renders are below the detector's long-side limit,
so never resized). For each torch thread count (1 is what a bench worker uses) and batch size B,
the views go through in consecutive batches of B, and two things are timed per view:

- **forward**: the network alone, on the B views' input tensors concatenated (B, 3, H, W);
- **detect**: the whole detection: each view's input tensor, one forward of the batch, then each
  view's post-processing (maps -> instances -> corners, the box verifier), as the detector does
  for one view (fenestra.pipeline.detectors.<arch>.detector_from_model); B = 1 is the per-view path.

Process CPU seconds (what the bench's stage figures count; robust to other processes on the
machine) and wall seconds, each the median over ``--reps`` repetitions after one warm-up, the batch
sizes interleaved in every repetition. The registry's ``detect`` call per view (what the bench's
session calls) is timed alongside, as the reference the B = 1 path must match. Before timing, each
batch size's outputs are compared with the per-view ones: the largest absolute difference of the
logits (and of the verifier's feature maps), and whether the detections (masks, boxes, scores,
corners) agree with the registry's ``detect`` per view. ``--from-json`` writes the table (and the
block) of an earlier measurement's JSON, its verdicts recomputed, without measuring.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import statistics
import sys
import time
from pathlib import Path
from typing import Callable, Sequence

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")  # as the tests: an idle OpenMP thread sleeps (2-thread runs)

PAYS = 0.10  # batching is adopted when it saves at least this share of the CPU per view at 1 thread (issue 34)
SCORE_ATOL = 1e-5  # detections of a batch "agree" with the per-view ones: masks equal, scores/boxes/corners this close
COORD_ATOL = 1e-3  # px


# ---------------------------------------------------------------- pure helpers

def chunks(items: Sequence, size: int) -> list[list]:
    """Consecutive batches of ``size`` items (the last one shorter when ``size`` does not divide them)."""
    if not (isinstance(size, int) and size >= 1):
        raise ValueError(f"batch size must be a positive int, got {size!r}")
    return [list(items[i:i + size]) for i in range(0, len(items), size)]


def stack_views(tensors: Sequence):
    """One batch (B, C, H, W) of per-view network inputs (1, C, H, W) of equal size, channels-last
    as the detectors feed their network; ValueError when the sizes differ (the bench's views of one
    profile all have its render size, so no view needs padding to another's)."""
    import torch  # noqa: PLC0415

    if not tensors:
        raise ValueError("no views to batch")
    shapes = {tuple(t.shape) for t in tensors}
    if len(shapes) != 1 or len(next(iter(shapes))) != 4 or next(iter(shapes))[0] != 1:
        raise ValueError(f"views to batch must be (1, C, H, W) tensors of one size, got {sorted(shapes)}")
    return torch.cat(list(tensors), dim=0).contiguous(memory_format=torch.channels_last)


def ratio(value: float, base: float) -> float:
    """value / base (a batch size's cost per view relative to batch 1's)."""
    if not base > 0:
        raise ValueError(f"base must be > 0, got {base!r}")
    return value / base


def verdict(rows: list[dict], detector: str, threads: int = 1, pays: float = PAYS) -> dict:
    """Whether batching pays for ``detector`` at ``threads``: the batch size with the least detect
    CPU per view, its ratio to batch 1, and ``pays`` when that ratio is at most 1 - pays. At more
    than one thread also ``vs_one_thread``: that batch's CPU per view over the single view's at one
    thread (what a bench worker runs), when the rows have it."""
    mine = [r for r in rows if r["detector"] == detector and r["threads"] == threads]
    if not mine:
        raise ValueError(f"no rows of {detector!r} at {threads} thread(s)")
    best = min(mine, key=lambda r: r["detect_cpu_ratio"])
    out = {"detector": detector, "threads": threads, "best_batch": best["batch"],
           "best_ratio": best["detect_cpu_ratio"], "threshold": 1.0 - pays,
           "pays": bool(best["batch"] > 1 and best["detect_cpu_ratio"] <= 1.0 - pays)}
    one = [r for r in rows if r["detector"] == detector and r["threads"] == 1 and r["batch"] == 1]
    if threads != 1 and one:
        out["vs_one_thread"] = ratio(best["detect_cpu_ms"], one[0]["detect_cpu_ms"])
    return out


# ---------------------------------------------------------------- the detector, split at the network

@dataclasses.dataclass
class Split:
    """A learned detector as pre-processing, network and post-processing (per arch, as its module's
    detector_from_model does for one view)."""

    name: str
    arch: str
    net: object
    prepare: Callable  # image (H, W, 3) uint8 -> (tensor (1, 3, Hp, Wp), H, W)
    forward: Callable  # (B, 3, Hp, Wp) -> (logits (B or 2B, M, Hp, Wp), {feature name: (B or 2B, C, h, w)})
    finish: Callable  # (maps (M, H, W) float32, {name: (1, C, h, w)}) -> detections
    probs: Callable = None  # logits -> probabilities (B, M, Hp, Wp): sigmoid, or EffWin's mirror mean

    def detect_batch(self, images: Sequence) -> list[list]:
        """Detections of each image, the network run once on all of them."""
        import torch  # noqa: PLC0415

        prepared = [self.prepare(im) for im in images]
        with torch.no_grad():
            logits, feats = self.forward(stack_views([p[0] for p in prepared]))
            probs = (self.probs or torch.sigmoid)(logits.float())
        return [self.finish(probs[i, :, :H, :W].cpu().numpy(), {k: v[i:i + 1].float().cpu() for k, v in feats.items()})
                for i, (_, H, W) in enumerate(prepared)]


def split_detector(name: str) -> Split | None:
    """The Split of registered detector ``name`` with its shipped weights; None for an arch this
    tool does not know how to split."""
    import torch  # noqa: PLC0415

    from fenestra.pipeline.detectors import DETECTORS, load_model  # noqa: PLC0415
    from fenestra.pipeline.detectors.winnet import instances_from_maps, pad_to_stride  # noqa: PLC0415

    entry = DETECTORS[name]
    mod, net, ckpt = load_model(entry.model, None, any_arch=name == "default")
    post = mod.post_config(ckpt)
    arch = ckpt["arch"]

    def prepare(image):
        x, H, W = pad_to_stride(mod.to_tensor(image), mod.STRIDE)
        return x.contiguous(memory_format=torch.channels_last), H, W

    if arch == "effwin":
        from fenestra.pipeline.detectors.verifier import classified  # noqa: PLC0415

        head = mod.verifier_from_checkpoint(net, ckpt)

        def forward(x):  # with the weights' ``mirror``: the views, then their mirrors, in one batch
            x = torch.cat([x, torch.flip(x, dims=[3])]) if post.mirror else x
            return net.forward_features(x) if head is not None else (net(x), {})

        def probs(logits):
            p = torch.sigmoid(logits)
            return mod.mirror_mean(p) if post.mirror else p

        def finish(maps, feats):
            dets = mod.detections_from_maps(maps, post)
            return dets if head is None else [d for d in classified(dets, maps[0], feats, head) if d.kind == "window"]
    elif arch == "winnet":
        def forward(x):
            return net(x), {}

        def finish(maps, feats):
            return instances_from_maps(maps[0], maps[1], post)
        probs = None
    else:
        return None
    return Split(name, arch, net, prepare, forward, finish, probs)


# ---------------------------------------------------------------- checks and timing

def max_abs_diff(a, b) -> float:
    return float((a.float() - b.float()).abs().max()) if a.numel() else 0.0


def detections_agree(a: list, b: list) -> tuple[bool, str]:
    """(True, "") when two detection lists agree (same order, masks equal, scores, boxes and corners
    within SCORE_ATOL / COORD_ATOL), else (False, what differs)."""
    import numpy as np  # noqa: PLC0415

    if len(a) != len(b):
        return False, f"{len(a)} vs {len(b)} detections"
    for k, (x, y) in enumerate(zip(a, b)):
        if x.mask.shape != y.mask.shape or not np.array_equal(x.mask, y.mask) or tuple(x.origin) != tuple(y.origin):
            return False, f"detection {k}: masks differ"
        if abs(x.score - y.score) > SCORE_ATOL or not np.allclose(x.box, y.box, atol=COORD_ATOL):
            return False, f"detection {k}: score {x.score} vs {y.score} or box differs"
        if (x.corners is None) != (y.corners is None) or (
                x.corners is not None and not np.allclose(x.corners, y.corners, atol=COORD_ATOL)):
            return False, f"detection {k}: corners differ"
    return True, ""


def check_outputs(split: Split, images: list, batch: int, reference: list[list]) -> dict:
    """Batched outputs against per-view ones: max |logit diff|, max |feature diff|, detections agree."""
    import torch  # noqa: PLC0415

    from fenestra.pipeline.session import CANDIDATE_SCORE_MIN  # noqa: PLC0415

    logit_d, feat_d, bad = 0.0, 0.0, []
    with torch.no_grad():
        singles = [split.forward(split.prepare(im)[0]) for im in images]
        for start, group in zip(range(0, len(images), batch), chunks(images, batch)):
            logits, feats = split.forward(stack_views([split.prepare(im)[0] for im in group]))
            for i in range(len(group)):
                one_logits, one_feats = singles[start + i]  # row 0: the view (row 1: its mirror, if any)
                logit_d = max(logit_d, max_abs_diff(logits[i:i + 1], one_logits[0:1]))
                for k, v in feats.items():
                    feat_d = max(feat_d, max_abs_diff(v[i:i + 1], one_feats[k][0:1]))
    batched = [d for group in chunks(images, batch) for d in split.detect_batch(group)]
    for k, (dets, ref) in enumerate(zip(batched, reference)):
        ok, why = detections_agree([d for d in dets if d.score >= CANDIDATE_SCORE_MIN], ref)
        if not ok:
            bad.append(f"view {k}: {why}")
    return {"max_abs_logit_diff": logit_d, "max_abs_feature_diff": feat_d, "detections_agree": not bad,
            "disagreements": bad}


def timed(fn: Callable[[], object]) -> tuple[float, float]:
    """(process CPU seconds, wall seconds) of one call."""
    c0, w0 = time.process_time(), time.perf_counter()
    fn()
    return time.process_time() - c0, time.perf_counter() - w0


def measure(split: Split, images: list, batches: list[int], threads: int, reps: int) -> list[dict]:
    """One row per batch size: median CPU and wall ms per view of the forward and of the detection,
    and of the registry's ``detect`` per view (the reference)."""
    import torch  # noqa: PLC0415

    from fenestra.pipeline.detectors import detect  # noqa: PLC0415
    from fenestra.pipeline.session import CANDIDATE_SCORE_MIN  # noqa: PLC0415
    from fenestra.bench.runner import LEARNED_DETECTOR_OPTIONS  # noqa: PLC0415

    torch.set_num_threads(threads)
    n = len(images)
    inputs = {b: [stack_views([split.prepare(im)[0] for im in g]) for g in chunks(images, b)] for b in batches}
    samples: dict[tuple[int, str], list[tuple[float, float]]] = {}

    def forward_all(b):
        with torch.no_grad():
            for x in inputs[b]:
                split.forward(x)

    def detect_all(b):
        for g in chunks(images, b):
            split.detect_batch(g)

    def registry_all():
        for im in images:
            detect(split.name, im, CANDIDATE_SCORE_MIN, **LEARNED_DETECTOR_OPTIONS)

    registry_all()  # builds (cached) the registry's detector
    torch.set_num_threads(threads)  # its build set the bench's thread count
    for rep in range(reps + 1):  # rep 0: warm-up
        for b in batches:
            for what, fn in (("forward", lambda: forward_all(b)), ("detect", lambda: detect_all(b))):
                t = timed(fn)
                if rep:
                    samples.setdefault((b, what), []).append(t)
        t = timed(registry_all)
        if rep:
            samples.setdefault((0, "registry"), []).append(t)

    def ms(key, k):
        return 1000.0 * statistics.median(s[k] for s in samples[key]) / n

    rows = []
    for b in batches:
        rows.append({"detector": split.name, "arch": split.arch, "threads": threads, "batch": b,
                     "forward_cpu_ms": ms((b, "forward"), 0), "forward_wall_ms": ms((b, "forward"), 1),
                     "detect_cpu_ms": ms((b, "detect"), 0), "detect_wall_ms": ms((b, "detect"), 1),
                     "registry_detect_cpu_ms": ms((0, "registry"), 0),
                     "registry_detect_wall_ms": ms((0, "registry"), 1)})
    base = next(r for r in rows if r["batch"] == batches[0])
    for r in rows:
        for k in ("forward_cpu", "forward_wall", "detect_cpu", "detect_wall"):
            r[f"{k}_ratio"] = ratio(r[f"{k}_ms"], base[f"{k}_ms"])
    return rows


# ---------------------------------------------------------------- inputs and report

def bench_views(profile, house: str, n_views: int, out: Path) -> tuple[list, dict]:
    """The first ``n_views`` views of ``house`` rendered as ``profile`` renders (images (H, W, 3)
    uint8), and where they come from."""
    from fenestra.bench.render_adapter import dataset_config  # noqa: PLC0415
    from fenestra.rendered_view import read_view  # noqa: PLC0415
    from fenestra.renders.dataset import render_dataset  # noqa: PLC0415

    cfg = dataclasses.replace(dataset_config(profile, house, out), n_views=n_views)
    root = Path(render_dataset(cfg, progress=False))
    images = [read_view(root / "views" / f"{i:06d}").image for i in range(n_views)]
    return images, {"house": house, "views": n_views, "renders": str(root.relative_to(ROOT) if root.is_relative_to(ROOT)
                                                                      else root),
                    "size": [int(images[0].shape[1]), int(images[0].shape[0])], "renderer": cfg.renderer,
                    "look_per": cfg.settings.look_per}


def markdown(doc: dict) -> str:
    src = doc["inputs"]
    lines = [f"`python tools/detector_batching.py {doc['args']}` (not in the Makefile): {src['views']} views of "
             f"`{src['house']}` rendered as profile `{doc['profile']}` renders them ({src['size'][0]}x{src['size'][1]} "
             f"{src['renderer']}, look per {src['look_per']}; the size the bench feeds the detector), through each "
             "learned detector the profile runs in consecutive batches of B views: **forward** the network alone on "
             "the batch, **detect** the whole detection (per-view input and post-processing around one forward of "
             "the batch; B = 1 is the per-view path). Milliseconds per view, process CPU and wall, median of "
             f"{doc['reps']} repetitions after a warm-up; ratio: to B = 1. {doc['machine']['cpu']}, "
             f"{doc['machine']['cores']} cores shared with other work (load {doc['machine']['load_before']:.1f} before, "
             f"{doc['machine']['load_after']:.1f} after), torch {doc['machine']['torch']}."
             + (f" Table written from that run's JSON by `{doc['table_from_json']}`." if "table_from_json" in doc else ""),
             "",
             "| detector | threads | B | forward CPU ms/view | ratio | forward wall ms/view | detect CPU ms/view | ratio "
             "| detect wall ms/view | outputs vs per view |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
    for r in doc["rows"]:
        c = r["check"]
        agree = ("same detections" if c["detections_agree"] else "detections differ") + \
            f", logits ±{c['max_abs_logit_diff']:.1e}"
        lines.append(f"| {r['detector']} ({r['arch']}) | {r['threads']} | {r['batch']} | {r['forward_cpu_ms']:.0f} | "
                     f"{r['forward_cpu_ratio']:.2f} | {r['forward_wall_ms']:.0f} | {r['detect_cpu_ms']:.0f} | "
                     f"{r['detect_cpu_ratio']:.2f} | {r['detect_wall_ms']:.0f} | {agree} |")
    ref = {(r["detector"], r["threads"]): r for r in doc["rows"]}
    lines += ["", "The registry's `detect` per view (what the bench's session calls), CPU ms/view: " + "; ".join(
        f"{d} at {t} thread{'s' if t > 1 else ''} {r['registry_detect_cpu_ms']:.0f}" for (d, t), r in ref.items()) + "."]
    for v in doc["verdicts"]:
        t = v["threads"]
        text = (f"**{v['detector']}, {t} thread{'s' if t > 1 else ''}**: the cheapest batch size (B = {v['best_batch']}) "
                f"costs {v['best_ratio']:.2f} × B = 1's detect CPU per view; batching pays at ≤ {v['threshold']:.2f} "
                f"(issue 34): **{'pays' if v['pays'] else 'does not pay'}**")
        if "vs_one_thread" in v:
            text += (f" at {t} threads, where B = {v['best_batch']} costs {v['vs_one_thread']:.2f} × the single view's "
                     "CPU at one thread (a bench worker's setting)")
        lines += ["", text + "."]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="default")
    ap.add_argument("--house", default="fzk-haus")
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--batches", default="1,2,4,8")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--reps", type=int, default=5)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "detector-batching")
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="detector-batching")
    ap.add_argument("--from-json", type=Path, default=None,
                    help="write the table of an earlier measurement's JSON (verdicts recomputed) instead of measuring")
    a = ap.parse_args()
    if a.from_json is not None:
        import json  # noqa: PLC0415

        doc = json.loads(a.from_json.read_text())
        doc["verdicts"] = [verdict(doc["rows"], v["detector"], v["threads"], doc["pays_threshold"])
                           for v in doc["verdicts"]]
        doc["table_from_json"] = f"python tools/detector_batching.py --from-json {a.from_json}"
        return report(doc, a)
    batches = [int(b) for b in a.batches.split(",")]
    threads = [int(t) for t in a.threads.split(",")]
    if batches[0] != 1 or sorted(set(batches)) != batches or a.views < max(batches) or a.reps < 1:
        ap.error("--batches must start at 1 and increase, --views be at least the largest batch, --reps >= 1")
    load_before = os.getloadavg()[0]
    import torch  # noqa: PLC0415

    from fenestra.bench.profiles import load_profile  # noqa: PLC0415
    from fenestra.bench.runner import plan_methods  # noqa: PLC0415
    from fenestra.pipeline.detectors import DETECTORS, detect  # noqa: PLC0415
    from fenestra.pipeline.session import CANDIDATE_SCORE_MIN  # noqa: PLC0415

    profile = load_profile(a.profile)
    methods, skipped = plan_methods(profile)
    learned = [d for d in dict.fromkeys(m.detector for m in methods) if DETECTORS[d].trainable]
    images, inputs = bench_views(profile, a.house, a.views, a.out / "renders")
    rows, verdicts, not_split = [], [], {}
    for name in learned:
        split = split_detector(name)
        if split is None:
            not_split[name] = "arch not known to this tool"
            continue
        for t in threads:
            torch.set_num_threads(t)
            reference = [detect(name, im, CANDIDATE_SCORE_MIN, threads=1) for im in images]
            torch.set_num_threads(t)
            checks = {b: check_outputs(split, images, b, reference) for b in batches}
            for b, c in checks.items():
                print(f"{name} threads={t} B={b}: max |logit diff| {c['max_abs_logit_diff']:.2e}, max |feature diff| "
                      f"{c['max_abs_feature_diff']:.2e}, detections {'agree' if c['detections_agree'] else 'DIFFER'}"
                      + (f" ({'; '.join(c['disagreements'][:3])})" if c["disagreements"] else ""), flush=True)
            for r in measure(split, images, batches, t, a.reps):
                r["check"] = checks[r["batch"]]
                rows.append(r)
                print(f"{name} threads={t} B={r['batch']}: forward {r['forward_cpu_ms']:.0f} ms CPU/view "
                      f"({r['forward_cpu_ratio']:.2f}), detect {r['detect_cpu_ms']:.0f} ms CPU/view "
                      f"({r['detect_cpu_ratio']:.2f}), registry detect {r['registry_detect_cpu_ms']:.0f}", flush=True)
            verdicts.append(verdict(rows, name, t))
    cpu = next((ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                if ln.startswith("model name")), platform.processor()) if Path("/proc/cpuinfo").is_file() else platform.processor()
    doc = {"command": f"python tools/detector_batching.py {' '.join(sys.argv[1:])}", "args": " ".join(sys.argv[1:]),
           "profile": profile.name, "inputs": inputs, "reps": a.reps, "batches": batches, "threads": threads,
           "detectors": learned, "skipped": skipped, "not_split": not_split, "pays_threshold": PAYS,
           "machine": {"cpu": cpu, "cores": os.cpu_count(), "torch": torch.__version__, "python": platform.python_version(),
                       "load_before": load_before, "load_after": os.getloadavg()[0]},
           "rows": rows, "verdicts": verdicts}
    report(doc, a)


def report(doc: dict, a: argparse.Namespace) -> None:
    """Print the Markdown table; write the JSON (``--json``) and the doc's block (``--doc``)."""
    text = markdown(doc)
    print(text)
    if a.json is not None:
        from fenestra.files import write_json  # noqa: PLC0415

        write_json(a.json, doc)
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)


if __name__ == "__main__":
    main()
