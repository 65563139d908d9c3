#!/usr/bin/env bash
# Soak test (not in ctest: it runs for minutes). Starts ism-server with models/default on
# 127.0.0.1, drives it at saturation with `ism-client bench` (closed loop, 2 requests in flight per
# worker thread, so a worker never waits for the network) for MINUTES, samples the server's
# resident memory every 10 s, and prints requests, errors by status, latency and memory.
#
#   tests/service/soak.sh [BUILD_DIR=build] [MINUTES=10]
#
# Exits non-zero on any failed request, on a server that died or did not exit 0 on SIGTERM,
# or when resident memory grew by more than ISM_SOAK_MAX_GROWTH_MB (default 64) after warm-up.
# Why after warm-up, and why 64 MB: glibc keeps freed memory in per-thread arenas, so during
# the first requests RSS climbs to about the model plus one request's working set per worker
# and then oscillates around a plateau whatever the request count. Warm-up is the first 10% of
# the run (at least 10 s); its highest sample is the baseline, and the highest sample after it
# must stay within the bound. Measured on the sample scene with 2 workers over 10 minutes: 90 MB
# with the model loaded, a plateau reached within the first minute, then samples between 185
# and 231 MB; 64 MB clears that ~45 MB swing. A leak grows with every request instead: the
# run fails for a leak of 64 MB / requests per request (printed at the end; ~60 KB for the
# ~1,100 requests of 10 minutes there), less than one request's decoded cloud.
#
# Environment: ISM_SOAK_SCENE (default models/sample/living_room.pcd), ISM_SOAK_THREADS (server
# worker threads, default: the number of cores), ISM_SOAK_MAX_GROWTH_MB.
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
minutes=${2:-10}
scene=${ISM_SOAK_SCENE:-$root/models/sample/living_room.pcd}
threads=${ISM_SOAK_THREADS:-$(nproc)}
bound_mb=${ISM_SOAK_MAX_GROWTH_MB:-64}
server_bin=$build/server/ism-server
client_bin=$build/client/ism-client
python=/usr/bin/python3

if ! [[ $minutes =~ ^[0-9]+$ ]] || ((minutes < 1 || minutes > 60)); then
  echo "soak.sh: MINUTES must be 1..60 (bench stops at 1 h), got '$minutes'" >&2
  exit 2
fi
for binary in "$server_bin" "$client_bin"; do
  [[ -x $binary ]] || { echo "soak.sh: $binary is missing; build the ism-server and ism-client targets" >&2; exit 2; }
done
[[ -r $scene ]] || { echo "soak.sh: cannot read the scene $scene" >&2; exit 2; }
concurrency=$((2 * threads))

work=$(mktemp -d)
server_pid=""
cleanup() {
  if [[ -n $server_pid ]] && kill -0 "$server_pid" 2>/dev/null; then
    kill -KILL "$server_pid" 2>/dev/null || true
    wait "$server_pid" 2>/dev/null || true
  fi
  rm -rf "$work"
}
trap cleanup EXIT

