#!/usr/bin/env bash
# WinNet recipe search on the GPU machine: variants of the WinNet config (winnet.toml) trained side by side on
# the same data and scored on validation (houses 201-208) and on fzk-haus, a bundled IFC house that
# is taken out of the training data for this search (leave-one-house-out). Never on samplehouse4.
# The record of the session-4 search (H100) is docs/experiments/winnet-search-h100.json.
#
# Here:  python lab/pack_data.py data.tar.xz --train-step 2 --jpeg-quality 70 \
#            out/detector-data/train out/detector-data/val          # ~31 MiB, 1204 + 288 views
# There: tar -xJf data.tar.xz && bash lab/scripts/gpu_winnet_search.sh OUT_DIR [VARIANT ...]
#
# Each variant is winnet.toml with the keys below replaced (iterations and crop given
# explicitly, so the variants do not move when winnet.toml does), device cuda, and its own batch-
# making worker processes (the machine's 16 cores are shared among the variants run together).
# CONFIGS_ONLY=1 writes the variants' configs to OUT_DIR and stops (tests/training/test_training.py).
set -euo pipefail
cd "$(dirname "$0")/../.."
OUTD=$1; shift
mkdir -p "$OUTD"
PY=${PY:-python3}
declare -A SET=(
  [base]="iterations=10000 crop_hw=[256,256]"
  [seed1]="iterations=10000 crop_hw=[256,256] seed=1"
  [scalelo]="iterations=10000 crop_hw=[256,256] scale_range=[0.25,1.0]"
  [lr6]="iterations=10000 crop_hw=[256,256] lr=6e-3"
  [crop384]="iterations=5000 crop_hw=[384,384]"
  [it16k]="iterations=16000 crop_hw=[256,256]"
  [c224]="iterations=16000 crop_hw=[224,224]"
)
VARIANTS=${*:-base seed1 it16k}
WORKERS=${WORKERS:-5}
for v in $VARIANTS; do
  [ -n "${SET[$v]+x}" ] || { echo "unknown variant $v (known: ${!SET[*]})" >&2; exit 1; }
  cfg="$OUTD/$v.toml"
  sed -e "s#^out = .*#out = \"$OUTD/$v.pt\"#" -e 's#^save_every = .*#save_every = 100000\ndevice = "cuda"#' \
      fenestra/training/configs/winnet.toml > "$cfg"
  for kv in ${SET[$v]}; do
    sed -i "s#^${kv%%=*} = .*#${kv%%=*} = ${kv#*=}#" "$cfg"
    grep -qxF "${kv%%=*} = ${kv#*=}" "$cfg" || { echo "variant $v: key ${kv%%=*} not in winnet.toml" >&2; exit 1; }
  done
done
[ "${CONFIGS_ONLY:-0}" = 1 ] && exit 0
mkdir -p "$OUTD/loho"
cp -r out/detector-data/train/fzk-haus-* "$OUTD/loho/"  # a copy: the data folder is left as it is
TRAIN=()
for d in out/detector-data/train/*/; do
  case "$(basename "$d")" in fzk-haus-*) ;; *) TRAIN+=(--data "${d%/}") ;; esac
done
for v in $VARIANTS; do
  cfg="$OUTD/$v.toml"
  ( $PY -m fenestra train --config "$cfg" "${TRAIN[@]}" --workers "$WORKERS" > "$OUTD/$v.train.log" 2>&1
    for split in out/detector-data/val "$OUTD/loho"; do
      $PY -m fenestra evaluate-detector --weights "$OUTD/$v.pt" --device cuda --data "$split" \
          --json "$OUTD/$v-$(basename "$split").json" > /dev/null
    done
    echo "done: $v" ) &
done
wait
$PY - "$OUTD" $VARIANTS <<'PY'
import json, sys
for v in sys.argv[2:]:
    r = {s: json.load(open(f"{sys.argv[1]}/{v}-{s}.json")) for s in ("val", "loho")}
    print(v, "  ".join(f"{s} segm {100 * m['segm']['AP']:.1f}/{100 * m['segm']['AP50']:.1f} bbox {100 * m['bbox']['AP']:.1f}"
                       for s, m in r.items()))
PY
