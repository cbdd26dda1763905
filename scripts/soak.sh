#!/usr/bin/env bash
# Soak (issue 37): rilod on a looped recording at SPEED x real time for
# MINUTES of data, logging its resident memory and the update p99 each
# wall-clock minute. By default a 10-minute simulated office walk (made once
# with `rilo sim`) at 10x for one hour of data: six minutes of wall time.
#
#   scripts/soak.sh [BUILD_DIR] [RECORDING] [SPEED] [MINUTES]
#
# Prints one line per minute (minute, RSS kB, update p99 and max ms since
# start, queue overflows) and the drift of RSS from the first minute to the
# last. rilod's log is kept in $OUT (default /tmp/rilo-soak).
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
rec="${2:-}"
speed="${3:-10}"
minutes="${4:-60}"
out="${OUT:-/tmp/rilo-soak}"
mkdir -p "$out"
if [[ -z "$rec" ]]; then
  rec="$out/office-10min"
  [[ -d "$rec" ]] || "$build/bin/rilo" sim "$rec" --seed 7 --seconds 600 >/dev/null
fi
rec="$(cd "$rec" && pwd)"
sed -e "s|path: ../tests/data/office-demo |path: $rec |" -e "s|speed: 1.0 |speed: $speed |" \
    -e "s|loop: false |loop: true  |" -e "s|file: ../tests/data/office-demo/anchors.csv|file: $rec/anchors.csv|" \
    config/rilod.yaml >"$out/soak.yaml"
wall_s=$(awk -v m="$minutes" -v s="$speed" 'BEGIN { printf "%d", m * 60 / s + 1 }')
"$build/bin/rilod" --config "$out/soak.yaml" --seconds "$wall_s" >"$out/rilod.log" 2>&1 &
pid=$!
echo "minute rss_kb p99_ms max_ms overflows"
first=""
last=""
for ((m = 1; m * 60 <= wall_s; ++m)); do
  sleep 60
  [[ -d /proc/$pid ]] || break
  rss=$(awk '/VmRSS/ {print $2}' "/proc/$pid/status")
  line=$(grep -E ' (tracking|degraded|initializing|lost): ' "$out/rilod.log" | tail -1)
  p99=$(sed -n 's/.*p99 \([0-9.]*\) ms, max.*/\1/p' <<<"$line")
  max=$(sed -n 's/.*p99 [0-9.]* ms, max \([0-9.]*\) ms;.*/\1/p' <<<"$line")
  ovf=$(sed -n 's/.*overflows \([0-9]*\),.*/\1/p' <<<"$line")
  echo "$m $rss ${p99:-?} ${max:-?} ${ovf:-?}"
  first="${first:-$rss}"
  last="$rss"
done
wait "$pid" || { echo "soak.sh: rilod failed, see $out/rilod.log" >&2; exit 1; }
grep 'stopped (' "$out/rilod.log" | sed 's/^.* info //'
echo "RSS drift, first minute to last: $(( ${last:-0} - ${first:-0} )) kB"
