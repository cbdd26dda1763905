#!/usr/bin/env bash
# ThreadSanitizer run of the assembled service (not part of CI: it takes
# minutes). Builds rilod and the service tests with -fsanitize=thread in their
# own build folder, runs the end-to-end tests (rilod as a child process over
# loopback DDS, and the in-process IMU-rate path test) and the runtime tests,
# and sums up the reports.
#
#   scripts/tsan-service.sh [build-dir]      (default: build-tsan)
#
# Reports go to <build-dir>/tsan/report.<pid> (one per process); third-party
# libraries that are not instrumented are suppressed (scripts/tsan.supp).
# Wall-clock limits of the tests are scaled by RILO_TEST_TIME_SCALE (TSan
# slows the estimator ten times and more). Tests that check real-time pacing
# or timing (RilodEndToEnd at 3x real time, SIGTERM within 1 s) can fail for
# slowness alone; what this run is for is the race reports.
# Exit code: 0 when no ThreadSanitizer report was written.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build-tsan}
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRILO_TSAN=ON -DRILO_BUILD_BENCHMARKS=OFF \
  ${CMAKE_CXX_COMPILER_LAUNCHER:+-DCMAKE_CXX_COMPILER_LAUNCHER=$CMAKE_CXX_COMPILER_LAUNCHER} >/dev/null
cmake --build "$build" -j2 --target rilod rilo_test_service rilo_test_runtime
reports="$PWD/$build/tsan"
rm -rf "$reports" && mkdir -p "$reports"
export TSAN_OPTIONS="halt_on_error=0 second_deadlock_stack=1 suppressions=$PWD/scripts/tsan.supp log_path=$reports/report"
export RILO_SOURCE_DIR="$PWD" RILO_TEST_TIME_SCALE=${RILO_TEST_TIME_SCALE:-10}
status=0
"$build/bin/rilo_test_service" --gtest_filter='ImuRatePath.*:RilodFaults.*:RilodEndToEnd.*' || status=$?
"$build/bin/rilo_test_runtime" || status=$?
echo "tests exit code: $status"
n=$(cat "$reports"/report.* 2>/dev/null | grep -c "WARNING: ThreadSanitizer" || true)
echo "ThreadSanitizer reports: $n (in $reports)"
[ "$n" -eq 0 ]
