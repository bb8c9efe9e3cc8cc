#!/usr/bin/env bash
# The "street" chunks of the detector data (issue #23 item 3; called by make_data.sh): procedural
# town houses whose windows have frames, mullions and transoms round glass panes
# (HouseSpec.window_styles), sills, architraves and shutters (HouseSpec ornament), 2-4 storeys of
# tall windows, some with a glazed door or a roof overhang; rendered with the wide look (renders/
# materials.py: St Petersburg plaster palette, brick and ashlar walls, glass variety, clear / low
# sun / overcast light) at street level and from oblique, far cameras.
#
# Split: seeds 151..170 TRAIN (ROOT/train-street), 213..216 VALIDATION (ROOT/val). Never samplehouse4
# or the bench's procedural houses.
# Usage:  bash fenestra/training/scripts/make_data_street.sh [ROOT=out/detector-data]   (reruns reuse views)
set -euo pipefail
cd "$(dirname "$0")/../../.."
ROOT=${1:-out/detector-data}
PY=${PY:-.venv/bin/python}
export PYOPENGL_PLATFORM=egl
mkdir -p "$ROOT/procedural"

$PY - "$ROOT/procedural" <<'PYEOF'
import sys
from dataclasses import replace
from pathlib import Path
from fenestra.scenes.generate import HouseSpec, make_house
root = Path(sys.argv[1])
FOOTPRINTS = [((0, 0), (18, 0), (18, 9), (0, 9)), ((0, 0), (12, 0), (12, 10), (0, 10)),
              ((0, 0), (24, 0), (24, 8), (0, 8)), ((0, 0), (14, 0), (16, 5), (14, 10), (0, 10))]
SIZES = [((0.9, 1.5), (1.5, 2.2)), ((0.7, 1.2), (1.2, 1.8)), ((1.0, 2.2), (1.0, 1.6)), ((0.5, 1.6), (0.6, 2.2))]
for seed in list(range(151, 171)) + list(range(213, 217)):
    wr, hr = SIZES[seed % 4]
    spec = HouseSpec(seed=seed, footprint=FOOTPRINTS[(seed // 4) % 4], storeys=2 + seed % 3,
                     storey_height=(3.0, 3.3, 3.6)[seed % 3], wall_thickness=(0.4, 0.5, 0.6)[(seed // 2) % 3],
                     reveal_depth=(0.1, 0.15, 0.25)[(seed // 3) % 3], rotation_deg=(seed * 37) % 90,
                     windows_per_wall=2 + (seed // 2) % 4, width_range=wr, height_range=hr,
                     window_styles=("frame", "mullion", "transom", "grid"),
                     sill_depth=(0.0, 0.06, 0.1)[seed % 3], surround_width=(0.0, 0.1, 0.16, 0.22)[(seed // 2) % 4],
                     shutters=seed % 5 == 0, roof_overhang=(0.0, 0.4)[(seed // 5) % 2],
                     fascia_height=(0.0, 0.3)[(seed // 5) % 2])
    out = root / f"street-{seed}.ifc"
    if out.exists():
        continue
    for doors in ((1,) if seed % 4 == 0 else ()) + (0,):
        try:  # no glazed door where the house has no suitable wall for one
            h = make_house(replace(spec, glazed_doors=doors), out)
            break
        except ValueError as e:
            print(f"{out.name}: {e}; trying without a door")
    print(f"{out}: {len(h.windows)} windows, {len(h.doors)} doors")
PYEOF

render() {  # scene views seed renderer root [extra options]
  local scene=$1 views=$2 seed=$3 renderer=$4 root=$5; shift 5
  $PY -m fenestra render --scene "$scene" --views "$views" --seed "$seed" --renderer "$renderer" \
      --out "$root" --look wide "$@" | tail -1
}
for s in $(seq 151 170); do
  ifc="$ROOT/procedural/street-$s.ifc"
  render "$ifc" 20 $((10000 + s)) pyrender "$ROOT/train-street" --look-per view --street-fraction 0.7
  render "$ifc" 20 $((10500 + s)) pyrender "$ROOT/train-street" --look-per view --sensor --distance-max 22 --azimuth-max 70 --street-fraction 0.5
  if [ $((s % 4)) -eq 0 ]; then render "$ifc" 8 $((11000 + s)) mitsuba "$ROOT/train-street" --spp 16; fi
done
for s in 213 214 215 216; do  # validation split
  ifc="$ROOT/procedural/street-$s.ifc"
  render "$ifc" 20 $((12000 + s)) pyrender "$ROOT/val" --sensor --street-fraction 0.5
done
echo "done: $ROOT (street)"
