#!/usr/bin/env bash
# Builds one benchmark (Release, CMake directly, in .build/bench; the apt packages installed first) and
# prints the path of its binary. bench/run.sh and bench/profile.sh build with it.
#   bash bench/build.sh bench_core|bench_tf|bench_cloud
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
target=${1:?usage: bench/build.sh bench_core|bench_tf|bench_cloud}
bash "$repo/scripts/install_deps.sh" >/dev/null
build="$repo/.build/bench"
cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=OFF >/dev/null
cmake --build "$build" --target "$target" -j"${LIDAR_DESKEW_JOBS:-2}" >/dev/null
find "$build" -type f -name "$target" -perm -u+x | head -n 1
