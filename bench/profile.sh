#!/usr/bin/env bash
# Instructions per scan of the whole per-scan path (bench/run.sh scan's scan_path), counted by callgrind:
# repeatable on a busy machine, where times are not. Builds bench_tf (bench/build.sh), runs
# exactly $ITERATIONS scans of one sensor under callgrind (the scans cycle through a 10 s recording, as in
# bench/run.sh scan), and prints the instructions per scan of the path and of the functions that cost most.
#   bash bench/profile.sh [UTM-30LX|ILD26TRI|LDS-01]   (default LDS-01; ITERATIONS=500)
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
sensor=${1:-LDS-01}
iterations=${ITERATIONS:-500}
bench=$(bash "$repo/bench/build.sh" bench_tf)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
# Counted: ScanProcessor's prepare and correct (the message checked, corrected, re-binned, the outputs
# built), not the benchmark's setup nor its look-up of the mount (TfFeed::mount, as the node's).
LIDAR_DESKEW_BENCH_NO_ACCURACY=1 LIDAR_DESKEW_BENCH_ITERATIONS=$iterations \
  valgrind --tool=callgrind --callgrind-out-file="$out/callgrind.out" \
  --toggle-collect='*ScanProcessor::prepare*' --toggle-collect='*ScanProcessor::correct*' \
  "$bench" --benchmark_filter="^scan_path/$sensor/" >/dev/null 2>"$out/valgrind.log"
callgrind_annotate --inclusive=yes "$out/callgrind.out" 2>/dev/null |
  awk -v n="$iterations" -v sensor="$sensor" '
    /PROGRAM TOTALS/ { gsub(",", "", $1); printf "%s: %.0f instructions per scan (%d scans)\n\n", sensor, $1 / n, n; next }
    /ScanProcessor::|TwistMotion::|KnotTrajectory::|ScanRebinner::|toCloud|lookupTransform|kthSmallest|se3|malloc$|free$/ {
      count = $1; gsub(",", "", count); name = $0; sub(/^[^?]*\?\?\?:/, "", name)
      gsub(/\(anonymous namespace\)::/, "", name); sub(/^lidar_deskew::/, "", name); sub(/\(.*$/, "", name)
      if (seen[name]++) next
      printf "%10.0f  %s\n", count / n, name }' | head -n 30
