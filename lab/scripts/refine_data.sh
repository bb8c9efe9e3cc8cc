#!/usr/bin/env bash
# Render the views the learned corner refinement (fenestra/pipeline/snappers/refine.py, fenestra/training/refine.py)
# trains on: the detector's TRAINING houses only (fzk-haus, duplex, jasmin-sun, niedriha and the
# procedural houses of make_data.sh's seeds 101..108), with render seeds of their own (7000+), half
# of the chunks with the sensor model (noise, blur, JPEG). Never samplehouse4, never the bench's
# procedural seeds 0, 1, 2 (unseen houses), never the validation seeds 201..208.
# About 3 minutes on 2 cores; reruns reuse rendered views.
# Usage:  bash lab/scripts/refine_data.sh [ROOT=out/refine-data]
# Then:   fenestra train-refine --data ROOT
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=${1:-out/refine-data}
PY=${PY:-.venv/bin/python}
export PYOPENGL_PLATFORM=egl

render() {  # scene views seed [extra options]
  local scene=$1 views=$2 seed=$3; shift 3
  $PY -m fenestra render --scene "$scene" --views "$views" --seed "$seed" --renderer pyrender --out "$ROOT/train" "$@" | tail -1
}

h=0
for house in fzk-haus duplex jasmin-sun niedriha; do
  h=$((h + 1))
  render "$house" 30 $((7000 + 10 * h + 1))
  render "$house" 30 $((7000 + 10 * h + 2)) --sensor
done

mkdir -p "$ROOT/procedural"
for i in 1 2 3 4 5 6 7 8; do  # the houses of make_data.sh's `scenes make` seeds 101..108
  s=$((100 + i))
  ifc="$ROOT/procedural/house-$s.ifc"
  [ -f "$ifc" ] || $PY -m fenestra scenes make "$ifc" --seed $s --storeys $((1 + i % 3)) \
      --windows-per-wall $((1 + (i / 2) % 3)) --rotation-deg $((i * 17))
  render "$ifc" 15 $((7100 + s))
  render "$ifc" 15 $((7200 + s)) --sensor
done
echo "done: $ROOT"
