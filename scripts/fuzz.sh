#!/usr/bin/env bash
# Fuzzes rilo's parsers with libFuzzer (issue 37): builds the fuzz targets
# (tests/fuzz/targets/) with clang, ASan and UBSan in build-fuzz/, runs each
# for SECONDS (default 100; six targets, two at a time), and merges the
# inputs that reach new code into the committed corpora tests/fuzz/corpus/.
# Every ordinary build replays those corpora (ctest -L fuzz). A crash leaves
# its input as build-fuzz/crash-<target>-*; the run then fails.
#
#   scripts/fuzz.sh [SECONDS [TARGET...]]     (default: all six targets)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-100}"
shift || true
build=build-fuzz
targets=(recording_csv meta_yaml rilod_config tum_trajectory bmi263_fifo dw3000_frame)
if (($# > 0)); then targets=("$@"); fi
command -v clang++ >/dev/null || { echo "fuzz.sh: clang++ not found (Debian: clang, libclang-rt-dev or llvm's libFuzzer)" >&2; exit 2; }

cmake -S . -B "$build" -G Ninja -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRILO_FUZZ=ON -DRILO_SANITIZE=ON -DRILO_WERROR=OFF \
  -DRILO_BUILD_TESTS=OFF -DRILO_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$build" --target $(printf 'fuzz_%s ' "${targets[@]}")

run() {
  local t="$1" work="$build/corpus-$1"
  rm -rf "$work" && mkdir -p "$work"
  # Explore from the committed corpus into a scratch folder, then keep only
  # what adds coverage (-merge=1) in the committed one.
  "$build/bin/fuzz_$t" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$build/crash-$t-" "$work" "tests/fuzz/corpus/$t" >"$build/fuzz-$t.log" 2>&1 || {
    echo "fuzz.sh: $t FAILED, see $build/fuzz-$t.log and $build/crash-$t-*" >&2; return 1; }
  "$build/bin/fuzz_$t" -merge=1 "tests/fuzz/corpus/$t" "$work" >>"$build/fuzz-$t.log" 2>&1
  local execs
  execs=$(grep -m1 'stat::number_of_executed_units' "$build/fuzz-$t.log" | awk '{print $2}')
  echo "$t: ${execs:-?} executions in ${seconds} s, 0 crashes, corpus $(ls "tests/fuzz/corpus/$t" | wc -l) inputs"
}

status=0
for ((i = 0; i < ${#targets[@]}; i += 2)); do
  run "${targets[i]}" & a=$!
  if ((i + 1 < ${#targets[@]})); then run "${targets[i + 1]}" & b=$!; else b=""; fi
  wait "$a" || status=1
  if [[ -n "$b" ]]; then wait "$b" || status=1; fi
done
exit "$status"
