#!/usr/bin/env bash
# End-to-end: `mlsreg eval --shard i/N` (and --shard-from-env, as in a Kubernetes Indexed Job)
# splits an evaluation so that `--merge` of the shards' CSVs writes what one run writes: the same
# rows in the same order with the same values (the timing columns aside), the same summary and
# the same --json; a missing shard is an error naming the runs it lacks; bad shard flags exit 2.
#   eval_shards.sh MLSREG SOURCE_DIR
set -euo pipefail
MLSREG=$1
cd "$2"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# Six problems on two targets (each bunny pair three times under other ids): the perturbed start
# of a problem depends on its index, so a shard that renumbered its problems would differ.
{
  head -1 data/bunny/pairs.csv
  for copy in a b c; do
    tail -n +2 data/bunny/pairs.csv | sed "s/^\([^,]*\),/\1_$copy,/"
  done
} > "$work/pairs.csv"
cp data/bunny/*.ply "$work/"
run=(eval --pairs "$work/pairs.csv" --methods cp-sicp,mls-sicp --samples 500 --jobs 2
     --perturb-angle 5 --perturb-translation 5 --perturb-seed 3)

"$MLSREG" "${run[@]}" --out "$work/one.csv" --json "$work/one.json" > "$work/one.txt" 2> /dev/null ||
  fail "the single run failed"
for i in 0 1; do
  "$MLSREG" "${run[@]}" --shard "$i/3" --out "$work/shard-$i.csv" > /dev/null 2>&1 ||
    fail "shard $i/3 failed"
done
JOB_COMPLETION_INDEX=2 "$MLSREG" "${run[@]}" --shard-from-env 3 --out "$work/shard-2.csv" \
  > /dev/null 2>&1 || fail "shard 2 from the environment failed"
# Whole targets per shard, dealt in order of appearance: two targets over three shards leave the
# last shard without rows.
rows=$(for i in 0 1 2; do echo $(($(wc -l < "$work/shard-$i.csv") - 1)); done | tr '\n' ' ')
[ "$rows" = "6 6 0 " ] || fail "rows per shard: $rows, expected 6 6 0 (each target whole)"

"$MLSREG" "${run[@]}" --merge "$work"/shard-*.csv --out "$work/merged.csv" \
  --json "$work/merged.json" > "$work/merged.txt" 2> /dev/null || fail "the merge failed"
# Equal but for the columns that time the runs.
strip_times() {
  python3 - "$1" <<'PY'
import csv, sys
rows = list(csv.reader(open(sys.argv[1])))
keep = [i for i, c in enumerate(rows[0]) if not (c.startswith("time_") or c in ("target_build_s", "trace_elapsed_s"))]
for r in rows:
    print(",".join(r[i] for i in keep))
PY
}
diff <(strip_times "$work/one.csv") <(strip_times "$work/merged.csv") > "$work/diff" ||
  fail "merged shards differ from one run: $(head -c 600 "$work/diff")"
diff <(sed 's/ *[0-9.]* s$//' "$work/one.txt") <(sed 's/ *[0-9.]* s$//' "$work/merged.txt") ||
  fail "the merged summary differs from one run's"
python3 - "$work/one.json" "$work/merged.json" <<'PY' || fail "the merged --json differs"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:])
for m in a["methods"] + b["methods"]:
    m.pop("median_time_s")
assert a == b, (a, b)
PY

# A missing shard: exit 1, naming the runs it lacks.
status=0
"$MLSREG" "${run[@]}" --merge "$work/shard-0.csv" "$work/shard-2.csv" > /dev/null 2> "$work/err" ||
  status=$?
[ "$status" -eq 1 ] || fail "merge without shard 1 exited $status"
grep -q "6 of 12 runs are missing" "$work/err" || fail "merge without shard 1: $(cat "$work/err")"
# The same shard twice.
status=0
"$MLSREG" "${run[@]}" --merge "$work"/shard-*.csv "$work"/shard-*.csv > /dev/null 2> "$work/err" ||
  status=$?
[ "$status" -eq 1 ] && grep -q "twice" "$work/err" || fail "a shard given twice: exit $status $(cat "$work/err")"

# Bad shard flags: exit 2 with the flag named.
for bad in "--shard 3/3" "--shard 1" "--shard -1/2" "--shard 0/0"; do
  status=0
  # shellcheck disable=SC2086
  "$MLSREG" "${run[@]}" $bad > /dev/null 2> "$work/err" || status=$?
  [ "$status" -eq 2 ] && grep -q -- "--shard" "$work/err" || fail "$bad: exit $status $(cat "$work/err")"
done
status=0
env -u JOB_COMPLETION_INDEX "$MLSREG" "${run[@]}" --shard-from-env 3 > /dev/null 2> "$work/err" ||
  status=$?
[ "$status" -eq 2 ] && grep -q "JOB_COMPLETION_INDEX" "$work/err" ||
  fail "--shard-from-env without the variable: exit $status $(cat "$work/err")"
echo "eval shards: OK"
