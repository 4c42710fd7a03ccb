#!/usr/bin/env bash
# The whole test suite: installs what is missing, builds with catkin_make (tests included), installs,
# and runs every test through CTest (the test debian_package builds the Debian package, overlapping the
# tests that mostly wait on roscore). Ends with CTest's summary; non-zero on
# any failure. Warnings are errors here (LIDAR_DESKEW_WERROR, off by default for users).
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd -P)
bash "$repo/scripts/install_deps.sh"
cmake_args=(-DCATKIN_ENABLE_TESTING=ON -DLIDAR_DESKEW_WERROR=ON)
bash "$repo/scripts/build_workspace.sh" "${cmake_args[@]}"
# The tests compile through the same cache, with build_workspace.sh's arguments (catkin_make runs CMake
# again, and regenerates, whenever they differ from its last run's).
source "$repo/scripts/compiler_cache.sh"
cd "$repo/.build/ws"
catkin_make -j"${LIDAR_DESKEW_JOBS:-2}" tests -DCMAKE_BUILD_TYPE=Release "${compiler_cache_args[@]}" "${cmake_args[@]}" \
  >/dev/null
cd build
ctest --output-on-failure -j"${LIDAR_DESKEW_JOBS:-2}"
