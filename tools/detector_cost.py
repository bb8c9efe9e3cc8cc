"""What the default detector costs per photo, and where the time goes (issue #36's cost target).

    .venv/bin/python tools/detector_cost.py [--spb ../shared/real/spb_facades] [--photos 30] [--threads 2] \
        [--json docs/results/detector_cost.json] [--doc fenestra/pipeline/models/README.md --block cost]

Inputs: the first ``--photos`` photos of the validation part of ``SPB/train`` (every 5th photo by
sorted name, never trained on; never the 10 test photos), each resized to a 640 px long side
(INTER_AREA), what issue #36 timed. Each photo is detected ``--repeats`` times after one warm-up
photo, with ``--threads`` torch threads, and each stage is timed on its own (wall and process CPU,
milliseconds): ``network`` (the EffWin forward pass and its feature maps), ``instances`` (void and
core maps to instances, corner cuts), ``corners`` (each instance's four corners from the heatmaps),
``verifier`` (the box verifier on the backbone's features), and ``detect`` (the registry's
``detect("default", image)`` as the CLI calls it: everything above, end to end). Per stage: the
median over photos of each photo's median over the repeats. Also the shipped weights' size on disk
(every ``*.pt`` of fenestra/pipeline/models/). Exit status 1 when a target is missed
(:data:`TARGET_DETECT_MS`, wall; :data:`TARGET_WEIGHTS_MB`). Without the photos: one line, exit 2.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

SPB = ROOT.parent / "shared" / "real" / "spb_facades"
MODELS = ROOT / "fenestra" / "pipeline" / "models"
TARGET_DETECT_MS = 300.0  # issue #36: a 640x480 photo on the CPU with 2 threads (wall, median)
TARGET_WEIGHTS_MB = 60.0  # issue #36: the shipped weights together
LONG_SIDE = 640
STAGES = ("network", "instances", "corners", "verifier", "detect")


def load_photo(path: Path, long_side: int = LONG_SIDE):
    """(H, W, 3) uint8 RGB of a photo resized to ``long_side`` px on its long side (INTER_AREA)."""
    import cv2  # noqa: PLC0415

    from fenestra.images import read_image  # noqa: PLC0415

    image = read_image(path, "photo")
    s = long_side / max(image.shape[:2])
    return cv2.resize(image, (round(image.shape[1] * s), round(image.shape[0] * s)), interpolation=cv2.INTER_AREA)


def timed(fn, *args):
    """(fn(*args), wall ms, process CPU ms)."""
    w, c = time.perf_counter(), time.process_time()
    out = fn(*args)
    return out, 1e3 * (time.perf_counter() - w), 1e3 * (time.process_time() - c)


def stage_times(image, model, post, head) -> tuple[dict[str, tuple[float, float]], list, list]:
    """Each stage of the default detector on one image: ({stage: (wall ms, CPU ms)}, the staged
    detections, ``detect("default", image)``'s detections): the two lists must be the same."""
    from fenestra.pipeline.detectors import detect  # noqa: PLC0415
    from fenestra.pipeline.detectors.effwin import instance_corners, predict_maps_features  # noqa: PLC0415
    from fenestra.pipeline.detectors.verifier import classified  # noqa: PLC0415
    from fenestra.pipeline.detectors.winnet import instances_from_maps  # noqa: PLC0415
    from fenestra.pipeline.types import Detection  # noqa: PLC0415

    t = {}
    (maps, feats), *t["network"] = timed(predict_maps_features, model, image, post.mirror)
    dets, *t["instances"] = timed(instances_from_maps, maps[0], maps[1], post, maps[2:])
    corners, *t["corners"] = timed(lambda: [instance_corners(maps[2:], d.mask) for d in dets])
    dets = [Detection(d.mask, d.box, d.score, d.label, corners=c) for d, c in zip(dets, corners)]
    staged, *t["verifier"] = timed(lambda: [d for d in classified(dets, maps[0], feats, head) if d.kind == "window"])
    whole, *t["detect"] = timed(detect, "default", image)
    return {k: tuple(v) for k, v in t.items()}, staged, whole


def staged_detector(threads: int):
    """(EffWin, PostConfig, verifier head) of the shipped default weights, with ``threads`` torch
    threads set as the CLI sets them."""
    from fenestra.pipeline.detectors import DETECTORS, get_detector, read_weights  # noqa: PLC0415
    from fenestra.pipeline.detectors.effwin import model_from_checkpoint, post_config, verifier_from_checkpoint  # noqa: PLC0415

    get_detector("default", threads=threads)
    ckpt = read_weights(DETECTORS["default"].model.weights)
    model = model_from_checkpoint(ckpt)
    return model, post_config(ckpt), verifier_from_checkpoint(model, ckpt)


def measure(photos: list[Path], threads: int, repeats: int) -> dict:
    """Per stage the median over photos of the per-photo median (wall, CPU ms), and per photo its detect."""
    import torch  # noqa: PLC0415

    model, post, head = staged_detector(threads)
    images = [load_photo(p) for p in photos]
    stage_times(images[0], model, post, head)  # warm-up
    per_photo = []
    for path, image in zip(photos, images):
        runs = [stage_times(image, model, post, head)[0] for _ in range(repeats)]
        per_photo.append({"photo": path.name, "shape": list(image.shape[:2]),
                          **{s: [statistics.median(r[s][i] for r in runs) for i in (0, 1)] for s in STAGES}})
    stages = {s: {"wall_ms": statistics.median(p[s][0] for p in per_photo),
                  "cpu_ms": statistics.median(p[s][1] for p in per_photo)} for s in STAGES}
    return {"threads": torch.get_num_threads(), "repeats": repeats, "stages": stages, "photos": per_photo,
            "detect_wall_ms_max": max(p["detect"][0] for p in per_photo)}


def cpu_name() -> str:
    """The CPU's model name (/proc/cpuinfo), else the machine type."""
    info = Path("/proc/cpuinfo")
    names = [ln.split(":", 1)[1].strip() for ln in (info.read_text().splitlines() if info.is_file() else [])
             if ln.startswith("model name")]
    return f"{names[0]}, {len(names)} logical CPUs" if names else platform.machine()


def weights_mb() -> dict[str, float]:
    """{file name: MB} of the shipped weights (fenestra/pipeline/models/*.pt)."""
    return {p.name: p.stat().st_size / 1e6 for p in sorted(MODELS.glob("*.pt"))}


def markdown(result: dict, command: str) -> str:
    """The model card's cost block from one measurement's JSON."""
    st, w = result["stages"], result["weights_mb"]
    lines = [f"`{command}`: the first {result['n_photos']} validation photos of `spb_facades/train` (never "
             f"trained on) at a {LONG_SIDE} px long side, {result['threads']} torch threads, median over photos "
             f"of each photo's median over {result['repeats']} repeats after a warm-up; "
             f"{result['cpu']}, load {result['load_before']:.1f} before, {result['load_after']:.1f} after.", "",
             "| stage | wall ms | CPU ms |", "|---|---:|---:|"]
    names = {"network": "network (EffWin forward, feature maps)", "instances": "void/core maps -> instances, corner cuts",
             "corners": "corners from the heatmaps", "verifier": "box verifier (doors, signboards)",
             "detect": "**`detect(\"default\", image)`, end to end**"}
    lines += [f"| {names[s]} | {st[s]['wall_ms']:.0f} | {st[s]['cpu_ms']:.0f} |" for s in STAGES]
    total = sum(w.values())
    ok_t, ok_w = st["detect"]["wall_ms"] <= TARGET_DETECT_MS, total <= TARGET_WEIGHTS_MB
    lines += ["", f"Slowest photo: {result['detect_wall_ms_max']:.0f} ms wall. Shipped weights: "
              + ", ".join(f"`{k}` {v:.1f} MB" for k, v in w.items()) + f", {total:.1f} MB together.",
              f"Issue #36's targets: a photo at <= {TARGET_DETECT_MS:.0f} ms: **{'met' if ok_t else 'not met'}** "
              f"({st['detect']['wall_ms']:.0f} ms); weights <= {TARGET_WEIGHTS_MB:.0f} MB: "
              f"**{'met' if ok_w else 'not met'}** ({total:.1f} MB)."]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spb", type=Path, default=SPB)
    ap.add_argument("--photos", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="cost")
    ap.add_argument("--from-json", type=Path, default=None, help="write the block from an earlier measurement")
    a = ap.parse_args()
    command = "python tools/detector_cost.py " + " ".join(sys.argv[1:])
    if a.from_json is not None:
        result = json.loads(a.from_json.read_text())
    else:
        if not (a.spb / "train" / "images").is_dir():
            print(f"no St Petersburg photos: {a.spb / 'train' / 'images'} not found (give --spb)", file=sys.stderr)
            sys.exit(2)
        from fenestra.training.dataset import real_box_photos  # noqa: PLC0415

        photos = real_box_photos(a.spb / "train", "val")[: a.photos]
        load_before = os.getloadavg()[0]
        result = measure(photos, a.threads, a.repeats)
        result.update(n_photos=len(photos), weights_mb=weights_mb(), load_before=load_before,
                      load_after=os.getloadavg()[0], cpu=cpu_name())
        if a.json is not None:
            from fenestra.files import write_json  # noqa: PLC0415

            write_json(a.json, result)
    text = markdown(result, command)
    print(text)
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)
    ok = result["stages"]["detect"]["wall_ms"] <= TARGET_DETECT_MS and sum(result["weights_mb"].values()) <= TARGET_WEIGHTS_MB
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
