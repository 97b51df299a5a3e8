#!/usr/bin/env bash
# End-to-end: the CLI keeps the promises of docs/cli.md.
# Checks: bad usage exits 2 (CLI11's own codes were 105, 106, 109), --help and --version 0; bad
# output paths are refused before the registration runs; a failing --plot is one line naming the
# cause (not a traceback blaming matplotlib); a file given as a served target is answered with
# how to upload it; max_iterations says its limit is per phase and the count in total; eval runs
# the default method, warns when every run starts at the ground truth, and a missing file is one
# error per run with no made-up median in the summary.
#   cli_promises.sh MLSREG SOURCE_DIR
set -euo pipefail
MLSREG=$1
cd "$2"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
# expect CODE ARGS...: runs mlsreg, stdout to $work/out, stderr to $work/err.
expect() {
  local want=$1 status=0
  shift
  "$MLSREG" "$@" > "$work/out" 2> "$work/err" || status=$?
  [ "$status" -eq "$want" ] || fail "mlsreg $*: exit $status, not $want: $(head -5 "$work/err")"
}
GT=$(awk -F, '$1 == "bun000_bun045" { print $4 }' data/bunny/pairs.csv)
reg=(register --source data/bunny/bun000.ply --target data/bunny/bun045.ply --init "$GT"
     --method cp-sicp --samples 300 --threads 1)

# ---- exit codes: parse errors are bad usage (2)
expect 2 "${reg[@]}" --threads 0
grep -q -- "--threads" "$work/err" || fail "--threads 0: $(cat "$work/err")"
expect 2
expect 2 register --no-such-flag
expect 2 eval --pairs data/bunny/pairs.csv --jobs 1 --bogus
expect 0 --help
expect 0 register --help
grep -q "NPY" "$work/out" || fail "register --help does not mention NPY"
expect 0 --version

# ---- output paths refused before anything runs
for bad in "--json $work/no/r.json" "--plot $work/r.gif" "--plot $work/no/r.png" \
           "--aligned $work/no/a.ply"; do
  # shellcheck disable=SC2086
  expect 2 "${reg[@]}" $bad
  grep -q -- "${bad%% *}: " "$work/err" || fail "$bad: $(cat "$work/err")"
  if grep -q "iter\|^result" "$work/out"; then fail "$bad: the registration ran first"; fi
done
expect 2 eval --pairs data/bunny/pairs.csv --out "$work/no/runs.csv"
grep -q -- "--out: cannot write" "$work/err" || fail "eval --out: $(cat "$work/err")"
expect 2 align --scans data/bunny/bun000.ply data/bunny/bun045.ply --out "$work/no/poses.txt"
grep -q -- "--out: cannot write" "$work/err" || fail "align --out: $(cat "$work/err")"

# ---- a failing --plot: one line, the real cause; the result is kept
expect 1 "${reg[@]}" --plot /proc/mlsreg-plot.png --json "$work/r.json"
[ "$(wc -l < "$work/err")" -eq 1 ] || fail "--plot failure printed: $(cat "$work/err")"
grep -q "^mlsreg register: --plot: cannot write '/proc/mlsreg-plot.png'" "$work/err" \
  || fail "--plot failure: $(cat "$work/err")"
if grep -qi "traceback\|matplotlib" "$work/err"; then fail "--plot blames: $(cat "$work/err")"; fi
[ -s "$work/r.json" ] || fail "--json was not written when --plot failed"
printf '#!/bin/sh\nexec /usr/bin/python3 -S "$@"\n' > "$work/python-without-matplotlib"
chmod +x "$work/python-without-matplotlib"
export MLSREG_PYTHON="$work/python-without-matplotlib"
expect 1 "${reg[@]}" --plot "$work/p.png"
unset MLSREG_PYTHON
[ "$(wc -l < "$work/err")" -eq 1 ] && grep -q "needs matplotlib: .*apt-get install python3-matplotlib" "$work/err" \
  || fail "--plot without matplotlib: $(cat "$work/err")"

