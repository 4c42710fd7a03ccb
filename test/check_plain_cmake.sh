#!/usr/bin/env bash
# The package configures and builds with CMake directly, outside any catkin workspace, in
# REPO/.build/plain. Laid out like the workspace .build/ws (src/lidar_deskew links to the repo, objects in
# build/lidar_deskew, devel space devel) so that it compiles through the workspace's compiler cache
# (scripts/compiler_cache.sh: ccache finds an object by the paths relative to the repo).
# Usage: test/check_plain_cmake.sh SOURCE_DIR
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "${1:?source dir}" && pwd -P)
source "$repo/scripts/compiler_cache.sh"
work="$repo/.build/plain"
rm -rf "$work"
mkdir -p "$work/src"
ln -s "$repo" "$work/src/lidar_deskew"
cmake -S "$work/src/lidar_deskew" -B "$work/build/lidar_deskew" -DCMAKE_BUILD_TYPE=Release \
  -DCATKIN_DEVEL_PREFIX="$work/devel" -DCATKIN_ENABLE_TESTING=OFF -DLIDAR_DESKEW_WERROR=ON \
  "${compiler_cache_args[@]}" >/dev/null
cmake --build "$work/build/lidar_deskew" --target lidar_deskew_core -j2 >/dev/null
test -n "$(find "$work/devel" "$work/build" -name 'liblidar_deskew_core.so*' -print -quit)"
echo "plain CMake configure + build of lidar_deskew_core: ok"
