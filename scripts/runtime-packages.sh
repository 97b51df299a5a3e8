#!/usr/bin/env bash
# Prints the Debian packages that own the shared libraries a binary needs (one per line, sorted):
# what the slim runtime image installs. Fails when a library belongs to no package.
# usage: scripts/runtime-packages.sh build/mlsreg
set -euo pipefail
binary=${1:?usage: runtime-packages.sh BINARY}
ldd "$binary" | awk '/=> \// { print $3 }' | while read -r lib; do
  real=$(readlink -f "$lib")
  pkg=$(dpkg -S "$real" 2>/dev/null || dpkg -S "$lib" 2>/dev/null || true)
  if [ -z "$pkg" ]; then echo "no package owns $lib" >&2; exit 1; fi
  echo "${pkg%%:*}"
done | sed 's/:amd64$//; s/:arm64$//' | sort -u
