"""A learned detector's figures over several seeds, per house: the median and the spread (min-max).

    .venv/bin/python tools/seed_spread.py [--profile heldout-seeds] [--seeds 0,1,2] [--views N] \
        [--method default/refine/wall+lines] [--doc docs/experiments.md --block seed-spread]

Runs the bench profile (``fenestra bench --profile P``: renders and all) once per seed, the seed
replacing the profile's (it draws the cameras and, with ``look_per = "view"``, every view's look),
``--views`` replacing its views per house, each run in ``out/bench/seed-spread/<profile>-s<seed>-<hash>``
(cached renders are reused; a cached run only when made at this commit with these weights). Per house and seed it takes the method's figures as the
results docs do (lab.docs: evaluable windows, detection rate, quads, all four
corners within 5 px, snapped corner median, rotation median, aspect-ratio error p90), and writes
one Markdown table: each figure's median over the seeds and its min-max, then the seeds' values
one by one, so a reader sees the spread instead of one lucky or unlucky draw (issue #36). The
houses are labelled by what they are to the detector (lab.docs.roles.house_role: held out,
same generator, trained on) and each role's houses are also pooled ("held-out families", ...). With
``--json`` the spread is also written as JSON (what the README's detector line quotes).
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

# (key of lab.docs.figures.house_figures, column title, scale, unit, decimals)
FIGURES = (("detection_rate", "detected", 100, " %", 0), ("quad_rate", "quads", 100, " %", 0),
           ("all_corners_close", "all corners within 5 px", 100, " %", 0),
           ("snap_median", "corner median", 1, " px", 2), ("rot_median", "rotation median", 1, "°", 2),
           ("aspect_p90", "aspect p90", 100, " %", 1),
           ("thin_quad_rate", "quads, thin windows", 100, " %", 0),
           ("oblique_quad_rate", "quads at {:g}–{:g}° incidence", 100, " %", 0))


def spread(values: list) -> tuple[float, float, float] | None:
    """(median, min, max) of the values that are not None; None when there is none."""
    import numpy as np  # noqa: PLC0415

    v = [float(x) for x in values if x is not None]
    return None if not v else (float(np.median(v)), min(v), max(v))


def cell(values: list, scale: float, unit: str, decimals: int) -> str:
    """``median [min-max]`` of per-seed values, each scaled, then the per-seed values in order."""
    s = spread(values)
    if s is None:
        return "-"
    f = lambda x: f"{scale * x:.{decimals}f}"  # noqa: E731
    each = ", ".join("-" if x is None else f(x) for x in values)
    return f"**{f(s[0])}**{unit} [{f(s[1])}–{f(s[2])}] ({each})"


def house_figures(df, method: str) -> dict[str, dict]:
    """house -> the figures of ``method`` (detector/snapper/pose[/quad_source]) on that house's rows, then the
    houses of each role together (lab.docs.roles.ROLE_GROUPS: "held-out families",
    "same generator", "trained-on houses"; a group only where the run has such a house)."""
    from fenestra.methods import Method  # noqa: PLC0415
    from lab.docs.figures import house_figures
    from lab.docs.roles import ROLE_GROUPS, house_role  # noqa: PLC0415

    m = Method.from_label(method)
    det = m.detector
    g = df[(df["detector"] == det) & (df["snapper"] == m.snapper) & (df["pose"] == m.pose_label)]
    if len(method.split("/")) == 4:  # a quad source named: that method's rows (its label as the bench writes it)
        g = g[g["method"] == m.label]
    out = {house: house_figures(rows) for house, rows in sorted(g.groupby("house"), key=lambda kv: kv[0])}
    roles = g["house"].map(lambda h: house_role(det, h))
    for role, label in ROLE_GROUPS.items():
        if (roles == role).any():
            out[label] = house_figures(g[roles == role])
    return out


def role_of(detector: str, house: str) -> str:
    """The role of a house row (lab.docs.roles.ROLES), or of a group row by its label."""
    from lab.docs.roles import ROLE_GROUPS, house_role  # noqa: PLC0415

    groups = {label: role for role, label in ROLE_GROUPS.items()}
    return groups.get(house) or house_role(detector, house)


def table(per_seed: dict[int, dict[str, dict]], detector: str) -> list[str]:
    """The Markdown table of {seed: {house: figures}}: per house, each figure's median over the
    seeds, [min-max], (the seeds' values in seed order); the role groups (bold) last."""
    from lab.docs.roles import ROLE_GROUPS  # noqa: PLC0415

    seeds = sorted(per_seed)
    names = {h for figs in per_seed.values() for h in figs}
    houses = sorted(names - set(ROLE_GROUPS.values())) + [g for g in ROLE_GROUPS.values() if g in names]
    from fenestra.conventions import OBLIQUE_INCIDENCE_DEG  # noqa: PLC0415

    head = ["house", "to the detector", "evaluable windows (per seed)"] + [title.format(*OBLIQUE_INCIDENCE_DEG)
                                                                          for _, title, *_ in FIGURES]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for h in houses:
        rows = [per_seed[s].get(h) or {} for s in seeds]
        n = ", ".join(str(r.get("n_evaluable", 0)) for r in rows)
        cells = [cell([r.get(k) for r in rows], scale, unit, dec) for k, _, scale, unit, dec in FIGURES]
        role = role_of(detector, h)
        name = f"**{h}**" if h in ROLE_GROUPS.values() else h
        lines.append(f"| {name} | {'**held out**' if role == 'held out' else role} | {n} | " + " | ".join(cells) + " |")
    return lines


def spread_json(per_seed: dict[int, dict[str, dict]], detector: str, meta: dict) -> dict:
    """The machine-readable spread (docs/results/seed_spread.json, read by tools/model_card_real.py for
    the README's detector line): meta, then per house or group its role and, per figure of FIGURES,
    the seeds' values (seed order), their median, min and max."""
    seeds = sorted(per_seed)
    names = sorted({h for figs in per_seed.values() for h in figs})
    houses = {}
    for h in names:
        rows = [per_seed[s].get(h) or {} for s in seeds]
        figs = {}
        for k, *_ in FIGURES + (("n_evaluable",), ("n_thin",), ("n_oblique",)):
            values = [rows[i].get(k) for i in range(len(seeds))]
            sp = spread(values)
            figs[k] = {"seeds": values, **({"median": sp[0], "min": sp[1], "max": sp[2]} if sp else {})}
        houses[h] = {"role": role_of(detector, h), "figures": figs}
    return {**meta, "seeds": seeds, "houses": houses}


def per_seed_from_json(doc: dict) -> dict[int, dict[str, dict]]:
    """The inverse of :func:`spread_json`: {seed: {house or group: {figure: value}}}."""
    return {s: {h: {k: f["seeds"][i] for k, f in v["figures"].items()} for h, v in doc["houses"].items()}
            for i, s in enumerate(doc["seeds"])}


def run_seed(profile, seed: int, views: int | None, out_root: Path, method: str | None = None):
    """The results table of ``profile`` run with ``seed`` (and ``views`` per house); with
    ``method`` (a label with a quad source, detector/snapper/pose/quad_source) that method alone
    instead of the profile's, in a run folder of its own."""
    from fenestra.bench.results import load_results  # noqa: PLC0415
    from fenestra.bench.runner import run_benchmark  # noqa: PLC0415
    from fenestra.methods import Method  # noqa: PLC0415

    p = dataclasses.replace(profile, seed=seed)
    if views is not None:
        p = dataclasses.replace(p, source=dataclasses.replace(
            p.source, render=dataclasses.replace(p.source.render, views_per_house=views)))
    methods = None if method is None else (Method.from_label(method),)
    suffix = "" if method is None else "-" + methods[0].quad_source.replace("+", "-")
    run_dir = out_root / f"{p.name}-s{seed}-{p.config_hash()}{suffix}"
    if not reusable(run_dir):
        run_benchmark(p, out_dir=run_dir, progress=False, report=None, force=run_dir.exists(), methods=methods)
    return load_results(run_dir)


def reusable(run_dir: Path) -> bool:
    """Whether a cached run may stand for a fresh one: complete, made at this commit with these
    weights (summary.json's ``commit`` and ``models``; a run of other weights is stale)."""
    import json  # noqa: PLC0415

    from fenestra.bench.results import SUMMARY_JSON, _commit, model_digests  # noqa: PLC0415

    try:
        meta = json.loads((run_dir / SUMMARY_JSON).read_text())["metadata"]
    except (OSError, ValueError, KeyError, TypeError):
        return False
    return ((run_dir / "results.parquet").is_file() and meta.get("commit") == _commit()
            and meta.get("models") == model_digests())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="heldout-seeds")
    ap.add_argument("--seeds", default="0,1,2", help="comma-separated seeds (at least 2)")
    ap.add_argument("--views", type=int, default=None, help="views per house (default: the profile's)")
    ap.add_argument("--method", default=None, help="detector/snapper/pose[/quad_source] (default: the CLI's, fenestra.conventions.DEFAULTS; "
                    "a quad source runs that method instead of the profile's)")
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "bench" / "seed-spread")
    ap.add_argument("--doc", type=Path, default=None)
    ap.add_argument("--block", default="seed-spread")
    ap.add_argument("--json", type=Path, default=None, help="also write the spread as JSON (e.g. docs/results/seed_spread.json)")
    ap.add_argument("--from-json", type=Path, default=None,
                    help="write the table from an earlier run's --json instead of running (other weights, say)")
    a = ap.parse_args()
    command = f"python tools/seed_spread.py {' '.join(sys.argv[1:])}"
    if a.from_json is not None:
        import json  # noqa: PLC0415

        meta = json.loads(a.from_json.read_text())
        per_seed, source = per_seed_from_json(meta), command
    else:
        meta, per_seed = measure(ap, a, command)
        source = None
    text = block_text(meta, per_seed, source)
    print(text)
    if a.json is not None and a.from_json is None:
        from fenestra.files import write_json  # noqa: PLC0415

        write_json(a.json, spread_json(per_seed, meta["method"].split("/")[0], meta))
    if a.doc is not None:
        from lab.docs.blocks import write_block  # noqa: PLC0415

        write_block(a.doc, a.block, text)


