#!/usr/bin/env bash
# CLI conventions: --version, the generated reference docs/cli.md matches the commands' own help,
# bash completion offers subcommands and flags, and --json on the commands that print results.
#   cli_conventions.sh MLSREG SOURCE_DIR
set -euo pipefail
MLSREG=$1
cd "$2"
fail() { echo "FAIL: $*" >&2; exit 1; }

version=$("$MLSREG" --version)
[[ $version =~ ^mlsreg\ [0-9]+\.[0-9]+\.[0-9]+$ ]] || fail "--version printed '$version'"

"$MLSREG" manual > "${TMPDIR:-/tmp}/cli.md.$$"
if ! diff -u docs/cli.md "${TMPDIR:-/tmp}/cli.md.$$" > "${TMPDIR:-/tmp}/cli.diff.$$"; then
  head -40 "${TMPDIR:-/tmp}/cli.diff.$$" >&2
  rm -f "${TMPDIR:-/tmp}/cli.md.$$" "${TMPDIR:-/tmp}/cli.diff.$$"
  fail "docs/cli.md is out of date: run build/mlsreg manual > docs/cli.md"
fi
rm -f "${TMPDIR:-/tmp}/cli.md.$$" "${TMPDIR:-/tmp}/cli.diff.$$"
grep -q "^| 4 | register, verify, align, batch |" docs/cli.md || fail "no exit code 4 in docs/cli.md"
grep -q -- "--auto-candidates" docs/cli.md || fail "register's parameter flags missing from docs/cli.md"

# Completion: source the script and ask it as bash would.
complete() { :; }  # the script's `complete` line needs an interactive shell's builtin
source <("$MLSREG" completion bash)
ask() {  # words...; the last is the one being completed
  COMP_WORDS=(mlsreg "$@")
  COMP_CWORD=$#
  COMPREPLY=()
  _mlsreg
  echo "${COMPREPLY[*]}"
}
[ "$(ask reg)" = "register" ] || fail "completion of 'reg': '$(ask reg)'"
[[ " $(ask register --sou) " == *" --source "* ]] || fail "completion of 'register --sou': '$(ask register --sou)'"
[[ " $(ask targets u) " == *" upload "* ]] || fail "completion of 'targets u': '$(ask targets u)'"
[[ " $(ask targets upload --i) " == *" --id "* ]] || fail "completion of 'targets upload --i'"
[[ " $(ask register --method auto --mls-pro) " == *" --mls-projection "* ]] || fail "completion after a value"

# serve refuses a port gRPC would wrap modulo 65536 (99999 listened on 34463), naming the flag.
status=0
"$MLSREG" serve --listen 127.0.0.1:99999 > /dev/null 2> "${TMPDIR:-/tmp}/serve.err.$$" || status=$?
grep -q -- "listen (--listen): port 99999" "${TMPDIR:-/tmp}/serve.err.$$" && [ "$status" -eq 2 ] \
  || fail "serve --listen 127.0.0.1:99999: exit $status: $(cat "${TMPDIR:-/tmp}/serve.err.$$")"
rm -f "${TMPDIR:-/tmp}/serve.err.$$"

# --json on eval (summary file); register's is checked in cli_round_trip.sh.
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
head -2 data/bunny/pairs.csv > "$work/one.csv"
sed -i "s|bun000.ply|$PWD/data/bunny/bun000.ply|; s|bun045.ply|$PWD/data/bunny/bun045.ply|" "$work/one.csv"
"$MLSREG" eval --pairs "$work/one.csv" --methods cp-sicp --samples 500 --jobs 1 --out "$work/runs.csv" \
  --json "$work/summary.json" > /dev/null 2>&1 || fail "eval --json exited $?"
python3 -c "import json,sys; j=json.load(open(sys.argv[1])); m=j['methods'][0]; assert m['method']=='cp-sicp' and m['runs']==1 and m['successes']==1, j" "$work/summary.json" \
  || fail "eval --json: $(cat "$work/summary.json")"
echo "PASS"
