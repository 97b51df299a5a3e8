#!/usr/bin/env bash
# The main job: a registration round trip through a locally started server. Starts
# `mlsreg serve` on a free loopback port, uploads the bundled Stanford bunny scan bun045 as a
# target, streams a registration of bun000 against it with the default method auto (MLS-SICP,
# verified against the target's MLS surface; started 10 degrees and 10 d from the ground truth;
# one line per ICP iteration), prints the final transform, the verification and the error
# against the ground truth, then stops the server. METHOD=mls-sicp (or any other) overrides it;
# extra arguments go to `mlsreg register` (e.g. --perturb-angle 150 for a start only the global
# stage recovers from).
set -euo pipefail
cd "$(dirname "$0")/.."
MLSREG=${MLSREG:-build/mlsreg}
source scripts/lib-server.sh
log=$(mktemp)
trap 'kill "${MLSREG_SERVER_PID:-}" 2>/dev/null || true; rm -f "$log"' EXIT
start_server "$log"
echo "== server listening on $MLSREG_SERVER_ADDRESS"
"$MLSREG" targets upload --server "$MLSREG_SERVER_ADDRESS" --id bunny-bun045 data/bunny/bun045.ply
GT=$(awk -F, '$1 == "bun000_bun045" { print $4 }' data/bunny/pairs.csv)
"$MLSREG" register --server "$MLSREG_SERVER_ADDRESS" --target bunny-bun045 \
  --source data/bunny/bun000.ply --method "${METHOD:-auto}" --init "$GT" --gt "$GT" \
  --perturb-angle 10 --perturb-translation 10 --perturb-seed 1 "$@"
stop_server
echo "== server stopped"
