#!/usr/bin/env bash
# Variants of training compared over several draws of its randomness. One model's figures on the
# development scans move with the k-means start, the sensor noise and the calibration rooms (the
# clouds' mAP by about +-1.5 points), which is as much as most single steps change them; each
# variant is therefore trained with the same seeds and compared seed by seed with the first.
#   tests/eval/seeds.sh BUILD_DIR OUTPUT.md "NAME|ISM-TRAIN OPTIONS|WHAT[|ISM-EVAL OPTIONS]" ... [-- SEED...]
# Seeds default to 1 2 3 4. About 2 minutes per variant and seed on 2 cores. Models, ism-eval's
# JSON and the training logs stay in BUILD_DIR/seeds/; with ISM_SEEDS_REUSE=1 a variant and seed
# evaluated there before is not trained again. The option --background (not ism-train's) trains on
# the manifest with the background meshes (models/default/background.tsv), as ablation.sh's row;
# with ism-train's --manifest among the options, that manifest is trained on instead. A step of
# recognition alone: ISM-TRAIN OPTIONS "=NAME" evaluates the models of the variant NAME (listed
# before it) again, with its own ISM-EVAL OPTIONS.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "$1" && pwd)
out=$2
shift 2
variants=()
while (($#)) && [[ $1 != -- ]]; do variants+=("$1"); shift; done
[[ ${1:-} == -- ]] && shift
seeds=("$@")
((${#seeds[@]})) || seeds=(1 2 3 4)
((${#variants[@]})) || { echo "usage: $0 BUILD_DIR OUTPUT.md \"NAME|ISM-TRAIN OPTIONS|WHAT\"... [-- SEED...]" >&2; exit 2; }
# shellcheck source=tests/eval/common.sh
source "$root/tests/eval/common.sh"
work=$build/seeds
mkdir -p "$work"
names=()
for variant in "${variants[@]}"; do
  IFS='|' read -r name train_args what eval_args <<< "$variant"
  names+=("$name|$what")
  use=(--manifest "$manifest")
  if [[ " $train_args " == *" --manifest "* ]]; then
    use=()
  elif [[ " $train_args " == *" --background "* ]]; then
    use=(--manifest "$background_manifest")
    train_args=${train_args//--background/}
  fi
  for seed in "${seeds[@]}"; do
    model=$work/$name.$seed.ismm
    if [[ ${ISM_SEEDS_REUSE:-0} == 1 && -f $work/$name.$seed.unorganized.json ]]; then
      echo "seeds: $name seed $seed kept" >&2
      continue
    fi
    if [[ $train_args == =* ]]; then
      model=$work/${train_args#=}.$seed.ismm
      [[ -f $model ]] || { echo "seeds: $name needs $model (list ${train_args#=} before it)" >&2; exit 1; }
    else
      # shellcheck disable=SC2086
      "$build/core/ism-train" "${use[@]}" -o "$model" --codebook global --no-scene-smoothing --seed "$seed" \
        $train_args > "$work/$name.$seed.train.log"
    fi
    # shellcheck disable=SC2086
    "$root/tests/eval/real_eval.sh" "$build" "$model" "$work/$name.$seed" $eval_args
    echo "seeds: $name seed $seed done" >&2
  done
done

PYTHONPATH=$root/tests/eval /usr/bin/python3 - "$work" "${seeds[*]}" "${names[@]}" > "$out" <<'PY'
import statistics
import sys
from real_row import figures, pct
work, seeds, variants = sys.argv[1], sys.argv[2].split(), sys.argv[3:]
keys = [("frames", "Kinect + sample mAP@0.25"), ("clouds", "SUN RGB-D + ScanNet mAP@0.25"),
        ("chair", "chair AP@0.25"), ("table", "table AP@0.25"), ("sofa", "sofa AP@0.25"),
        ("chair_r", "chair r at 0.5"), ("fp_per_scan", "FP per scan at 0.5")]


def values(name, seed):
    f = figures(f"{work}/{name}.{seed}")
    f["chair"], f["table"], f["sofa"] = f.pop("per_class")
    return f


runs = {v.split("|")[0]: {s: values(v.split("|")[0], s) for s in seeds} for v in variants}
first = variants[0].split("|")[0]
print(f"Means over seeds {', '.join(seeds)}; in brackets, the change from the first row seed by seed (lowest .. "
      "highest). Percentages, but FP per scan.\n")
print("| variant | " + " | ".join(title for _, title in keys) + " |")
print("|---|" + "---|" * len(keys))
for v in variants:
    name, what = v.split("|")
    cells = []
    for key, _ in keys:
        scale = 1 if key == "fp_per_scan" else 100
        vals = [runs[name][s][key] for s in seeds]
        cell = f"{scale * statistics.mean(vals):.1f}" if key != "fp_per_scan" else f"{statistics.mean(vals):.2f}"
        if name != first:
            diffs = [scale * (runs[name][s][key] - runs[first][s][key]) for s in seeds]
            cell += f" ({min(diffs):+.1f} .. {max(diffs):+.1f})"
        cells.append(cell)
    print(f"| {what} | " + " | ".join(cells) + " |")
print()
print("Per seed, the clouds' mAP@0.25: " + "; ".join(
    f"{v.split('|')[0]} " + " ".join(pct(runs[v.split('|')[0]][s]["clouds"]) for s in seeds) for v in variants))
PY
