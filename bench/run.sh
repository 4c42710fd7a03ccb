#!/usr/bin/env bash
# Builds (Release, CMake directly) and runs one benchmark on one core, median of 5 repetitions.
#   bash bench/run.sh core   # the ROS-free core: correction, re-binning, per-point times
#   bash bench/run.sh tf     # with tf lookups: ours (knots: twist and linear; exact) vs laser_geometry, then accuracy
#   bash bench/run.sh cloud  # multi-line clouds (OS1-64, 65,536 points): core, and the whole per-cloud path
#   bash bench/run.sh scan   # the whole per-scan path (ScanProcessor) vs laser_geometry, and their ratio
# Extra arguments go to Google Benchmark, e.g. --benchmark_filter=DeskewScan
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
name=${1:?usage: bench/run.sh core|tf|cloud|scan [benchmark arguments]}
shift
if [ "$name" = scan ]; then  # part of bench_tf: the same recordings and tf buffer
  name=tf
  export LIDAR_DESKEW_BENCH_NO_ACCURACY=1
  set -- --benchmark_filter='^(scan_path|laser_geometry)/' "$@"
fi
bench=$(bash "$repo/bench/build.sh" "bench_$name")
taskset -c 0 "$bench" --benchmark_min_time=0.5 --benchmark_repetitions=5 --benchmark_report_aggregates_only=true "$@"
