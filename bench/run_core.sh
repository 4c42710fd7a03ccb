#!/usr/bin/env bash
# Builds (Release) and runs the core benchmark on one core. Extra arguments go to Google Benchmark,
# e.g. --benchmark_filter=DeskewScan --benchmark_repetitions=5
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$repo/scripts/install_deps.sh" >/dev/null
build="$repo/.build/bench"
cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=OFF >/dev/null
cmake --build "$build" --target bench_core -j"${LIDAR_DESKEW_JOBS:-2}" >/dev/null
bench=$(find "$build" -type f -name bench_core -perm -u+x | head -n 1)
taskset -c 0 "$bench" --benchmark_min_time=0.5 --benchmark_repetitions=5 --benchmark_report_aggregates_only=true "$@"
