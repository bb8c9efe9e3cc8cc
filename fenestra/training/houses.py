"""The procedural training houses of the detector and corner-refinement data, by family.

    python -m fenestra.training.houses varied ROOT   # ROOT/varied-<seed>.ifc (make_data.sh)
    python -m fenestra.training.houses facade ROOT   # ROOT/facade-<seed>.ifc (make_data.sh)
    python -m fenestra.training.houses street ROOT   # ROOT/street-<seed>.ifc (make_data_street.sh)

Each family is a list of (file name, HouseSpec) drawn from the seed alone, so every script that
names a house (the detector data: make_data.sh, make_data_street.sh) gets the same one. A file already there is
kept (reruns reuse it); a new one is written under a ``.part`` name and renamed when whole.
Seeds: varied 111..126 train, 201..204 validation; facade 131..146 train,
205..208 validation; street 151..170 train, 213..216 validation. Never the bench's procedural seeds
0, 1, 2 (docs/DESIGN.md Decisions: one procedural seed never trains a shipped detector).

- ``varied``: strip windows of extreme aspect ratio close under the ceiling slab, small windows,
  tall glazed openings, reveals 0.05-0.30 m, other footprints, 2.5-3.2 m storeys.
- ``facade``: the same styles plus roof overhangs with a dark fascia band and eave shadow over the
  top windows, glazed doors and glazed curtain walls (IfcDoor / IfcPlate: unlabelled glazing,
  i.e. negatives). Fewer doors / no curtain wall where a house has no suitable wall for them.
- ``street``: town houses whose windows have frames, mullions and transoms round glass panes, sills,
  architraves and shutters, 2-4 storeys of tall windows, reveals 0.10-0.25 m, some with a glazed
  door or a roof overhang.
"""
from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

from fenestra.scenes.generate import HouseSpec, make_house

TRAIN_SEEDS = {"varied": range(111, 127), "facade": range(131, 147), "street": range(151, 171)}
VALIDATION_SEEDS = {"varied": range(201, 205), "facade": range(205, 209), "street": range(213, 217)}

# width_range, height_range (m), windows per wall, storey height (m), wall thickness (m), reveal (m)
STYLES = {
    "strip": ((1.4, 3.6), (0.3, 0.7), 2, 2.6, 0.3, 0.1),
    "small": ((0.3, 0.7), (0.3, 0.8), 4, 3.0, 0.35, 0.15),
    "tall": ((0.5, 1.1), (1.5, 2.4), 3, 3.2, 0.3, 0.05),
    "mixed": ((0.4, 2.6), (0.4, 1.9), 3, 2.8, 0.5, 0.3),
}
FOOTPRINTS = [((0, 0), (12, 0), (12, 8), (0, 8)),
              ((0, 0), (16, 0), (16, 6), (0, 6)),
              ((0, 0), (10, 0), (13, 4), (10, 8), (0, 8)),
              ((0.0, 0.0), (9.0, 0.0), (11.5, 4.5), (7.0, 9.0), (-1.5, 6.5))]
STREET_FOOTPRINTS = [((0, 0), (18, 0), (18, 9), (0, 9)), ((0, 0), (12, 0), (12, 10), (0, 10)),
                     ((0, 0), (24, 0), (24, 8), (0, 8)), ((0, 0), (14, 0), (16, 5), (14, 10), (0, 10))]
STREET_SIZES = [((0.9, 1.5), (1.5, 2.2)), ((0.7, 1.2), (1.2, 1.8)), ((1.0, 2.2), (1.0, 1.6)), ((0.5, 1.6), (0.6, 2.2))]


