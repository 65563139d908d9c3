#!/usr/bin/env bash
# The README's first command: install what is needed, build, start ism-server with the shipped
# default models, recognise the shipped sample scene with ism-client, print the hypotheses,
# stop the server. Needs no ../shared.
set -euo pipefail
cd "$(dirname "$0")/.."
bash deploy/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DISM_BUILD_SERVICE=ON >/dev/null
cmake --build build -j"$(nproc)" --target ism-server ism-client

port=${ISM_DEMO_PORT:-50151}
log=$(mktemp)
build/server/ism-server --listen "127.0.0.1:${port}" --models models/default --metrics-listen "" >"$log" 2>&1 &
server=$!
trap 'kill -TERM $server 2>/dev/null; wait $server 2>/dev/null || true; rm -f "$log"' EXIT

client=build/client/ism-client
for _ in $(seq 1 100); do
  "$client" --server "127.0.0.1:${port}" health >/dev/null 2>&1 && break
  kill -0 $server 2>/dev/null || { cat "$log"; echo "ism-server exited"; exit 1; }
  sleep 0.2
done
"$client" --server "127.0.0.1:${port}" models
"$client" --server "127.0.0.1:${port}" recognize models/sample/living_room.pcd --picture build/living_room.png
echo "picture of the scene with the boxes: build/living_room.png"
echo "ground truth of the sample scene: models/sample/living_room.json"
