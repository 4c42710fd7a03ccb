#!/usr/bin/env bash
# deskew_calibrate's peak memory (and time) against the recording's length: simulated UTM-30LX drives
# (1081 beams, 40 Hz, odometry at 50 Hz, stamps 0.5 s late) of each length given, each calibrated
# under /usr/bin/time -v. Prints the peak resident set size, per recorded second too.
#   bash bench/calibrate_memory.sh [SECONDS ...]     (default: 60 600)
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
[ $# -gt 0 ] || set -- 60 600
bash "$repo/scripts/build_workspace.sh" >/dev/null
bin="$repo/.build/ws/devel/lib/lidar_deskew"
work="$repo/.build/calibrate_memory"
mkdir -p "$work"
printf "%10s %8s %12s %14s %10s %s\n" "recorded_s" "scans" "peak_MB" "peak_kB_per_s" "time_s" "exit"
for seconds in "$@"; do
  "$bin/deskew_simulate" --scenario UTM-30LX/normal/turns --noise --duration "$seconds" --stamp-error 0.5 \
    --bag "$work/drive.bag" --truth "$work/drive.truth" >/dev/null
  code=0
  /usr/bin/time -v "$bin/deskew_calibrate" "$work/drive.bag" --scan-topic /scan >"$work/out.txt" \
    2>"$work/time.txt" || code=$?
  peak_kb=$(awk -F': ' '/Maximum resident set size/ { print $2 }' "$work/time.txt")
  elapsed=$(awk -F': ' '/Elapsed \(wall clock\)/ { print $2 }' "$work/time.txt")
  scans=$(( ${seconds%.*} * 40 ))
  awk -v s="$seconds" -v n="$scans" -v kb="$peak_kb" -v t="$elapsed" -v c="$code" 'BEGIN {
    printf "%10s %8d %12.1f %14.1f %10s %s\n", s, n, kb / 1024, kb / s, t, c }'
  rm -f "$work/drive.bag" "$work/drive.truth"
done