def varied_spec(seed: int) -> HouseSpec:
    """The ``varied`` house of a seed: style ``seed % 4`` of STYLES, 1-3 storeys."""
    wr, hr, n, sh, th, rev = STYLES[list(STYLES)[seed % 4]]
    return HouseSpec(seed=seed, footprint=FOOTPRINTS[(seed // 4) % 4], storeys=1 + seed % 3,
                     storey_height=sh, wall_thickness=th, reveal_depth=rev, rotation_deg=(seed * 23) % 90,
                     windows_per_wall=1 + (seed // 2) % n, width_range=wr, height_range=hr)


def facade_spec(seed: int) -> HouseSpec:
    """The ``facade`` house of a seed before its doors and curtain walls (:func:`facade_variants`)."""
    wr, hr, n, sh, th, rev = STYLES[list(STYLES)[seed % 4]]
    return HouseSpec(seed=seed, footprint=FOOTPRINTS[(seed // 4) % 4], storeys=1 + seed % 2,
                     storey_height=max(sh, 2.6), wall_thickness=th, reveal_depth=rev,
                     rotation_deg=(seed * 31) % 90, windows_per_wall=1 + (seed // 2) % n,
                     width_range=wr, height_range=hr,
                     roof_overhang=(0.3, 0.5, 0.8, 1.1)[(seed // 3) % 4],
                     fascia_height=(0.25, 0.4, 0.6)[seed % 3])


def street_spec(seed: int) -> HouseSpec:
    """The ``street`` house of a seed before its glazed door (:func:`street_variants`)."""
    wr, hr = STREET_SIZES[seed % 4]
    return HouseSpec(seed=seed, footprint=STREET_FOOTPRINTS[(seed // 4) % 4], storeys=2 + seed % 3,
                     storey_height=(3.0, 3.3, 3.6)[seed % 3], wall_thickness=(0.4, 0.5, 0.6)[(seed // 2) % 3],
                     reveal_depth=(0.1, 0.15, 0.25)[(seed // 3) % 3], rotation_deg=(seed * 37) % 90,
                     windows_per_wall=2 + (seed // 2) % 4, width_range=wr, height_range=hr,
                     window_styles=("frame", "mullion", "transom", "grid"),
                     sill_depth=(0.0, 0.06, 0.1)[seed % 3], surround_width=(0.0, 0.1, 0.16, 0.22)[(seed // 2) % 4],
                     shutters=seed % 5 == 0, roof_overhang=(0.0, 0.4)[(seed // 5) % 2],
                     fascia_height=(0.0, 0.3)[(seed // 5) % 2])


def variants(family: str, seed: int) -> list[HouseSpec]:
    """The specs to try for a seed, richest first: the first that ``make_house`` accepts is written."""
    if family == "varied":
        return [varied_spec(seed)]
    if family == "facade":
        base = facade_spec(seed)
        return [replace(base, glazed_doors=doors, curtain_walls=int(cws))
                for doors, cws in ((1 + seed % 2, seed % 2 == 0), (1, seed % 2 == 0), (1, False), (0, False))]
    if family == "street":
        base = street_spec(seed)
        return [replace(base, glazed_doors=d) for d in ((1,) if seed % 4 == 0 else ()) + (0,)]
    raise ValueError(f"house family {family!r} unknown; choose from {sorted(TRAIN_SEEDS)}")


def write_family(family: str, root: Path) -> list[Path]:
    """Write ROOT/<family>-<seed>.ifc for every train and validation seed (files there are kept)."""
    root.mkdir(parents=True, exist_ok=True)
    out = []
    for seed in list(TRAIN_SEEDS[family]) + list(VALIDATION_SEEDS[family]):
        path = root / f"{family}-{seed}.ifc"
        out.append(path)
        if path.exists():
            continue
        specs = variants(family, seed)
        part = path.with_name(path.name + ".part")  # written whole, then renamed: a rerun never keeps half a house
        for i, spec in enumerate(specs):
            try:
                h = make_house(spec, part)
                break
            except ValueError as e:
                if i == len(specs) - 1:
                    raise
                print(f"{path.name}: {e}; trying fewer features")
        part.replace(path)
        print(f"{path}: {len(h.windows)} windows, {len(h.doors)} doors, {len(h.curtain_walls)} curtain-wall bays")
    return out


def main(argv: list[str]) -> int:
    if len(argv) != 2 or argv[0] not in TRAIN_SEEDS:
        print(f"usage: python -m fenestra.training.houses {{{','.join(TRAIN_SEEDS)}}} ROOT", file=sys.stderr)
        return 2
    write_family(argv[0], Path(argv[1]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
