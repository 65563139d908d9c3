#!/usr/bin/env bash
# The ablation of docs/EVALUATION.md: one model per step of the default pipeline, each trained
# from the shipped model's meshes (Debian's sweethome3d-furniture) and evaluated with ism-eval
# on the development scans in ../shared/data/real and the shipped sample scene. Every row adds
# one step to the one above it; the first is the seed's pipeline.
#   tests/eval/ablation.sh [BUILD_DIR] [OUTPUT.md] [ROW...]      (about 35 minutes on 2 cores)
# Writes the table to OUTPUT.md (default: stdout) and keeps the models, ism-eval's JSON and the
# training times in BUILD_DIR/ablation/. Given ROW names, only those rows are trained and
# evaluated again; the others are read from BUILD_DIR/ablation/ (a row changed by a commit must be
# named, or the whole table made afresh). With ISM_ABLATION_KEEP_MODELS=1 every row's model and
# training time are taken from BUILD_DIR/ablation/ and only evaluated again (a change to recognition
# alone; about 10 minutes).
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
out=${2:-/dev/stdout}
only=("${@:3}")
# shellcheck source=tests/eval/common.sh
source "$root/tests/eval/common.sh"
work=$build/ablation
mkdir -p "$work"

# Rows before the projector's shadow train without it, rows before the coarse front end at the
# seed's scales, rows before the calibration for clouds calibrate on frames alone.
# Rows before the far training views see each mesh as near as it fits in view.
# Rows before the surface keypoints take contours alone; rows before the height test's
# normalisation spread a keypoint's weight over all of its codeword's votes; rows before the table
# top keep their fitted shapes' boxes, and rows before the footprint prior keep every table top.
# Rows before the shape profile calibrate on the verification's fit alone; rows before the seat run
# keep chairs and couches whatever their run at seat height, rows before the open top whatever stands
# over them, rows before the bare floor whatever floor lies in their footprint. Rows before the
# checked calibration calibrate on every verified peak of the rooms; rows before under the top keep
# tables with nothing measured under their top, rows before the seat's area chairs and couches with
# little measured at seat height, rows before the upper part's clearance count a wall's face at a
# chair's or couch's edge in the top of its body, rows before the seen-through top keep chairs
# whose fitted backrest the sensor sees through, and rows before the given up's check keep the
# scenes' up however far their floor is tilted from it. Rows before the peaks' neighbourhood
# centre their peaks on their bin's own votes, in training's calibration rooms and in recognition.
contours="--surface-keypoints 0 --height-weighting lost --no-shape-profile --no-calibration-scene-checks"
near="$contours --view-distance 0"
old="$near --seed-front-end --no-projector-shadow --no-cloud-calibration --no-verification"
fine="$near --seed-front-end --no-cloud-calibration --no-verification"
# name | ism-train options (=ROW: that row's model) | ism-eval options | what the row adds
steps=(
  "seed|--preset seed|--preset seed --trust-given-up|the seed's pipeline (LRF votes, leave-one-out thresholds, box selection)"
  "planes|$old --cloud-keypoints boundary --vote-frame lrf --height-tolerance 0 --no-calibration|--preset seed --trust-given-up|+ up and floor: floor and walls never keypoints, training meshes on a floor"
  "upright|$old --cloud-keypoints boundary --height-tolerance 0 --no-calibration|--preset seed --trust-given-up|+ upright vote frames"
  "heights|$old --cloud-keypoints boundary --no-calibration|--preset seed --trust-given-up|+ the height test: votes only from training keypoints at the keypoint's height"
  "one-answer|$old --cloud-keypoints boundary --no-calibration|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ upright boxes from the training objects, height prior, one answer per object"
  "calibrated|$old --cloud-keypoints boundary|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ confidence calibrated on rendered rooms"
  "range-image|$old|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ unorganized clouds: contours of the range image from the sensor"
  "shadow|$fine|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ the projector's shadow in training scans and calibration rooms"
  "coarse|$near --no-cloud-calibration --no-verification|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ descriptors at 3 cm voxels, 7.5 cm normals, 18 cm SHOT instead of 1 / 3 / 8 cm"
  "clouds|$near --no-verification|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ a second calibration for unorganized clouds, on the rooms seen as point samples"
  "verified|$near|--preset default --centre-suppression --map-verification viewpoint --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ verification: training shapes fitted to the measured depth, the fit in the confidence"
  "surface|=verified|--preset default --map-verification viewpoint --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ one object across categories only where one explains the other's verified surface"
  "far-views|$contours|--preset default --map-verification viewpoint --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ training views from 3.5 m rather than as near as the object fits in view"
  "background|$contours --calibration-background 0|--preset default --map-verification viewpoint --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ codewords weighed against 21 background meshes (manifest rows of category background)"
  "background-rooms|$contours|--preset default --map-verification viewpoint --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ up to 2 of the background meshes in each calibration room"
  "maps|=background-rooms|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ maps (fused rooms) verified in 3D, not on a depth buffer from their made-up viewpoint"
  "surface-keypoints|--height-weighting lost --no-shape-profile --no-calibration-scene-checks|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ keypoints on the surfaces off the floor and walls, one per 9 cm cube, besides their contours"
  "height-normalized|--no-shape-profile --no-calibration-scene-checks|--preset default --no-top-extent --no-seat-run --no-open-top --no-bare-floor --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ the height test's weight spread over the votes at the keypoint's height, not over all of its codeword's"
  "table-top|=height-normalized|--preset default --no-footprint-prior --keep-topless --no-seat-run --no-open-top --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ tables' boxes spanning the scene's table top, not their fitted shape"
  "footprint|=height-normalized|--preset default --keep-topless --no-seat-run --no-open-top --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ tables whose top is deeper or shallower than every training table's rejected"
  "shape-profile|--no-calibration-scene-checks|--preset default --keep-topless --no-seat-run --no-open-top --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ the measured surface's profile over height and distance from the box's axis against the training shapes' in the confidence, but for flat-topped categories"
  "top-required|=shape-profile|--preset default --no-seat-run --no-open-top --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ tables whose top the scene does not show dropped"
  "seat-run|=shape-profile|--preset default --no-open-top --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ chairs and couches whose measured surface at seat height runs shorter than half their category's shortest training shape's dropped"
  "open-top|=shape-profile|--preset default --no-upper-part --no-level-top --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ chairs and couches with measured surface standing over their top (over a fifth of the points over their inner footprint, 0.1-0.6 m above it) dropped"
  "upper-part|=shape-profile|--preset default --no-level-top --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ chairs and couches with no measured point over their footprint 0.55-0.75 m above the floor, where a backrest is, dropped"
  "level-top|=shape-profile|--preset default --no-bare-floor --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ couches over a level top (6 in 10 of their footprint's 8 cm cells highest within one 10 cm band, as a bed's mattress) refuted: no answer for that object"
  "bare-floor|=shape-profile|--preset default --no-under-top --no-seat-area --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ any hypothesis in a map with bare floor (measured floor, nothing above it) in 3 in 10 of the cells of its inner footprint dropped"
  "under-top|=shape-profile|--preset default --no-seat-area --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ tables under whose measured top nothing is measured (under 1 in 10 of the cells of its inner footprint), as under a bed's or a cabinet's, dropped"
  "seat-area|=shape-profile|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ chairs and couches with a measured point 0.25-0.65 m above the floor in under 3 in 10 of the cells of their inner footprint that the sensor saw there, as over a desk's legs, dropped"
  "checked-calibration||--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ the confidence calibrated on the rendered rooms' peaks that pass these checks of the scene (but the seat's area), as the answers have"
  "draws|--draws 3|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ three draws of training's randomness answering together: each draw's peaks grouped by object, each verified by its draw, the mean of the draws' confidences"
  "balanced-codebook|--draws 3 --codebook-sampling balanced|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ the global codebook's k-means on as many descriptors of each category, not on a sample of all pooled"
  "kinds|--draws 3 --codebook-sampling balanced|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ a calibration room's peak on furniture of another category of its kind (a dining chair's on an office chair) left out of its category's fit, not counted against it"
  "walls|--draws 2 --codebook-sampling balanced --wall-seen-through 1|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ a vertical plane the sensor sees through at more points than its own is no wall, its points keypoints again; two draws, not three, to pay for it"
  "learned-weights|--draws 2 --codebook-sampling balanced --wall-seen-through 1 --learned-weights|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ codeword weights learned from the calibration rooms' true and false peaks, lowered where the false peaks are made of them (Maji and Malik's max-margin Hough transform)"
  "seat-under-top|=learned-weights|--preset default --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ of a couch and a table whose measured top covers a third of the couch's footprint, the less confident dropped (a couch is not pushed under a table)"
  "top-height|=learned-weights|--preset default --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ tables whose measured top stands more than 0.1 m below or above every training table's dropped"
  "level-run-on|=learned-weights|--preset default --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ couches beside which the measured surface runs on as one level above a seat's height, up to a tall bed's mattress at 0.8 m, refuted"
  "behind-back|=learned-weights|--preset default --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ chairs behind whose fitted shape's back the measured surface runs on as one level, a bed's mattress behind the bench at its foot, refuted"
  "near-side|=learned-weights|--preset default --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|+ chairs and couches of a single view with measured surface standing over the side of their footprint facing the sensor, a wall between it and them, dropped"
  "closed-front|=learned-weights|--preset default --no-upper-clearance --no-seen-top --trust-given-up|+ in a single view, a table's measured points under its top less than 0.3 m in from the side facing the sensor (a dresser's drawers) do not open it"
  "upper-clearance|=learned-weights|--preset default --no-seen-top --trust-given-up|+ the points in the top of a chair's or couch's body count only more than 0.2 m from surface standing over its top, a wall at its edge"
  "seen-top|=learned-weights|--preset default --trust-given-up|+ chairs and couches of a single view whose fitted shape's top quarter, a backrest, has under 1 in 20 of its seen pixels explained, dropped"
  "given-up-check|=learned-weights|--preset default|+ a given up more than 3 deg from the normal of a floor that holds more points than the plane square to it gives way to that normal"
  "peaks|--draws 2 --codebook-sampling balanced --wall-seen-through 1 --learned-weights|--preset default|+ each peak centred on the votes of its bin and its 26 neighbours, not its bin's alone, in recognition and in the calibration rooms (the default)"
  "no-free-space|--fit-terms inliers|--preset default --fit-terms inliers --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|one draw without verification's free-space term: a shape's pixels the sensor saw through count as hidden ones do, against it (optional: ism-train and ism-eval --fit-terms inliers)"
  "no-inliers|--fit-terms free-space|--preset default --fit-terms free-space --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|one draw without verification's inlier term: only the pixels the sensor saw through count, against the shape (optional: --fit-terms free-space)"
  "icp|=checked-calibration|--preset default --icp 8 --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|one draw with up to 8 steps of ICP about up after verification's pose search (optional: ism-detect and ism-eval --icp 8)"
  "calibration-maps|--draws 3 --codebook-sampling balanced --calibration-maps|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|three draws with each calibration room also seen as a map (one view fused per 1.5 cm cube, 30,000-80,000 points, no pose) in the clouds' calibration (optional: ism-train --calibration-maps)"
  "kinect-window|--pixel-shift 0.5 --correlation-window 9|--preset default --no-seat-under-top --no-top-height --no-level-run-on --no-behind-back --no-near-side --no-closed-front --no-upper-clearance --no-seen-top --trust-given-up|one draw with the Kinect's correlation window in training scans and calibration rooms: edges jittered, thin parts lost (optional: ism-train --pixel-shift 0.5 --correlation-window 9)"
)
rows=()
training_manifest=$manifest
for step in "${steps[@]}"; do
  IFS='|' read -r name train_args eval_args what <<< "$step"
  # From the background row on, every row trains with the background meshes.
  [[ $name == background ]] && training_manifest=$background_manifest
  model=$work/$name.ismm
  # Rows that do not name their codebook's sampling cluster a sample of every category's
  # descriptors pooled: the steps before the balanced codebook's measure the pooled one.
  [[ $train_args == *--codebook-sampling* || $train_args == =* ]] || train_args+=" --codebook-sampling pooled"
  # A calibration room's peak on another category of its kind counts against it in the rows before
  # the kinds' and in the single-draw rows made before it; the kinds' row and those that build on it
  # (walls, learned weights, the rooms seen as maps) leave it out, as the default does.
  [[ $name == kinds || $name == walls || $name == learned-weights || $name == calibration-maps || $name == peaks || $train_args == =* ]] || train_args+=" --calibration-kind-negatives"
  # Every row before the peaks' neighbourhood, and the single-draw rows made before it, centre
  # their peaks on their bin, in the calibration rooms and in recognition.
  if [[ $name != peaks ]]; then
    [[ $train_args == =* ]] || train_args+=" --bin-peaks"
    eval_args+=" --bin-peaks"
  fi
  if ((${#only[@]})) && [[ " ${only[*]} " != *" $name "* ]]; then
    [[ -f $work/$name.seconds ]] || { echo "ablation: $name has no earlier run in $work; name it" >&2; exit 1; }
    rows+=("$name|$what|$(cat "$work/$name.seconds")")
    continue
  fi
  if [[ $train_args == =* ]]; then  # a recognition step: the model of the row named
    model=$work/${train_args#=}.ismm
    cp "$work/${train_args#=}.seconds" "$work/$name.seconds"
    seconds=$(cat "$work/$name.seconds")
  elif [[ ${ISM_ABLATION_KEEP_MODELS:-0} == 1 ]]; then
    [[ -f $model && -f $work/$name.seconds ]] || { echo "ablation: $name has no model in $work to keep" >&2; exit 1; }
    seconds=$(cat "$work/$name.seconds")
  else
    start=$(date +%s.%N)
    # shellcheck disable=SC2086
    "$build/core/ism-train" --manifest "$training_manifest" -o "$model" --codebook global --no-scene-smoothing $train_args \
      > "$work/$name.train.log"
    seconds=$(echo "$(date +%s.%N) - $start" | bc)
    echo "$seconds" > "$work/$name.seconds"
  fi
  # shellcheck disable=SC2086
  "$root/tests/eval/real_eval.sh" "$build" "$model" "$work/$name" $eval_args
  rows+=("$name|$what|$seconds")
  echo "ablation: $name done" >&2
done

PYTHONPATH=$root/tests/eval /usr/bin/python3 - "$work" "${rows[@]}" > "$out" <<'PY'
import sys
from real_row import figures, pct
work, rows = sys.argv[1], sys.argv[2:]
print("| step | Kinect + sample mAP@0.25 | SUN RGB-D + ScanNet mAP@0.25 | their chair / table / sofa AP@0.25 "
      "| chair r at 0.5 | FP per scan at 0.5 | training s |")
print("|---|---|---|---|---|---|---|")
for row in rows:
    name, what, seconds = row.split("|")
    f = figures(f"{work}/{name}")
    print(f"| {what} | {pct(f['frames'])} | {pct(f['clouds'])} | {' / '.join(pct(v) for v in f['per_class'])} "
          f"| {pct(f['chair_r'])} | {f['fp_per_scan']:.1f} | {float(seconds):.0f} |")
PY
