#!/usr/bin/env bash
# Render the views the box verifier sees beside the real photos (fenestra/training/verifier.py): six chunks
# of make_data.sh's TRAIN renders (the same scenes, seeds and options: views the detector trained
# on; never samplehouse4, never the validation houses), 150 views, about a minute on 2 cores.
# Usage:  bash lab/scripts/verifier_data.sh [ROOT=out/verifier-renders]   (reruns reuse views)
# Then:   fenestra train-verifier out/train/default.pt --renders ROOT --render-views 150
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=${1:-out/verifier-renders}
PY=${PY:-.venv/bin/python}
export PYOPENGL_PLATFORM=egl

render() {  # scene seed [extra options]
  local scene=$1 seed=$2; shift 2
  $PY -m fenestra render --scene "$scene" --views 25 --seed "$seed" --renderer pyrender --out "$ROOT" "$@" | tail -1
}

render fzk-haus 1011
render duplex 1021
render jasmin-sun 1031
render niedriha 1041
render duplex 1022 --sensor
render niedriha 1042 --sensor
