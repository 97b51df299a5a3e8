#!/usr/bin/env bash
# Soak benchmark (not run by CI): starts `mlsreg serve` on a loopback port with a short idle
# timeout, then build/bench/mlsreg_soak_bench runs CYCLES upload / register / delete cycles with
# CLIENTS concurrent clients while an attacker keeps SILENT streams open that announce data and
# send none. Prints errors by code (good clients and attacker), cycle latency p50/p99 and the
# server's RSS growth after warm-up.
set -euo pipefail
cd "$(dirname "$0")/.."
MLSREG=${MLSREG:-build/mlsreg}
source scripts/lib-server.sh
log=$(mktemp)
trap 'kill "${MLSREG_SERVER_PID:-}" 2>/dev/null || true; rm -f "$log"' EXIT
start_server "$log" --workers "${WORKERS:-2}" --idle-timeout-seconds "${IDLE:-2}"
build/bench/mlsreg_soak_bench --server "$MLSREG_SERVER_ADDRESS" --server-pid "$MLSREG_SERVER_PID" \
  --cycles "${CYCLES:-1000}" --clients "${CLIENTS:-8}" --silent-streams "${SILENT:-40}" "$@"
stop_server
