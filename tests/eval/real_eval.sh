#!/usr/bin/env bash
# One model on the development scans, as docs/EVALUATION.md's tables measure it: ism-eval real on
# the Kinect frames with the sample scene and on the SUN RGB-D and ScanNet clouds (AP over every
# candidate, down to confidence 0.01), and on all of them at the default operating point (r and false
# positives at min_confidence 0.5).
#   tests/eval/real_eval.sh BUILD_DIR MODEL PREFIX [ISM-EVAL OPTIONS...]
# Writes PREFIX.{all,organized,unorganized}.{json,txt,log} (the three runs side by side); tests/eval/real_row.py reads them.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$1 model=$2 prefix=$3
shift 3
real=$root/../shared/data/real
pids=()
for subset in all organized unorganized; do
  case $subset in
    all) scenes=("$real/kinect" "$root/models/sample/living_room.json" "$real/sunrgbd" "$real/scannet") ;;
    organized) scenes=("$real/kinect" "$root/models/sample/living_room.json") ;;
    unorganized) scenes=("$real/sunrgbd" "$real/scannet") ;;
  esac
  operating=--min-confidence=0.01
  [[ $subset == all ]] && operating=--min-confidence=0.5
  "$build/core/ism-eval" real -m "$model" "${scenes[@]}" "$@" $operating --json "$prefix.$subset.json" \
    > "$prefix.$subset.txt" 2> "$prefix.$subset.log" &
  pids+=($!)
done
for pid in "${pids[@]}"; do wait "$pid"; done
