#!/usr/bin/env bash
# Runs every fuzz target of a build configured with -DISM_FUZZ=ON for MINUTES each (default 10),
# one after the other, each with JOBS parallel workers (default 1). New inputs accumulate in
# BUILD/tests/fuzz/<target>/corpus, crashes in .../artifacts; a target that finds one stops
# and the script carries on with the next, exiting non-zero at the end.
#   tests/fuzz/run_long.sh BUILD_DIR [MINUTES] [JOBS]
set -u
build=${1:?usage: run_long.sh BUILD_DIR [MINUTES] [JOBS]}
minutes=${2:-10}
jobs=${3:-1}
source_dir=$(cd "$(dirname "$0")" && pwd)
failed=()
for target in pcd ply depth_png packed model request; do
  binary=$build/tests/fuzz/fuzz_$target
  if [[ ! -x $binary ]]; then
    echo "skip $target: $binary not built"
    continue
  fi
  work=$build/tests/fuzz/$target
  mkdir -p "$work/corpus" "$work/artifacts"
  echo "== $target: $minutes min, $jobs job(s); log in $work/fuzz.log"
  args=(-max_total_time=$((minutes * 60)) -rss_limit_mb=4096 -timeout=25 -print_final_stats=1
        -artifact_prefix="$work/artifacts/")
  if ((jobs > 1)); then
    args+=(-fork="$jobs")
  fi
  if ! "$binary" "${args[@]}" "$work/corpus" "$source_dir/corpus/$target" >"$work/fuzz.log" 2>&1; then
    failed+=("$target")
    grep -m1 -A12 "ERROR:\|deadly signal\|uncaught exception" "$work/fuzz.log"
  fi
  grep -E "^#[0-9]+ +DONE|stat::" "$work/fuzz.log" | tail -6
done
if ((${#failed[@]})); then
  echo "findings in: ${failed[*]} (inputs in $build/tests/fuzz/<target>/artifacts)"
  exit 1
fi
