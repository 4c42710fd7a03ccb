#!/usr/bin/env bash
# Instructions per cloud of the 3D per-cloud path (bench_cloud's BM_CloudNodeletPath: an OS1-64 sweep
# parsed, corrected, its output built), counted by callgrind: repeatable on a busy machine, where times
# are not (bench/compare_cloud.sh times them). Runs exactly $ITERATIONS clouds under callgrind and prints
# the instructions per cloud of prepare, correct and the functions that cost most.
#   bash bench/profile_cloud.sh   (ITERATIONS=20; KEEP=DIR)
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
iterations=${ITERATIONS:-20}
bench=$(bash "$repo/bench/build.sh" bench_cloud)
# KEEP=DIR: the callgrind output kept there (for callgrind_annotate), else in a temporary folder.
if [ -n "${KEEP:-}" ]; then
  out=$KEEP
  mkdir -p "$out"
else
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
# Counted: CloudProcessor's prepare and correct, not the benchmark's setup. (Their whole names: a
# pattern matching the lambdas within too would toggle the counting off inside.)
ns=lidar_deskew::ros_adapter
LIDAR_DESKEW_BENCH_ITERATIONS=$iterations \
  valgrind --tool=callgrind --callgrind-out-file="$out/callgrind.out" \
  --toggle-collect="$ns::CloudProcessor::prepare(boost::shared_ptr<sensor_msgs::PointCloud2_<std::allocator<void> > const> const&) const" \
  --toggle-collect="$ns::CloudProcessor::correct($ns::PreparedCloud const&, mrpt::poses::CPose3D const&, lidar_deskew::core::MotionSource const&)" \
  "$bench" --benchmark_filter='^BM_CloudNodeletPath/' >/dev/null 2>"$out/valgrind.log"
callgrind_annotate --inclusive=yes "$out/callgrind.out" 2>/dev/null |
  awk -v n="$iterations" '
    /PROGRAM TOTALS/ { gsub(",", "", $1); printf "OS1-64: %.0f instructions per cloud (%d clouds)\n\n", $1 / n, n; next }
    /^ *[0-9,]+ .*\?\?\?:/ {
      count = $1; gsub(",", "", count); name = $0; sub(/^[^?]*\?\?\?:/, "", name)
      gsub(/\(anonymous namespace\)::/, "", name); gsub(/lidar_deskew::/, "", name); sub(/\(.*$/, "", name)
      if (seen[name]++) next
      printf "%10.0f  %s\n", count / n, name }' | head -n 30
