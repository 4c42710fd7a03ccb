#!/usr/bin/env bash
# The package configures and builds with CMake directly, outside any catkin workspace.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
source_dir=${1:?source dir}
build_dir=${2:?build dir}
rm -rf "$build_dir"
cmake -S "$source_dir" -B "$build_dir" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=OFF >/dev/null
cmake --build "$build_dir" --target lidar_deskew_core -j2 >/dev/null
test -n "$(find "$build_dir" -name 'liblidar_deskew_core.so*' -print -quit)"
echo "plain CMake configure + build of lidar_deskew_core: ok"
