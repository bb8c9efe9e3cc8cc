#!/usr/bin/env bash
# Render the views the learned corner refinement (fenestra/pipeline/snappers/refine.py, fenestra/training/refine.py)
# trains on: the detector's TRAINING houses only (fzk-haus, duplex, jasmin-sun, niedriha, the
# procedural houses of make_data.sh's seeds 101..108, and since refine v2 the varied houses 111..126
# and the street houses 151..169 (odd seeds) of fenestra/training/houses.py, whose glass sits
# 0.05-0.30 m behind the wall face: the corner to find is the opening's on the outer face, the reveal
# included, where a detector's mask stops at the glass), with render seeds of their own (7000+), half
# of the chunks with the sensor model (noise, blur, JPEG), the recessed houses with a look per view.
# Never samplehouse4 or any other held-out bench house, never the bench's procedural seeds 0, 1, 2
# (unseen houses), never the validation seeds 201..216.
# About 6 minutes on 2 cores; reruns reuse rendered views.
# Usage:  bash fenestra/training/scripts/refine_data.sh [ROOT=out/refine-data]
# Then:   fenestra train-refine --data ROOT
set -euo pipefail
cd "$(dirname "$0")/../../.."
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

# Recessed openings (refine v2): reveals 0.05-0.30 m, frames, sills, architraves, the wide look.
$PY -m fenestra.training.houses varied "$ROOT/procedural" >/dev/null
$PY -m fenestra.training.houses street "$ROOT/procedural" >/dev/null
for s in $(seq 111 126); do
  render "$ROOT/procedural/varied-$s.ifc" 6 $((7300 + s)) --look-per view $( [ $((s % 2)) -eq 0 ] && echo --sensor )
done
for s in $(seq 151 2 169); do
  render "$ROOT/procedural/street-$s.ifc" 8 $((7400 + s)) --look wide --look-per view --street-fraction 0.5 \
      $( [ $((s % 4)) -eq 1 ] && echo --sensor )
done
echo "done: $ROOT"
