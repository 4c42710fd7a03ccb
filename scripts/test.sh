#!/usr/bin/env bash
# The whole test suite: installs what is missing, builds with catkin_make (tests included), installs,
# builds the Debian package, and runs every test through CTest. Ends with CTest's summary; non-zero on
# any failure.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$repo/scripts/install_deps.sh"
bash "$repo/scripts/build_workspace.sh" -DCATKIN_ENABLE_TESTING=ON
cd "$repo/.build/ws"
catkin_make -j"${LIDAR_DESKEW_JOBS:-2}" tests >/dev/null
# the Debian package that the test debian_package installs (its own build folder, kept between runs)
bash "$repo/scripts/build_deb.sh" >/dev/null
cd build
ctest --output-on-failure -j"${LIDAR_DESKEW_JOBS:-2}"
