#!/usr/bin/env bash
# The demo: installs what is missing, builds with CMake directly (no workspace needed) and runs the
# core on simulated scans of the paper's sensors, printing raw vs corrected error.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$repo/scripts/install_deps.sh"
build="$repo/.build/cmake"
cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=OFF >/dev/null
cmake --build "$build" --target deskew_core_demo -j"${LIDAR_DESKEW_JOBS:-2}" >/dev/null
demo=$(find "$build" -type f -name deskew_core_demo -perm -u+x | head -n 1)
"$demo" "$@"
echo
"$demo" --noise "$@"
