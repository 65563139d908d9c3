#!/usr/bin/env bash
# The benchmarks of issue 5, side by side in one run, as one markdown table of medians:
#   tests/bench/run.sh [BUILD_DIR] [--skip-training] [--skip-peer] [--repetitions N]
# BUILD_DIR (default: build) is configured as Release if it does not exist yet, and the targets
# needed are built. Then:
#   1. ism-bench: each stage of one 640x480 Kinect frame (the development data's TUM desk frame,
#      else the sample scene) on 1 and on all threads, the whole recognition in process and
#      through the real ism-server over gRPC, model load, the server's memory;
#   2. ism-train on the default model's manifest with models/build_default.py's options, timed once;
#   3. pcl-ism-peer: PCL's ISM trained on the same scans, both run on the annotated scenes.
# Raw outputs stay in BUILD_DIR/bench-results/.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$root/build
skip_training=0 skip_peer=0 repetitions=5
while (( $# )); do
  case $1 in
    --skip-training) skip_training=1 ;;
    --skip-peer) skip_peer=1 ;;
    --repetitions) repetitions=${2:?--repetitions needs a number}; shift ;;
    -h|--help) sed -n '2,11p' "$0"; exit 0 ;;
    -*) echo "run.sh: unknown option $1" >&2; exit 2 ;;
    *) build=$(cd "$(dirname "$1")" && pwd)/$(basename "$1") ;;
  esac
  shift
done
[[ $repetitions =~ ^[1-9][0-9]*$ ]] || { echo "run.sh: --repetitions '$repetitions' is not a positive integer" >&2; exit 2; }
command_line="tests/bench/run.sh ${build#$root/}"
if (( skip_training )); then command_line+=" --skip-training"; fi
if (( skip_peer )); then command_line+=" --skip-peer"; fi
command_line+=" --repetitions $repetitions"
py=/usr/bin/python3

if [[ ! -f $build/CMakeCache.txt ]]; then
  cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DISM_BUILD_TESTS=ON -DISM_BUILD_SERVICE=ON >&2
fi
build_type=$(sed -n 's/^CMAKE_BUILD_TYPE:[A-Z]*=//p' "$build/CMakeCache.txt")
[[ $build_type == Release ]] || echo "run.sh: WARNING: $build is a '$build_type' build; figures are meant for Release" >&2
# Everything but the table goes to stderr.
cmake --build "$build" --target ism-bench ism-server ism-train pcl-ism-peer >&2

out=$build/bench-results
mkdir -p "$out"
rm -f "$out"/{bench.json,training.json,peer.json,peer.log}

kinect=$root/../shared/data/real/kinect
scenes=("$root/models/sample/living_room.json")
if [[ -d $kinect ]]; then
  scenes=("$kinect" "${scenes[@]}")
else
  echo "run.sh: $kinect is absent: the frame benchmarks fall back to the sample scene, the peer runs on it alone" >&2
fi

echo "== ism-bench ($repetitions repetitions)" >&2
"$build/tests/bench/ism-bench" --benchmark_repetitions="$repetitions" --benchmark_report_aggregates_only=true \
  --benchmark_out="$out/bench.json" --benchmark_out_format=json >&2

# The shipped model's meshes as models/build_default.py extracts them, without touching models/.
# The shipped model also trains on the background meshes; PCL's ISM has no use for them.
manifest=$("$py" "$root/models/build_default.py" --bin "$build/core" --work "$build/bench-default-model-src" \
           --no-background --manifest-only)
shipped_manifest=$("$py" "$root/models/build_default.py" --bin "$build/core" --work "$build/bench-shipped-model-src" \
                   --manifest-only)
if (( skip_training )); then
  echo '{"skipped": "skipped (--skip-training)"}' >"$out/training.json"
else
  echo "== ism-train on $shipped_manifest" >&2
  start=$(date +%s.%N)
  # shellcheck disable=SC2046
  "$build/core/ism-train" --manifest "$shipped_manifest" -o "$out/furniture.ismm" \
    $("$py" "$root/models/build_default.py" --bin "$build/core" --training-options) >"$out/training.log"
  end=$(date +%s.%N)
  scans=$(grep -c '^scanned ' "$out/training.log" || true)
  printf '{"seconds": %s, "scans": %s}\n' "$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.1f", b - a }')" "${scans:-0}" >"$out/training.json"
fi

peer_status=""
if (( skip_peer )); then
  peer_status="skipped (--skip-peer)"
else
  echo "== pcl-ism-peer on ${scenes[*]}" >&2
  set +e
  "$build/tests/bench/pcl-ism-peer" --manifest "$manifest" --model "$root/models/default/furniture.ismm" \
    --json "$out/peer.json" "${scenes[@]}" 2>&1 | tee "$out/peer.log" >&2
  code=${PIPESTATUS[0]}
  set -e
  if (( code != 0 )); then
    peer_status="pcl-ism-peer exited with status $code"
    if (( code > 128 )); then peer_status+=" (signal $((code - 128)))"; fi
    peer_status+=", see $out/peer.log"
    rm -f "$out/peer.json"
  fi
fi

"$py" "$root/tests/bench/report.py" --bench "$out/bench.json" --peer "$out/peer.json" --peer-status="$peer_status" \
  --training "$out/training.json" --command "$command_line" | tee "$out/table.md"