port=$($python -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
address=127.0.0.1:$port
"$server_bin" --listen "$address" --models "$root/models/default" --threads "$threads" --metrics-listen "" \
  --log-level warn 2>"$work/server.log" &
server_pid=$!
for _ in $(seq 600); do
  "$client_bin" --server "$address" --deadline-ms 1000 health >/dev/null 2>&1 && break
  kill -0 "$server_pid" 2>/dev/null || { echo "soak.sh: ism-server exited during start-up:" >&2; cat "$work/server.log" >&2; exit 1; }
  sleep 0.1
done
"$client_bin" --server "$address" --deadline-ms 1000 health >/dev/null

rss_kb() { awk '/^VmRSS:/ { print $2 }' "/proc/$server_pid/status"; }
echo "soak: ism-server pid $server_pid on $address, $threads worker threads; bench -c $concurrency for ${minutes}m on $scene"
start=$(date +%s)
echo "0 $(rss_kb)" >"$work/rss"
"$client_bin" --server "$address" --json bench "$scene" -c "$concurrency" -z "${minutes}m" --warmup "$concurrency" \
  >"$work/bench.json" 2>"$work/bench.err" &
bench_pid=$!
next=$((start + 10))
while kill -0 "$bench_pid" 2>/dev/null; do
  if (($(date +%s) >= next)); then
    kill -0 "$server_pid" 2>/dev/null || break
    echo "$((next - start)) $(rss_kb)" >>"$work/rss"
    next=$((next + 10))
  fi
  sleep 1
done
bench_status=0
wait "$bench_pid" || bench_status=$?
server_alive=1
if kill -0 "$server_pid" 2>/dev/null; then
  echo "$(($(date +%s) - start)) $(rss_kb)" >>"$work/rss"
  kill -TERM "$server_pid"
  server_exit=0
  wait "$server_pid" || server_exit=$?
else
  server_alive=0
  server_exit=-1
fi
server_pid=""

status=0
$python - "$work/bench.json" "$work/rss" "$bench_status" "$server_alive" "$server_exit" "$bound_mb" "$minutes" <<'EOF' || status=$?
import json, sys

bench_path, rss_path, bench_status, alive, server_exit, bound_mb, minutes = sys.argv[1:]
bench_status, alive, server_exit, bound_mb, minutes = int(bench_status), int(alive), int(server_exit), float(bound_mb), int(minutes)
text = open(bench_path).read().strip()
report = json.loads(text.splitlines()[-1]) if text else None
samples = [tuple(map(int, line.split())) for line in open(rss_path) if line.strip()]
mb = lambda kb: kb / 1024.0
warm_s = max(10, minutes * 60 // 10)
warm = [kb for t, kb in samples if t <= warm_s]
after = [kb for t, kb in samples if t > warm_s] or warm
start_kb, end_kb, max_kb = samples[0][1], samples[-1][1], max(kb for _, kb in samples)
baseline_kb = max(warm)
growth_mb = mb(max(after) - baseline_kb)

failures = []
print()
print("%-34s %s" % ("metric", "value"))
if report:
    errors = report["errors"]
    lat = report["latency_ms"]
    print("%-34s %d" % ("requests", report["requests"]))
    print("%-34s %d" % ("ok", report["ok"]))
    print("%-34s %s" % ("errors by status", ", ".join("%s %d" % kv for kv in errors.items()) or "none"))
    print("%-34s %.1f s" % ("elapsed", report["elapsed_s"]))
    print("%-34s %.2f req/s" % ("throughput", report["throughput_rps"]))
    print("%-34s %.0f / %.0f / %.0f / %.0f ms" % ("latency p50 / p90 / p99 / max", lat["p50"], lat["p90"], lat["p99"], lat["max"]))
    if errors:
        failures.append("%d requests failed" % sum(errors.values()))
    requests = max(1, report["requests"])
else:
    failures.append("ism-client bench printed no report (exit %d)" % bench_status)
    requests = 1
print("%-34s %d (every 10 s)" % ("RSS samples", len(samples)))
print("%-34s %.1f MB" % ("RSS at start (model loaded)", mb(start_kb)))
print("%-34s %.1f MB" % ("RSS after warm-up (max, first %d s)" % warm_s, mb(baseline_kb)))
print("%-34s %.1f MB" % ("RSS at end", mb(end_kb)))
print("%-34s %.1f MB" % ("RSS max", mb(max_kb)))
print("%-34s %+.1f MB" % ("growth start -> end", mb(end_kb - start_kb)))
print("%-34s %+.1f MB (bound %.0f MB)" % ("growth after warm-up (max - base)", growth_mb, bound_mb))
print("%-34s %.1f KB" % ("smallest leak/request the bound sees", bound_mb * 1024 / requests))
print("%-34s %s" % ("server", "exit %d on SIGTERM" % server_exit if alive else "DIED during the run"))
print()
print("RSS trace (s: MB): " + ", ".join("%d: %.0f" % (t, mb(kb)) for t, kb in samples))
if bench_status != 0 and report and not report["errors"]:
    failures.append("ism-client bench exited %d" % bench_status)
if growth_mb > bound_mb:
    failures.append("resident memory grew %.1f MB after warm-up, above the bound of %.0f MB" % (growth_mb, bound_mb))
if not alive:
    failures.append("ism-server died during the run")
elif server_exit != 0:
    failures.append("ism-server exited %d on SIGTERM" % server_exit)
if failures:
    print("\nSOAK FAILED: " + "; ".join(failures))
    sys.exit(1)
print("\nsoak passed")
EOF
if ((status != 0)); then
  echo "--- bench stderr ---" >&2
  tail -20 "$work/bench.err" >&2 || true
  echo "--- server log (last 20 lines) ---" >&2
  tail -20 "$work/server.log" >&2 || true
fi
exit $status
