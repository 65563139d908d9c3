#!/usr/bin/env bash
# ctest entry for the Node client tests: installs the locked dependencies only when they are
# missing (npm ci needs the npm registry), then runs node's built-in test runner.
set -euo pipefail
package_dir=$1
if [[ ! -d "$package_dir/node_modules/@grpc/grpc-js" ]]; then
  (cd "$package_dir" && npm ci --no-audit --no-fund)
fi
exec node --test "$(dirname "$0")/client.test.js"
