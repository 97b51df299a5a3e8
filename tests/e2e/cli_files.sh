#!/usr/bin/env bash
# End-to-end: the clouds `mlsreg register` reads and writes, as the user meant them.
# Checks: a CloudCompare "x y z r g b" export is read as colours (not normalised into normals)
# and its colours stay beside the distance field of --aligned; --aligned and --merged write the
# format their extension names (PCD, XYZ, NPY); an extension mlsreg cannot write, or a missing
# directory, is refused before the registration runs; "x y z intensity" is read, and the ignored
# column said; normals given in a file are said not to be used.
#   cli_files.sh MLSREG SOURCE_DIR
set -euo pipefail
MLSREG=$1
cd "$2"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

# The source as text files: colours (CloudCompare's header), intensity, unit normals.
python3 - "$work" <<'PY'
import sys
work = sys.argv[1]
rows = [l.split() for l in open("data/bunny/bun000.ply") if len(l.split()) == 3]
rows = [r for r in rows if all(c.replace(".", "").replace("-", "").replace("e", "").isdigit() for c in r)]
with open(f"{work}/cc.txt", "w") as f:
    f.write("//X,Y,Z,R,G,B\n")
    for i, (x, y, z) in enumerate(rows):
        f.write(f"{x},{y},{z},{i % 256},{(7 * i) % 256},200\n")
with open(f"{work}/intensity.xyz", "w") as f:
    f.write("x y z intensity\n")
    for x, y, z in rows:
        f.write(f"{x} {y} {z} 0.5\n")
with open(f"{work}/normals.xyz", "w") as f:
    f.write("x y z nx ny nz\n")
    for x, y, z in rows:
        f.write(f"{x} {y} {z} 0 0 1\n")
PY
GT=$(awk -F, '$1 == "bun000_bun045" { print $4 }' data/bunny/pairs.csv)
run=(register --target data/bunny/bun045.ply --init "$GT" --method cp-sicp --samples 500 --threads 1)

"$MLSREG" "${run[@]}" --source "$work/cc.txt" --aligned "$work/aligned.pcd" \
  --merged "$work/merged.xyz" > "$work/cc.out" 2> "$work/cc.err" || fail "colours: $(cat "$work/cc.err")"
grep -q "^result: " "$work/cc.out" || fail "no result: $(cat "$work/cc.out")"
python3 - "$work" <<'PY' || fail "--aligned .pcd / --merged .xyz"
import struct, sys
work = sys.argv[1]
source = [l.strip().split(",") for l in open(f"{work}/cc.txt")][1:]
data = open(f"{work}/aligned.pcd", "rb").read()
header_end = data.index(b"DATA binary\n") + 12
header = data[:header_end].decode()
assert "FIELDS x y z distance_d rgb\n" in header and "SIZE 8 8 8 4 4\n" in header, header
n = int(header.split("POINTS ")[1].split()[0])
assert n == len(source), (n, len(source))
for i in (0, 1, 1000, n - 1):
    x, y, z, d, rgb = struct.unpack_from("<dddfI", data, header_end + 32 * i)
    assert (rgb >> 16, (rgb >> 8) & 255, rgb & 255) == tuple(int(v) for v in source[i][3:]), i
    assert 0 <= d < 5, d
merged = open(f"{work}/merged.xyz").read().splitlines()
assert merged[0] == "x y z cloud r g b", merged[0]
assert merged[1].split()[3:] == ["0", "255", "140", "0"], merged[1]
assert merged[-1].split()[3:] == ["1", "70", "130", "180"], merged[-1]
PY

# NPY: numbers only, in the documented column order.
"$MLSREG" "${run[@]}" --source data/bunny/bun000.ply --aligned "$work/aligned.npy" --quiet \
  > /dev/null 2>&1 || fail "--aligned .npy"
python3 -c "
import struct, sys
data = open(sys.argv[1], 'rb').read()
header = data[10:10 + struct.unpack('<H', data[8:10])[0]].decode()
assert \"'shape': (40256, 7)\" in header, header
" "$work/aligned.npy" || fail "--aligned .npy shape"

# Refused before the registration runs: no iteration line, exit 2, the flag named.
for bad in "--aligned $work/out.obj" "--merged $work/nodir/m.ply" "--aligned $work"; do
  status=0
  # shellcheck disable=SC2086
  "$MLSREG" "${run[@]}" --source data/bunny/bun000.ply $bad > "$work/bad.out" 2> "$work/bad.err" || status=$?
  [ "$status" -eq 2 ] || fail "$bad: exit $status: $(cat "$work/bad.err")"
  grep -q -- "${bad%% *}: " "$work/bad.err" || fail "$bad: $(cat "$work/bad.err")"
  if grep -q "iter" "$work/bad.out"; then fail "$bad: the registration ran first"; fi
done
grep -q "does not exist" <("$MLSREG" "${run[@]}" --source data/bunny/bun000.ply --merged "$work/nodir/m.ply" 2>&1) \
  || fail "a missing directory is not named"

# Extra columns are read and said; normals given are said not to be used.
"$MLSREG" "${run[@]}" --source "$work/intensity.xyz" --quiet > /dev/null 2> "$work/i.err" \
  || fail "x y z intensity: $(cat "$work/i.err")"
grep -q "note: .*intensity.xyz: XYZ: columns read and ignored: intensity (column 4)" "$work/i.err" \
  || fail "the ignored column is not said: $(cat "$work/i.err")"
"$MLSREG" "${run[@]}" --source "$work/normals.xyz" --quiet > /dev/null 2> "$work/n.err" \
  || fail "normals: $(cat "$work/n.err")"
grep -q "normals.xyz: its normals are not used" "$work/n.err" || fail "normals: $(cat "$work/n.err")"
# --columns names unnamed columns (and refuses PLY, whose header names them).
tail -n +2 "$work/cc.txt" > "$work/bare.csv"
"$MLSREG" "${run[@]}" --source "$work/bare.csv" --columns x,y,z,r,g,b --quiet > /dev/null 2> "$work/c.err" \
  || fail "--columns: $(cat "$work/c.err")"
if grep -q "note" "$work/c.err"; then fail "--columns named every column: $(cat "$work/c.err")"; fi
status=0
"$MLSREG" "${run[@]}" --source data/bunny/bun000.ply --columns x,y,z > /dev/null 2> "$work/p.err" || status=$?
[ "$status" -eq 2 ] && grep -q -- "--columns names the columns of text" "$work/p.err" \
  || fail "--columns with PLY files only: $status $(cat "$work/p.err")"
echo "PASS"
