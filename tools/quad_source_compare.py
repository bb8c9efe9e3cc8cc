"""The corner head's quads against the mask fit, through snapping and pose, on a bench profile.

    .venv/bin/python tools/quad_source_compare.py --profile smoke [--snappers none,linefit,lsd] \
        [--poses lm,wall+lines] [--out out/quadsrc-smoke] [--doc docs/experiments.md --block NAME]

Runs ``bench.runner.run_benchmark`` with the learned detector ``default`` and every snapper x pose
given, once per quad source of ``--sources``: ``mask`` (the fit to the mask, fenestra/pipeline/quad.py),
``corners`` (the corner heatmaps' peaks, falling back to the mask where they do not describe it),
``mask+corners`` (the mask fit, the corner heatmaps' peaks where it finds no quadrilateral),
and prints per method: windows with a quad, corner error after snapping (median px, share of
the bench's corner recall at 5 px), aspect-ratio error p90 and rotation error median. The bench
lets a profile select quad sources only through this override (fenestra.methods.Method). Each
source runs on its own: within one run the per-wall strategies reuse the per-window results of a
(snapper, pose, K) key without the quad source (fenestra/bench/evaluate.py ``_reconstruct``), so the
``corners`` per-wall rows would repeat the ``mask`` ones.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from fenestra.bench.profiles import load_profile  # noqa: E402
from fenestra.bench.runner import run_benchmark  # noqa: E402
from fenestra.methods import Method  # noqa: E402
from fenestra.pipeline.quad import QUAD_SOURCES  # noqa: E402


def table(results: dict, methods: list[Method]) -> list[str]:
    lines = ["| snapper | pose | quad source | evaluable | quads | corner error median px (snapped) | "
             "corner recall at 5 px | aspect error p90 | rotation error median deg | rotation error p90 deg |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for m in methods:
        r = results.get(m.label)
        if r is None:
            lines.append(f"| {m.snapper} | {m.pose_label} | {m.quad_source} | (no row) ||||||")
            continue
        c, a, rot = r["corner_err_px_snap"], r["aspect_err_rel"], r["rot_err_deg"]
        fmt = (lambda v, k=1.0, d=2: "-" if v is None else f"{k * v:.{d}f}")
        lines.append(f"| {m.snapper} | {m.pose_label} | {m.quad_source} | {r['n_evaluable']} | "
                     f"{100 * (1 - c['fail_rate']):.0f} % | {fmt(c['median'])} | {100 * c['recall']['5']:.0f} % | "
                     f"{fmt(a['p90'], 100, 1)} % | {fmt(rot['median'])} | {fmt(rot['p90'])} |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="smoke")
    ap.add_argument("--detector", default="default")
    ap.add_argument("--snappers", default="none,linefit,lsd")
    ap.add_argument("--poses", default="lm,wall+lines")
    ap.add_argument("--sources", default="mask,corners", help=f"quad sources, of {QUAD_SOURCES}")
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--reuse", action="store_true", help="table the run already in --out (same arguments)")
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default=None)
    a = ap.parse_args()
    profile = load_profile(a.profile)
    methods = [Method(a.detector, s, p, quad_source=q) for s in a.snappers.split(",")
               for p in a.poses.split(",") for q in a.sources.split(",")]
    out = a.out or Path("out") / f"quadsrc-{profile.name}"
    if not (a.reuse and (out / "summary.json").is_file()):
        # one run: the bench keys its per-wall reuse of per-window results on the quad parameters too
        run_benchmark(profile, out_dir=out, workers=a.workers, progress=False, report=None,
                      methods=tuple(methods), force=True)
    results = json.loads((out / "summary.json").read_text())["results"]
    lines = [f"`python tools/quad_source_compare.py {' '.join(sys.argv[1:])}` (profile {profile.name}, "
             f"detector {a.detector}; corner error after snapping, every corner of the evaluable windows)", ""]
    text = "\n".join(lines + table(results, methods)) + "\n"
    print(text)
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)


if __name__ == "__main__":
    main()
