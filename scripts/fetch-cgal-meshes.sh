#!/usr/bin/env bash
# Puts CGAL's example meshes (data/meshes/NAME.off from Debian's libcgal-demo package, fetched
# with `apt-get download` and unpacked, never installed or committed) into DIR, skipping those
# already there.
#
#   bash scripts/fetch-cgal-meshes.sh DIR NAME [NAME ...]
set -euo pipefail
dir=$1
shift
mkdir -p "$dir"
missing=()
for m in "$@"; do [ -f "$dir/$m.off" ] || missing+=("$m"); done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "== fetching libcgal-demo (CGAL's example meshes) with apt-get download"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
(cd "$tmp" && { apt-get download libcgal-demo 2>/dev/null || { apt-get update -qq && apt-get download libcgal-demo; }; })
dpkg-deb --fsys-tarfile "$tmp"/libcgal-demo_*.deb |
  tar -x -C "$tmp" ./usr/share/doc/libcgal-dev/data.tar.gz
for m in "${missing[@]}"; do
  tar -xzf "$tmp/usr/share/doc/libcgal-dev/data.tar.gz" -C "$tmp" "data/meshes/$m.off"
  cp "$tmp/data/meshes/$m.off" "$dir/$m.off"
done
