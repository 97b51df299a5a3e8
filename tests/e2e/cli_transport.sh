#!/usr/bin/env bash
# The networked half of the CLI is a module loaded on demand (cli/transport.h): a program copied
# without libmlsreg_transport.so still registers locally, and its networked commands fail with a
# message that names the module and MLSREG_TRANSPORT; pointed at the module, they work again.
#   cli_transport.sh MLSREG SOURCE_DIR
set -euo pipefail
MLSREG=$1
cd "$2"
source scripts/lib-server.sh
fail() { echo "FAIL: $*" >&2; exit 1; }
work=$(mktemp -d)
trap 'kill "${MLSREG_SERVER_PID:-}" 2>/dev/null || true; rm -rf "$work"' EXIT
module="$(dirname "$MLSREG")/libmlsreg_transport.so"
[ -f "$module" ] || fail "no transport module beside $MLSREG"
cp "$MLSREG" "$work/mlsreg"
lonely=$work/mlsreg

# The program alone does not need gRPC to start.
if ldd "$lonely" | grep -q "libgrpc"; then fail "mlsreg links gRPC itself"; fi

# A local registration needs no module.
status=0
"$lonely" register --source data/bunny/bun045.ply --target data/bunny/bun000.ply --quiet \
  --json "$work/local.json" > /dev/null || status=$?
[ "$status" = 0 ] || fail "a local register without the module exited $status"
grep -q '"verified": true' "$work/local.json" || fail "the local registration did not verify"

# Networked commands name what is missing, and exit 1.
for command in "health --server 127.0.0.1:1 --attempts 1" "serve --listen 127.0.0.1:0"; do
  status=0
  # shellcheck disable=SC2086
  "$lonely" $command > /dev/null 2> "$work/err" || status=$?
  [ "$status" = 1 ] || fail "'$command' without the module exited $status"
  grep -q "libmlsreg_transport.so" "$work/err" || fail "'$command': $(cat "$work/err")"
  grep -q "MLSREG_TRANSPORT" "$work/err" || fail "'$command' does not say how to name the module"
done

# MLSREG_TRANSPORT names it: a round trip through a server started by the copy.
export MLSREG_TRANSPORT=$module
MLSREG=$lonely start_server "$work/server.log" --workers 1
address=$MLSREG_SERVER_ADDRESS
"$lonely" health --server "$address" | grep -qx SERVING || fail "health through MLSREG_TRANSPORT"
"$lonely" targets upload --server "$address" --id bun000 data/bunny/bun000.ply > /dev/null
status=0
"$lonely" register --server "$address" --target bun000 --source data/bunny/bun045.ply --quiet \
  --json "$work/remote.json" > /dev/null || status=$?
[ "$status" = 0 ] || fail "a served register through MLSREG_TRANSPORT exited $status"
grep -q '"verified": true' "$work/remote.json" || fail "the served registration did not verify"

# A file that is not the module is refused with the loader's reason.
status=0
MLSREG_TRANSPORT=$work/mlsreg "$lonely" health --server "$address" 2> "$work/err" || status=$?
[ "$status" = 1 ] || fail "a wrong module exited $status"
grep -q "$work/mlsreg" "$work/err" || fail "a wrong module's message: $(cat "$work/err")"
echo "cli_transport: ok"
