#!/usr/bin/env bash
# Render the detector training and held-out evaluation data (DESIGN.md dataset folders).
# Split: TRAIN on fzk-haus, duplex, jasmin-sun, niedriha + procedural houses (seeds 101..);
#        HELD OUT: samplehouse4 (never seen in training), used by `fenestra evaluate-detector`.
# Usage: bash pipeline/models/make_data.sh [OUT_ROOT=out/detector-data]
# Then:  fenestra train --config pipeline/models/default.toml --data out/detector-data/train-*
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=${1:-out/detector-data}
PY=${PY:-.venv/bin/python}
VIEWS=${VIEWS:-100}          # views per bundled training house
PROC_HOUSES=${PROC_HOUSES:-6}
PROC_VIEWS=${PROC_VIEWS:-40} # views per procedural house
EVAL_VIEWS=${EVAL_VIEWS:-80}
MITSUBA_VIEWS=${MITSUBA_VIEWS:-0}  # path-traced views per bundled training house (slow on CPU)
export PYOPENGL_PLATFORM=egl
mkdir -p "$ROOT"

render() {  # scene views seed renderer out
  [ -f "$5/coco.json" ] && { echo "have $5"; return; }
  $PY -m fenestra render --scene "$1" --views "$2" --seed "$3" --renderer "$4" --out "$5"
}

seed=1
for house in fzk-haus duplex jasmin-sun niedriha; do
  render "$house" "$VIEWS" $((1000 + seed)) pyrender "$ROOT/train-$house"
  if [ "$MITSUBA_VIEWS" -gt 0 ]; then
    render "$house" "$MITSUBA_VIEWS" $((2000 + seed)) mitsuba "$ROOT/train-$house-mitsuba"
  fi
  seed=$((seed + 1))
done
for i in $(seq 1 "$PROC_HOUSES"); do
  s=$((100 + i))
  ifc="$ROOT/procedural/house-$s.ifc"
  mkdir -p "$ROOT/procedural"
  [ -f "$ifc" ] || $PY -m fenestra scenes make "$ifc" --seed $s --storeys $((1 + i % 3)) \
      --windows-per-wall $((1 + i % 3)) --rotation-deg $((i * 17))
  render "$ifc" "$PROC_VIEWS" $((3000 + s)) pyrender "$ROOT/train-proc-$s"
done
render samplehouse4 "$EVAL_VIEWS" 9001 pyrender "$ROOT/heldout-samplehouse4"
echo "done: $ROOT"
