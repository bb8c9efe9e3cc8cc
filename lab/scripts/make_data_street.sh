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
# Usage:  bash lab/scripts/make_data_street.sh [ROOT=out/detector-data]   (reruns reuse views)
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=${1:-out/detector-data}
PY=${PY:-.venv/bin/python}
export PYOPENGL_PLATFORM=egl
mkdir -p "$ROOT/procedural"

$PY -m fenestra.training.houses street "$ROOT/procedural"  # specs: fenestra/training/houses.py

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
