#!/usr/bin/env bash
# Train and evaluate Mask R-CNN (fenestra/training/configs/maskrcnn-r50-gpu.toml) on the GPU machine in one go.
# Usage: bash lab/scripts/gpu_maskrcnn.sh DATA_ROOT OUT_DIR [TRAIN_SECONDS=330]
#   DATA_ROOT holds train/, val/, heldout-pyrender/, heldout-mitsuba/ (lab/scripts/make_data.sh).
# A 30-iteration probe measures the speed; the run then gets as many iterations as fit in
# TRAIN_SECONDS (printed, and recorded in the weights' train_config). Metrics: OUT_DIR/eval-*.json.
set -euo pipefail
cd "$(dirname "$0")/../.."
DATA=$1 OUTD=$2 BUDGET=${3:-330}
PY=${PY:-python3}
mkdir -p "$OUTD"
$PY -m fenestra train --config fenestra/training/configs/maskrcnn-r50-gpu.toml --data "$DATA/train" --iterations 30 \
    --out "$OUTD/probe.pt" > "$OUTD/probe.log"
rate=$($PY -c "import csv,sys; r=list(csv.DictReader(open(sys.argv[1]))); print((float(r[-1]['elapsed_s'])-float(r[1]['elapsed_s']))/(int(r[-1]['iteration'])-int(r[1]['iteration'])))" "$OUTD/probe.loss.csv")
ITER=$($PY -c "print(int($BUDGET / $rate) // 100 * 100)")
echo "probe: $rate s/iteration -> $ITER iterations in ~${BUDGET}s"
$PY -m fenestra train --config fenestra/training/configs/maskrcnn-r50-gpu.toml --data "$DATA/train" --iterations "$ITER" \
    --out "$OUTD/maskrcnn.pt" | awk 'NR % 10 == 1'
for split in val heldout-pyrender heldout-mitsuba; do
  $PY -m fenestra evaluate-detector --detector maskrcnn --weights "$OUTD/maskrcnn.pt" --device cuda \
      --data "$DATA/$split" --json "$OUTD/eval-$split.json"
done
