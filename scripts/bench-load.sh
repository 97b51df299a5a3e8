#!/usr/bin/env bash
# Load benchmark: starts `mlsreg serve` on a loopback port (WORKERS, QUEUE as given), then runs
# build/bench/mlsreg_load_bench with 1, 2, 8 and 32 concurrent clients registering the bundled
# bunny scans against one cached target. Prints throughput, p50/p99 latency, the ratio of a
# served registration to the same registration in-process, server RSS before/after, and errors
# by status code (RESOURCE_EXHAUSTED is expected only once the queue is full).
set -euo pipefail
cd "$(dirname "$0")/.."
MLSREG=${MLSREG:-build/mlsreg}
source scripts/lib-server.sh
log=$(mktemp)
trap 'kill "${MLSREG_SERVER_PID:-}" 2>/dev/null || true; rm -f "$log"' EXIT
start_server "$log" --workers "${WORKERS:-2}" --queue-capacity "${QUEUE:-64}"
build/bench/mlsreg_load_bench --server "$MLSREG_SERVER_ADDRESS" --server-pid "$MLSREG_SERVER_PID" \
  --clients "${CLIENTS:-1,2,8,32}" --requests-per-client "${REQUESTS:-4}" "$@"
stop_server
