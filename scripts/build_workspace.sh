#!/usr/bin/env bash
# Builds the package with catkin_make in a workspace inside the repo's ignored .build/ folder
# (.build/ws/src/lidar_deskew links back to the repo) and installs it afresh to .build/ws/install (an
# earlier install's files that the package no longer installs would linger; test/check_install.sh
# checks what is installed and what is not).
# Usage: scripts/build_workspace.sh [extra catkin_make arguments...]
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd -P)
ws="$repo/.build/ws"
mkdir -p "$ws/src"
ln -sfn "$repo" "$ws/src/lidar_deskew"
cd "$ws"
jobs=${LIDAR_DESKEW_JOBS:-2}
source "$repo/scripts/compiler_cache.sh"
args=(-DCMAKE_BUILD_TYPE=Release "${compiler_cache_args[@]}" "$@")
catkin_make -j"$jobs" "${args[@]}"
rm -rf "$ws/install"
# The same arguments: catkin_make runs CMake again whenever they differ from its last run's.
catkin_make -j"$jobs" install "${args[@]}" >/dev/null
