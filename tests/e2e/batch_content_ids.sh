#!/usr/bin/env bash
# End-to-end: `mlsreg batch` identifies targets by content. A target file replaced by another
# scan at the same path is uploaded again under a new id (the old transform is never served),
# and running the same batch again re-uses the target without sending its data.
set -euo pipefail
MLSREG=$1
SRC=$2
cd "$SRC"
source scripts/lib-server.sh
work=$(mktemp -d)
trap 'kill "${MLSREG_SERVER_PID:-}" 2>/dev/null || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

start_server "$work/server.log" --workers 2
A=$MLSREG_SERVER_ADDRESS
cp data/bunny/bun045.ply "$work/target.ply"
echo "id,source,target" > "$work/jobs.csv"
echo "a,$SRC/data/bunny/bun000.ply,$work/target.ply" >> "$work/jobs.csv"
run_batch() {  # RESULTS
  "$MLSREG" batch --server "$A" --manifest "$work/jobs.csv" --results "$1" --samples 300 \
    2>> "$work/batch.log" || fail "batch failed: $(tail -5 "$work/batch.log")"
}
target_id() { awk -F, 'NR == 2 { print $3 }' "$1"; }

run_batch "$work/first.csv"
first=$(target_id "$work/first.csv")
[[ "$first" == target-* ]] || fail "target id '$first' does not name the file"
run_batch "$work/again.csv"
[ "$(target_id "$work/again.csv")" = "$first" ] || fail "the same content got another id"
grep -q "target=$first code=OK.*unchanged=true" "$work/server.log" ||
  fail "the second upload of the same content sent its data: $(grep CreateTarget "$work/server.log")"

cp data/bunny/bun315.ply "$work/target.ply"  # another scan at the same path
run_batch "$work/replaced.csv"
replaced=$(target_id "$work/replaced.csv")
[ "$replaced" != "$first" ] || fail "a replaced target file kept its id $first"
points=$("$MLSREG" targets get --server "$A" "$replaced" | awk '{ print $3 }')
[ "$points" = "$(grep -a -m1 "^element vertex" data/bunny/bun315.ply | awk "{ print \$3 }")" ] ||
  fail "the replaced target has $points points"
[ "$(awk -F, 'NR == 2 { print $8 }' "$work/replaced.csv")" != \
  "$(awk -F, 'NR == 2 { print $8 }' "$work/first.csv")" ] || fail "the replaced target gave the old transform"
stop_server || fail "server exited non-zero"
echo "batch content ids: all checks passed"
