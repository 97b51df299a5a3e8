#!/usr/bin/env bash
# mlsreg against Open3D 0.16 (Debian's python3-open3d) on the tuning split, in one run (not run
# by CI; see bench/peer_comparison.py for the protocol and how Open3D was tuned).
#   bash bench/peer_comparison.sh [--out summary.csv]
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
python3 -c "import open3d" 2>/dev/null || DEBIAN_FRONTEND=noninteractive apt-get install -y -q python3-open3d
bash scripts/build.sh
BUILD_DIR=${BUILD_DIR:-build}
# The tuning split's scans (scripts/tuning-split.sh makes them; its registrations are skipped
# here by asking for no method it would time).
if [ ! -f "$BUILD_DIR/tuning/scans/.done" ]; then bash scripts/tuning-split.sh --methods cp-sicp; fi
exec /usr/bin/python3 bench/peer_comparison.py --scans "$BUILD_DIR/tuning/scans" \
  --mlsreg "$BUILD_DIR/mlsreg" "$@"
