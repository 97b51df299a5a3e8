#!/usr/bin/env bash
# Prints the Debian packages that own the shared libraries the given binaries need (one per line,
# sorted): what the slim runtime image installs. Fails when a library belongs to no package.
# usage: scripts/runtime-packages.sh build/mlsreg build/libmlsreg_transport.so
set -euo pipefail
[ $# -gt 0 ] || { echo "usage: runtime-packages.sh BINARY..." >&2; exit 2; }
for binary in "$@"; do ldd "$binary"; done | awk '/=> \// { print $3 }' | while read -r lib; do
  real=$(readlink -f "$lib")
  pkg=$(dpkg -S "$real" 2>/dev/null || dpkg -S "$lib" 2>/dev/null || true)
  if [ -z "$pkg" ]; then echo "no package owns $lib" >&2; exit 1; fi
  echo "${pkg%%:*}"
done | sed 's/:amd64$//; s/:arm64$//' | sort -u
