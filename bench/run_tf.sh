#!/usr/bin/env bash
# Builds (Release) and runs the tf benchmark on one core: our knots, our exact per-beam lookups and
# laser_geometry's fixed-frame projection on the same scans and tf buffer, then their accuracy.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$repo/scripts/install_deps.sh" >/dev/null
build="$repo/.build/bench"
cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=OFF >/dev/null
cmake --build "$build" --target bench_tf -j"${LIDAR_DESKEW_JOBS:-2}" >/dev/null
bench=$(find "$build" -type f -name bench_tf -perm -u+x | head -n 1)
taskset -c 0 "$bench" --benchmark_min_time=0.5 --benchmark_repetitions=5 --benchmark_report_aggregates_only=true "$@"
