#!/usr/bin/env bash
# Configures (Release, Ninja, ccache when present) and builds mlsreg into ./build.
# Usage: scripts/build.sh [extra cmake -D options...]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
JOBS=${JOBS:-$(nproc)}
launcher=()
if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
# Paths relative to the checkout in ccache's keys, so another clone of the same sources hits.
export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD}
generator=()
if command -v ninja >/dev/null 2>&1; then generator=(-G Ninja); fi
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  cmake -S . -B "$BUILD_DIR" "${generator[@]}" -DCMAKE_BUILD_TYPE=${BUILD_TYPE:-Release} "${launcher[@]}" "$@"
elif [ $# -gt 0 ]; then
  cmake -S . -B "$BUILD_DIR" "$@"
fi
cmake --build "$BUILD_DIR" -j "$JOBS"
# The Python package into Debian's python3 (/usr/local/lib/python3.X/dist-packages/mlsreg), when
# it was built and the prefix is writable (as root); otherwise use PYTHONPATH=$BUILD_DIR/python.
if [ -d "$BUILD_DIR/python/mlsreg" ] && [ "${MLSREG_INSTALL_PYTHON:-1}" != 0 ] &&
   [ -w "$(cmake -L -N "$BUILD_DIR" 2>/dev/null | sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p')" ]; then
  cmake --install "$BUILD_DIR" --component python >/dev/null
fi
