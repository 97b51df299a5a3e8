#!/usr/bin/env bash
# The whole test suite, what CI runs:
#   1. Release build (gcc) and every test with CTest: unit, service, cluster, end-to-end.
#   2. ASan + UBSan build (clang): the unit and service tests (the abuse suite among them), then
#      every libFuzzer target for FUZZ_SECONDS (default 15) on a seed corpus from the test data.
#   3. TSan build (clang): the service and cluster tests.
# SANITIZERS=0 runs stage 1 only (the quick local loop).
# Trees configured here from scratch are unity builds (CMAKE_UNITY_BUILD: a few sources per
# translation unit, about half the compile time of a clean build, which is what CI pays); a tree
# that exists keeps its setting, so a developer's incremental builds stay per file.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
JOBS=${JOBS:-$(nproc)}
FUZZ_SECONDS=${FUZZ_SECONDS:-15}
stage() { echo; echo "==== $* ($(date +%T))"; }

stage "1/3 release build and all tests"
if [ -f "$BUILD_DIR/CMakeCache.txt" ]; then scripts/build.sh; else scripts/build.sh -DCMAKE_UNITY_BUILD=ON; fi
(cd "$BUILD_DIR" && ctest --output-on-failure -j "$JOBS")
[ "${SANITIZERS:-1}" = 0 ] && exit 0

# Sanitizer trees: clang, -O1, line tables only (what the sanitizers' stack traces use), unity
# builds, only the targets their tests need.
sanitizer_build() {  # DIR SANITIZER FUZZERS TARGETS...
  local dir=$1 sanitizer=$2 fuzzers=$3
  shift 3
  local launcher=()
  if command -v ccache >/dev/null 2>&1; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
  if [ ! -f "$dir/CMakeCache.txt" ]; then
    CC=clang-14 CXX=clang++-14 cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Debug \
      -DCMAKE_CXX_FLAGS="-O1" -DCMAKE_CXX_FLAGS_DEBUG="-gline-tables-only" -DCMAKE_UNITY_BUILD=ON \
      "${launcher[@]}" \
      -DMLSREG_SANITIZE="$sanitizer" \
      -DMLSREG_BUILD_FUZZERS="$fuzzers" -DMLSREG_BUILD_BENCHMARKS=OFF -DMLSREG_BUILD_TOOLS=OFF -DMLSREG_BUILD_PYTHON=OFF
  fi
  cmake --build "$dir" -j "$JOBS" --target "$@"
}

stage "2/3 ASan + UBSan: unit and service tests, fuzzers"
fuzzers=(ply_reader pcd_reader xyz_reader npy_reader off_reader obj_reader intrinsics_reader
         wire_cloud wire_parameters)
sanitizer_build build-asan address ON mlsreg_unit_tests mlsreg_service_tests mlsreg_fuzz_seeds \
  "${fuzzers[@]/#/fuzz_}"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# Tests that time a registration against a wall-clock deadline run in stage 1 only: sanitizers
# slow the library several-fold.
timed='DeadlineStopsTheRegistration|HealthTurnsNotServingAndRunningWorkDrains'
# Whole registrations on real scans, `auto` from far starts, the verification's scene tests and
# multi-view jobs take from half a minute to four minutes each under ASan (seconds in stage 1):
# they run in stage 1 only. Their code paths run under ASan in the smaller synthetic tests, the
# service tests (the abuse suite among them) and the fuzzers.
heavy='RealDataTest\.|AlignScansTest\.|AutoMethodTest\.|VerificationTest\.|MergedCloudTest\.|ThreadsTest\.'
heavy+='|RegistrationTest\.(CoarsePhaseFilters|StSicpMatches|MlsBeatsClosest)|TargetTest\.PartsMadeOnFirstUse'
heavy+='|FeatureCloudTest\.TheTargetMakes|RegistrationServiceTest\.AutoFromAHalfTurn'
(cd build-asan && ctest --output-on-failure -j "$JOBS" -E "^e2e\.|NOT_BUILT|$timed|$heavy")
corpus=$(mktemp -d)
trap 'rm -rf "$corpus"' EXIT
build-asan/tests/fuzz/mlsreg_fuzz_seeds . "$corpus"
for f in "${fuzzers[@]}"; do
  echo "fuzz_$f: ${FUZZ_SECONDS}s"
  build-asan/tests/fuzz/fuzz_"$f" -max_total_time="$FUZZ_SECONDS" -max_len=65536 -timeout=10 \
    -rss_limit_mb=1024 -print_final_stats=1 "$corpus/$f" 2>&1 | grep -E "stat::number_of_executed_units|ERROR|SUMMARY|crash-|Done" || true
  test "${PIPESTATUS[0]}" -eq 0 || { echo "fuzz_$f FAILED"; exit 1; }
done

stage "3/3 TSan: service and cluster tests"
sanitizer_build build-tsan thread OFF mlsreg_service_tests mlsreg_cluster_tests
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ignore_noninstrumented_modules=1 suppressions=$PWD/tests/tsan.supp"
(cd build-tsan && ctest --output-on-failure -j "$JOBS" -R 'Test\.' -E "NOT_BUILT|$timed|$heavy")
stage "done"
