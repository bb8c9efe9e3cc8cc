#!/usr/bin/env bash
# Render the detector training data and the held-out evaluation data with `fenestra render`
# (renders/dataset.py; each call writes a hashed dataset folder under the given root).
#
# Split: TRAIN on fzk-haus, duplex, jasmin-sun, niedriha + procedural houses (scenes make, seeds
#        101..108). HELD OUT: samplehouse4, never seen in training.
# Domain randomisation: every chunk has its own seed, so its own look (palette, textures, sun, sky);
#        half the chunks add the realistic sensor model (noise, blur, JPEG), some radial distortion;
#        a path-traced (mitsuba) chunk per training house.
# Usage:  bash pipeline/models/make_data.sh [ROOT=out/detector-data]   (about 10 min on 2 cores)
# Then:   make train      (= fenestra train --config pipeline/models/default.toml)
set -euo pipefail
cd "$(dirname "$0")/../.."
ROOT=${1:-out/detector-data}
PY=${PY:-.venv/bin/python}
export PYOPENGL_PLATFORM=egl

render() {  # scene views seed renderer root [extra options]
  local scene=$1 views=$2 seed=$3 renderer=$4 root=$5; shift 5
  $PY -m fenestra render --scene "$scene" --views "$views" --seed "$seed" --renderer "$renderer" \
      --out "$root" "$@" | tail -1
}

# Bundled training houses: 6 raster chunks of 25 views + 1 mitsuba chunk of 20 views each.
h=0
for house in fzk-haus duplex jasmin-sun niedriha; do
  h=$((h + 1))
  for c in 1 2 3 4 5 6; do
    s=$((1000 + 10 * h + c))
    extra=()
    [ $((c % 2)) -eq 0 ] && extra+=(--sensor)
    [ "$c" -eq 3 ] && extra+=(--k1 0.15)
    [ "$c" -eq 5 ] && extra+=(--no-shadows)
    render "$house" 25 "$s" pyrender "$ROOT/train" "${extra[@]}"
  done
  render "$house" 20 $((2000 + h)) mitsuba "$ROOT/train" --spp 16
done

# Procedural houses (1-3 storeys, 1-3 windows per wall, rotated): 2 chunks of 20 views each.
mkdir -p "$ROOT/procedural"
for i in 1 2 3 4 5 6 7 8; do
  s=$((100 + i))
  ifc="$ROOT/procedural/house-$s.ifc"
  [ -f "$ifc" ] || $PY -m fenestra scenes make "$ifc" --seed $s --storeys $((1 + i % 3)) \
      --windows-per-wall $((1 + (i / 2) % 3)) --rotation-deg $((i * 17))
  render "$ifc" 20 $((3000 + s)) pyrender "$ROOT/train"
  render "$ifc" 20 $((4000 + s)) pyrender "$ROOT/train" --sensor
done

# Held-out house: raster (4 looks, 2 with the sensor model) and path-traced.
for c in 1 2 3 4; do
  extra=()
  [ $((c % 2)) -eq 0 ] && extra+=(--sensor)
  render samplehouse4 25 $((9000 + c)) pyrender "$ROOT/heldout-pyrender" "${extra[@]}"
done
render samplehouse4 24 9100 mitsuba "$ROOT/heldout-mitsuba" --spp 16
echo "done: $ROOT"
