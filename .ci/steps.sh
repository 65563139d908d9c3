# The CI steps besides the main build, sourced by .ci/run and .ci/sanitizers from the repository
# root. Each configures its own build tree, builds only the targets its tests run, runs them and
# returns non-zero on any failure. Instrumented builds use -O1 (as the sanitizers' documentation
# advises; it also compiles faster than -O3) with line tables, so reports name file:line.

jobs=$(nproc)
instrumented=(-DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS_RELEASE=-O1 -DNDEBUG" -DISM_BUILD_TESTS=ON
              -DISM_BUILD_SERVICE=ON)
# clang: its libFuzzer and TSan runtimes come with libclang-rt-14-dev.
configure_clang() {  # BUILD_DIR [cmake -D options...]
  local dir=$1
  shift
  CC=clang CXX=clang++ cmake -S . -B "$dir" -G Ninja "${instrumented[@]}" -DCMAKE_CXX_FLAGS=-gline-tables-only \
    "$@" >/dev/null
}

# Reports that processes other than ctest's own wrote. The tests start ism-server and ism-client
# as child processes and stop the server with SIGKILL, so a sanitizer report there would change
# no exit status a test checks; log_path sends every process's reports to DIR/NAME.EXE.PID
# instead (log_exe_name), and a report there fails the step. A sanitizer creates its file when it
# begins to write, so an empty one holds no report (its process died before writing a byte,
# e.g. by the SIGKILL that ends a test's server): it is listed, not counted. Contents go through
# cat -v, so that bytes that are not text can neither hide a report nor stop the digest's grep.
sanitizer_reports() {  # DIR
  local file count=0
  for file in "$1"/*.[0-9]*; do
    [[ -e $file ]] || continue
    if [[ ! -s $file ]]; then
      echo "empty sanitizer report file (no report in it): $file"
      continue
    fi
    count=$((count + 1))
    echo "sanitizer report from $(basename "$file") ($(wc -c < "$file") bytes):"
    head -n 60 "$file" | cat -v
  done
  ((count == 0)) || { echo "sanitizer reports in $count process(es)"; return 1; }
}

# libFuzzer over every decoder: ISM_FUZZ_SECONDS each over the seed corpus in tests/fuzz/corpus.
fuzz_step() {
  configure_clang build-fuzz -DISM_FUZZ=ON -DISM_FUZZ_SECONDS="${ISM_FUZZ_SECONDS:-10}" || return
  cmake --build build-fuzz -j"$jobs" --target ism_fuzzers || return
  # One libFuzzer process per target, single-threaded and bounded by time: side by side they
  # each run their ISM_FUZZ_SECONDS.
  ctest --test-dir build-fuzz -L fuzz --output-on-failure -j"$jobs"
}

# The main build: everything, tests included, as a user's `cmake --build build` makes it.
main_build_step() {
  cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DISM_BUILD_TESTS=ON -DISM_BUILD_SERVICE=ON >/dev/null || return
  cmake --build build -j"$jobs"
}

# SigtermDrainsTheRunningRequest needs a 640x480 recognition to finish within the server's drain
# time, which the sanitizers' slowdown exceeds.
too_slow_instrumented='^ServiceShutdown\.SigtermDrainsTheRunningRequest$'

# Service tests left out under ThreadSanitizer because they run no code concurrently that the
# tests kept do not: in-process, single-threaded checks of request conversion, wire messages and
# log escaping (Conversion, WireMessages, UntrustedText), and one request at a time from a
# single-threaded client whose point is the answer or the output, not the server's threads
# (AnswersTest: presets; ClientTest: the CLI's output and exit codes; UntrustedTextServiceTest:
# log lines; HealthCheck: the probe). The main suite runs all of them. Every test that drives a
# server from several threads or streams (ServiceTest, BadInputTest's flood, Faults, Admission,
# BenchTest, SecurityTest's per-client stream limits, Cancellation) stays.
tsan_duplicates='^(Conversion|WireMessages|UntrustedText|UntrustedTextServiceTest|AnswersTest|ClientTest|HealthCheck)\.'

# The service tests' tiny model (tests/service/service_fixture.cc), from the main build's
# uninstrumented ism_test_model: training it is the tests' set-up, not the server under test,
# and instrumented it took minutes, longer than a test's timeout on a busy machine, so that
# every test process started training it again. Needs main_build_step first.
seed_test_model() {  # BUILD_DIR
  local trained
  # It prints the model's folder last (first, when it trains, how long that took).
  trained=$(build/tests/clients/ism_test_model | tail -n 1) || return
  mkdir -p "$1/tests/service/cache/models"
  cp "$trained/default.ismm" "$1/tests/service/cache/models/default.ismm"
}

# ThreadSanitizer over the server tests (ism-server, ism-client and the test driver instrumented).
# clang rather than gcc because of OpenMP: with clang our own OpenMP loops (recognition, front
# end, training) run on LLVM's libomp, whose TSan tool libarcher tells TSan about OpenMP's
# barriers and tasks; gcc's libgomp has no such tool and every loop would be reported. Debian's
# PCL runs its loops (normals, MLS, SHOT) on libgomp regardless, but PCL is not instrumented:
# ignore_noninstrumented_modules keeps the allocations and copies it makes on libgomp's threads
# out of the picture. .ci/tsan.supp says what else is left out and why.
tsan_step() {
  configure_clang build-tsan -DISM_SANITIZE=thread || return
  local options="halt_on_error=0 second_deadlock_stack=1 ignore_noninstrumented_modules=1 log_exe_name=1"
  options+=" suppressions=$PWD/.ci/tsan.supp"
  # The build runs service_test to list its tests (gtest_discover_tests), so it needs them too.
  TSAN_OPTIONS=$options cmake --build build-tsan -j"$jobs" --target ism-server ism-client service_test || return
  seed_test_model build-tsan || return
  local reports=$PWD/build-tsan/sanitizer-reports
  rm -rf "$reports" && mkdir -p "$reports"
  # libarcher comes with clang's libomp (libomp-dev), next to clang's resource directory.
  local archer
  archer=$(realpath -e "$(clang -print-resource-dir)/../../libarcher.so") || return
  local status=0
  OMP_TOOL_LIBRARIES=$archer TSAN_OPTIONS="$options log_path=$reports/tsan" \
    ctest --test-dir build-tsan -L service -E "$too_slow_instrumented|$tsan_duplicates" --output-on-failure \
    --timeout 900 -j"$jobs" || status=$?
  sanitizer_reports "$reports" || status=1
  return $status
}

# AddressSanitizer + UndefinedBehaviorSanitizer over the unit and server tests, with gcc, the
# compiler the shipped binaries are built with.
asan_step() {
  cmake -S . -B build-asan -G Ninja "${instrumented[@]}" -DCMAKE_CXX_FLAGS=-g1 -DISM_SANITIZE="address;undefined" \
    >/dev/null || return
  # The unit test executables are named after tests/core/*_test.cc (tests/CMakeLists.txt).
  local targets=(ism-server ism-client service_test)
  local src
  for src in tests/core/*_test.cc; do targets+=("$(basename "$src" .cc)"); done
  cmake --build build-asan -j"$jobs" --target "${targets[@]}" || return
  local reports=$PWD/build-asan/sanitizer-reports
  rm -rf "$reports" && mkdir -p "$reports"
  local status=0
  ASAN_OPTIONS="log_path=$reports/asan log_exe_name=1" LSAN_OPTIONS="suppressions=$PWD/.ci/lsan.supp print_suppressions=0" \
    UBSAN_OPTIONS="log_path=$reports/ubsan log_exe_name=1 print_stacktrace=1" \
    ctest --test-dir build-asan -L "core|service" -E "$too_slow_instrumented" --output-on-failure --timeout 1800 \
    || status=$?
  sanitizer_reports "$reports" || status=1
  return $status
}

# Runs FUNCTION, prints its wall time, and remembers a failure in $failed without stopping. The
# step's output also goes to ci-logs/NAME.log, which failure_digest reads.
failed=()
timings=""
run_step() {  # NAME FUNCTION
  local start=$SECONDS
  mkdir -p ci-logs
  echo "== $1"
  # As a condition, so that set -e neither stops the step at its first failing command nor the
  # run at a failed step; with pipefail the pipeline fails when the step does.
  if ! "$2" 2>&1 | tee "ci-logs/$1.log"; then failed+=("$1"); fi
  timings+="${timings:+, }$1 $((SECONDS - start)) s"
  echo "== $1: $((SECONDS - start)) s"
}

# What made the failed steps fail, in a few lines, for the end of the run: where a CI system shows
# only the last lines of a long log, the failed tests and the first frames of each sanitizer report
# are there to read.
failure_digest() {
  local name lines
  local pattern='\*\*\*(Failed|Timeout|Exception)|\((Failed|Timeout|SEGFAULT|Subprocess aborted|Child aborted)\)'
  pattern+='|tests failed|WARNING: ThreadSanitizer|ERROR: (Address|Leak)Sanitizer|runtime error:|SUMMARY: '
  pattern+='|sanitizer report|FAILED:|error:|: Failure$|^\[  FAILED  \] [A-Za-z]'
  for name in "${failed[@]}"; do
    echo "== what failed in $name (ci-logs/$name.log):"
    lines=$(grep -a -E -A4 "$pattern" "ci-logs/$name.log" | grep -v -E '^ +Start ' | head -n 40 || true)
    if [[ -n $lines ]]; then echo "$lines"; else tail -n 10 "ci-logs/$name.log"; fi
  done
}