# ---- a file where a served target id belongs
expect 2 register --server 127.0.0.1:1 --source data/bunny/bun000.ply --target "$PWD/data/bunny/bun045.ply"
grep -q "the id of a target on the server, not a file" "$work/err" && grep -q "mlsreg targets upload" "$work/err" \
  || fail "served target path: $(cat "$work/err")"

# ---- max_iterations: the limit per phase, the count in total (MLS-SICP: coarse, then fine)
expect 0 register --source data/bunny/bun000.ply --target data/bunny/bun045.ply --init "$GT" \
  --method mls-sicp --samples 300 --threads 1 --max-iterations 2 --quiet
grep -Eq "^result: max_iterations \(2 per phase\) after [0-9]+ iterations in total" "$work/out" \
  || fail "max_iterations: $(head -1 "$work/out")"

# ---- lengths in metres: the same registration as in units of d; a bad unit names its flag
expect 0 register --source data/bunny/bun000.ply --target data/bunny/bun045.ply --init "$GT" \
  --method mls-sicp --samples 300 --threads 1 --max-iterations 3 --mls-radius 5d --quiet --json "$work/d.json"
metres=$(python3 -c "import json; print(5 * json.load(open('$work/d.json'))['scales']['mean_spacing'])")
expect 0 register --source data/bunny/bun000.ply --target data/bunny/bun045.ply --init "$GT" \
  --method mls-sicp --samples 300 --threads 1 --max-iterations 3 --mls-radius "${metres}m" --quiet --json "$work/m.json"
python3 - "$work/d.json" "$work/m.json" <<'PY' || fail "--mls-radius in m differs from in d"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:])
assert abs(a["scales"]["mls_radius"] - b["scales"]["mls_radius"]) < 1e-9 * a["scales"]["mls_radius"], (a["scales"], b["scales"])
assert max(abs(x - y) for x, y in zip(a["transform"], b["transform"])) < 1e-9
PY
expect 2 "${reg[@]}" --max-distance 1furlong
grep -q -- "--max-distance: '1furlong' is not valid" "$work/err" || fail "bad length: $(cat "$work/err")"
expect 2 "${reg[@]}" --max-distance=-1cm
grep -q -- "--max-distance: '-1cm' is not valid" "$work/err" || fail "negative length: $(cat "$work/err")"
expect 2 "${reg[@]}" --mls-radius 10m
grep -q "mls.radius_d = 10 m is .* d on this target" "$work/err" || fail "length out of range: $(cat "$work/err")"

# ---- eval: the default method; starting at the ground truth is warned of; a missing file
head -2 data/bunny/pairs.csv > "$work/one.csv"
sed -i "s|bun000.ply|$PWD/data/bunny/bun000.ply|; s|bun045.ply|$PWD/data/bunny/bun045.ply|" "$work/one.csv"
expect 0 eval --pairs "$work/one.csv" --samples 300 --jobs 1 --out "$work/runs.csv"
grep -q "^auto " "$work/out" || fail "eval's default method is not auto: $(cat "$work/out")"
grep -q "warning: .*one.csv: 1 of 1 problems have no init column .* start at the ground truth" "$work/err" \
  || fail "no warning about starting at the ground truth: $(cat "$work/err")"
expect 0 eval --pairs "$work/one.csv" --samples 300 --jobs 1 --out "$work/runs.csv" --perturb-angle 5 --perturb-translation 5
if grep -q "warning" "$work/err"; then fail "warned with --perturb-*: $(cat "$work/err")"; fi
sed "s|bun000.ply|missing.ply|" "$work/one.csv" > "$work/missing.csv"
expect 3 eval --pairs "$work/missing.csv" --samples 300 --jobs 1 --out "$work/runs.csv" --perturb-angle 5
grep -q "^mlsreg eval: bun000_bun045 (auto, .*missing.csv): .*missing.ply" "$work/err" \
  || fail "missing file: $(cat "$work/err")"
grep -Eq "^auto +1 +0/1 +1 +- +- +- +-$" "$work/out" || fail "summary of a run that did not run: $(cat "$work/out")"
if grep -q "0\.0000" "$work/out"; then fail "made-up median: $(cat "$work/out")"; fi
echo "PASS"