def measure(ap, a, command: str) -> tuple[dict, dict[int, dict[str, dict]]]:
    """(the run's meta, {seed: house_figures}) of the profile run once per seed of ``a.seeds``."""
    seeds = [int(s) for s in a.seeds.split(",")]
    if len(seeds) < 2 or len(set(seeds)) != len(seeds) or min(seeds) < 0:
        ap.error(f"--seeds needs at least 2 distinct seeds >= 0, got {a.seeds!r}")
    from fenestra.bench.profiles import load_profile  # noqa: PLC0415
    from fenestra.conventions import DEFAULTS  # noqa: PLC0415

    method = a.method or f"{DEFAULTS.detector}/{DEFAULTS.snapper}/{DEFAULTS.pose}"
    profile = load_profile(a.profile)
    render = profile.source.render
    look = dict(dict(render.options).get("settings", {})).get("look_per", "set")
    extra = method if len(method.split("/")) == 4 else None  # a quad source the profile cannot select
    per_seed = {s: house_figures(run_seed(profile, s, a.views, a.out, extra), method) for s in seeds}
    meta = {"command": command, "method": method, "profile": profile.name,
            "views_per_house": a.views or render.views_per_house, "look_per": look,
            "size": [render.width, render.height], "renderer": render.renderer,
            "seeds": seeds}
    return meta, per_seed


def block_text(meta: dict, per_seed: dict[int, dict[str, dict]], source: str | None = None) -> str:
    """The Markdown block: the run's command and setting, then :func:`table`; ``source``: the command
    that wrote it from the run's JSON, when it was not written by the run itself."""
    w, h = meta["size"]
    written = "." if source is None else f"; table written from that run's JSON by `{source}`."
    head = (f"`{meta['command']}`: `{meta['method']}` on profile `{meta['profile']}`, {meta['views_per_house']} "
            f"views per house and seed ({w}x{h} {meta['renderer']}, look drawn per {meta['look_per']}), seeds "
            f"{', '.join(map(str, sorted(per_seed)))}{written} Each cell: **median over the seeds** [min–max] (the "
            "seeds' values in order); quads and corners within 5 px are shares of the evaluable windows (a missed "
            "window counts as neither).")
    return "\n".join([head, ""] + table(per_seed, meta["method"].split("/")[0])) + "\n"

if __name__ == "__main__":
    main()
