#!/usr/bin/env bash
# The Debian package works from its own files. Builds it with scripts/build_deb.sh (or takes DEB),
# checks its control data and that apt resolves its Depends, that lintian finds no error (it prints the
# warnings; each warning's tag must be justified in docs/PACKAGING.md), that
# it holds what a downstream package needs and not the simulators' and scoring's headers, unpacks it
# into a scratch root and then,
# in a private mount namespace where that root is laid over /usr (where dpkg -i would put the files;
# the rest of the machine does not see them, and a copy installed on the machine is hidden) and with
# an empty environment (no build tree, devel space or workspace install on any path):
#  (a) rosrun lidar_deskew deskew_bag corrects the Neato recording (60 scans, most corrected);
#  (b) on a roscore of its own (free port), roslaunch lidar_deskew deskew.launch loads the nodelet
#      through the installed nodelets.xml: it logs its start-up line and advertises /scan_deskewed;
#  (c) a CMake project outside any workspace does find_package(lidar_deskew) and links its core.
# Needs root (a mount namespace and overlayfs); without them it says so and exits 77 (skipped).
# Usage: test/check_deb.sh REPO [DEB]
set -euo pipefail
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH

if [ "${1:-}" = --inside ]; then
  # In the namespace, with an empty environment: $2 scratch folder, $3 repo.
  scratch=$2
  repo=$3
  multiarch=$(dpkg-architecture -qDEB_HOST_MULTIARCH)
  # A whiteout (character device 0/0) hides what the machine itself has of ours under /usr.
  mkdir -p "$scratch/hide"
  for path in lib/lidar_deskew share/lidar_deskew include/lidar_deskew "lib/$multiarch/cmake/lidar_deskew" \
    "lib/$multiarch/pkgconfig/lidar_deskew.pc" $(cd /usr && ls -d "lib/$multiarch"/liblidar_deskew* 2>/dev/null); do
    if [ -e "/usr/$path" ]; then
      mkdir -p "$(dirname "$scratch/hide/$path")"
      mknod "$scratch/hide/$path" c 0 0
    fi
  done
  mount -t overlay overlay -o "lowerdir=$scratch/root/usr:$scratch/hide:/usr" /usr

  echo "== (a) deskew_bag from the package"
  rosrun lidar_deskew deskew_bag --help >"$scratch/help.txt"
  grep -q "usage:" "$scratch/help.txt"
  rosrun lidar_deskew deskew_simulate --list >"$scratch/scenarios.txt"
  grep -q "ILD26TRI/high/arc" "$scratch/scenarios.txt"
  summary=$(rosrun lidar_deskew deskew_bag "$repo/data/neato_xv11/test_drive.bag" "$scratch/neato.bag" \
    --scan-topic /stable_scan --stamp-at end --quiet)
  echo "$summary"
  count() { echo "$summary" | sed -n "s/.*[:,] $1 \([0-9]*\).*/\1/p"; }
  received=$(count received)
  corrected=$(($(count published) - $(count "passed through")))
  echo "received $received, corrected $corrected"
  [ "$received" -eq 60 ] && [ "$corrected" -gt 50 ] || { echo "FAIL: expected 60 scans, > 50 corrected"; exit 1; }
  rosbag info "$scratch/neato.bag" >"$scratch/neato.txt"
  grep -q "/stable_scan_deskewed " "$scratch/neato.txt" || { echo "FAIL: no corrected scans in the bag"; exit 1; }

  echo "== (b) the nodelet from the package's nodelets.xml"
  rospack plugins --attrib=plugin nodelet >"$scratch/plugins.txt"
  grep -qx "lidar_deskew /usr/share/lidar_deskew/nodelets.xml" "$scratch/plugins.txt" ||
    { echo "FAIL: rospack does not see nodelets.xml"; exit 1; }
  port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("localhost", 0)); print(s.getsockname()[1])')
  export ROS_MASTER_URI=http://localhost:$port ROS_HOSTNAME=localhost
  pids=()
  trap 'for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done; wait' EXIT
  roscore -p "$port" >"$scratch/roscore.log" 2>&1 &
  pids+=($!)
  # roslaunch would start a master of its own if it came first
  for _ in $(seq 60); do
    if rosnode list >/dev/null 2>&1; then break; fi
    sleep 0.5
  done
  # the manager's start-up line goes to a file: flushed line by line (rosconsole, and roslaunch's own)
  ROSCONSOLE_STDOUT_LINE_BUFFERED=1 PYTHONUNBUFFERED=1 \
    roslaunch lidar_deskew deskew.launch scan:=/scan >"$scratch/roslaunch.log" 2>&1 &
  pids+=($!)
  started="/scan -> /scan_deskewed and /scan_deskewed_points"
  for _ in $(seq 60); do
    if grep -qs -e "$started" -e "process has died" "$scratch/roslaunch.log"; then break; fi
    sleep 0.5
  done
  rosnode list
  rostopic list | tee "$scratch/topics.txt"
  if ! grep "$started" "$scratch/roslaunch.log" || ! grep -qx /scan_deskewed "$scratch/topics.txt"; then
    cat "$scratch/roslaunch.log"
    echo "FAIL: the nodelet did not start from the package"
    exit 1
  fi

  echo "== (c) find_package(lidar_deskew) from a CMake project"
  mkdir -p "$scratch/downstream"
  cat >"$scratch/downstream/CMakeLists.txt" <<'CMAKE'
cmake_minimum_required(VERSION 3.16)
project(downstream LANGUAGES CXX)
set(CMAKE_CXX_STANDARD 17)
find_package(lidar_deskew REQUIRED)
add_executable(downstream main.cpp)
target_include_directories(downstream SYSTEM PRIVATE ${lidar_deskew_INCLUDE_DIRS})
target_link_libraries(downstream ${lidar_deskew_LIBRARIES})
CMAKE
  cat >"$scratch/downstream/main.cpp" <<'CPP'
#include <lidar_deskew/core/motion.h>
int main() {
  lidar_deskew::core::PoseSamples odom;
  odom.add(0, mrpt::poses::CPose2D(0, 0, 0));
  odom.add(lidar_deskew::core::secondsToNs(0.1), mrpt::poses::CPose2D(0.1, 0, 0.05));
  return odom.covers(lidar_deskew::core::secondsToNs(0.05)) ? 0 : 1;
}
CPP
  cmake -S "$scratch/downstream" -B "$scratch/downstream/build" >"$scratch/downstream.log" 2>&1 &&
    cmake --build "$scratch/downstream/build" >>"$scratch/downstream.log" 2>&1 &&
    "$scratch/downstream/build/downstream" ||
    { cat "$scratch/downstream.log"; echo "FAIL: downstream CMake project"; exit 1; }
  grep "lidar_deskew_DIR:" "$scratch/downstream/build/CMakeCache.txt"
  echo "debian package: ok"
  exit 0
fi

repo=${1:?repo}
deb=${2:-}
[ -n "$deb" ] || deb=$(bash "$repo/scripts/build_deb.sh" | tail -n 1)
echo "package: $deb"
if ! unshare --mount true 2>/dev/null; then
  echo "SKIPPED: needs a mount namespace (root) to lay the package over /usr"
  exit 77
fi
scratch=$(mktemp -d /tmp/lidar_deskew_deb.XXXXXX)
trap 'rm -rf "$scratch"' EXIT

# Control data: named and versioned as built, its Depends resolve on this machine.
field() { dpkg-deb -f "$deb" "$1"; }
version=$(sed -n 's:.*<version>\(.*\)</version>.*:\1:p' "$repo/package.xml" | head -n 1)-1
[ "$(field Package)" = ros-lidar-deskew ] && [ "$(field Version)" = "$version" ] &&
  [ "$(field Architecture)" = "$(dpkg --print-architecture)" ] || { echo "FAIL: control fields"; exit 1; }
depends=$(field Depends)
echo "Depends: $depends"
for dependency in libmrpt-poses2.5 libroscpp4d libnodeletlib1d rosbash python3-roslaunch libnodeletlib-tools; do
  grep -q "\b$dependency\b" <<<"$depends" || { echo "FAIL: Depends lacks $dependency"; exit 1; }
done
apt-get install -s "$deb" >"$scratch/apt.log" 2>&1 || { cat "$scratch/apt.log"; echo "FAIL: apt cannot install it"; exit 1; }
grep -E "^Inst ros-lidar-deskew|ros-lidar-deskew is already the newest" "$scratch/apt.log" ||
  { cat "$scratch/apt.log"; echo "FAIL: apt would not install it"; exit 1; }

# lintian: no error; every warning justified in docs/PACKAGING.md (its tag named there).
command -v lintian >/dev/null || { echo "FAIL: lintian is not installed (scripts/install_deps.sh)"; exit 1; }
lintian_options=()
[ "$(id -u)" -ne 0 ] || lintian_options=(--allow-root)
lintian "${lintian_options[@]}" --tag-display-limit 0 "$deb" >"$scratch/lintian.txt" 2>&1 || true
echo "lintian: $(grep -c '^E: ' "$scratch/lintian.txt") errors, $(grep -c '^W: ' "$scratch/lintian.txt") warnings"
grep -E '^[EW]: ' "$scratch/lintian.txt" || true
if grep -q '^E: ' "$scratch/lintian.txt"; then echo "FAIL: lintian reports errors"; exit 1; fi
if grep -qv -e '^[EWIPNXO]: ' "$scratch/lintian.txt"; then
  cat "$scratch/lintian.txt"
  echo "FAIL: lintian did not run"
  exit 1
fi
justified=$(cat "$repo/docs/PACKAGING.md")
for tag in $(sed -n 's/^W: [^ ]* \([^ ]*\).*/\1/p' "$scratch/lintian.txt" | sort -u); do
  grep -q "\b$tag\b" <<<"$justified" || { echo "FAIL: lintian warning $tag is not justified in docs/PACKAGING.md"; exit 1; }
done

# Debian's layout, and no catkin workspace files in /usr.
files=$(dpkg-deb -c "$deb" | awk '{print $6}')
echo "$(echo "$files" | wc -l) entries"
multiarch=$(dpkg-architecture -qDEB_HOST_MULTIARCH)
soversion=$(cut -d. -f1-2 <<<"$version")  # the libraries' SONAME version: MAJOR.MINOR
for path in usr/lib/lidar_deskew/deskew_node usr/lib/lidar_deskew/deskew_bag usr/lib/lidar_deskew/deskew_simulate \
  usr/lib/lidar_deskew/deskew_metrics usr/lib/lidar_deskew/deskew_core_demo usr/lib/lidar_deskew/deskew_calibrate \
  "usr/lib/$multiarch/liblidar_deskew_nodelets.so" "usr/lib/$multiarch/liblidar_deskew_core.so" \
  "usr/lib/$multiarch/cmake/lidar_deskew/lidar_deskewConfig.cmake" usr/include/lidar_deskew/core/deskew.h \
  usr/share/lidar_deskew/package.xml usr/share/lidar_deskew/nodelets.xml usr/share/lidar_deskew/launch/deskew.launch \
  usr/share/lidar_deskew/launch/deskew_node.launch usr/share/lidar_deskew/launch/core_demo.launch \
  usr/share/lidar_deskew/config/deskew.yaml usr/share/lidar_deskew/rviz/scan_deskew.rviz \
  usr/share/lidar_deskew/rviz/cloud_deskew.rviz usr/share/lidar_deskew/launch/demo_cloud.launch \
  "usr/lib/$multiarch/liblidar_deskew_core.so.$soversion" usr/lib/python3/dist-packages/lidar_deskew/cfg/DeskewScanConfig.py \
  usr/lib/python3/dist-packages/lidar_deskew/cfg/DeskewCloudConfig.py \
  usr/share/doc/ros-lidar-deskew/copyright usr/share/doc/ros-lidar-deskew/changelog.Debian.gz \
  usr/share/doc/ros-lidar-deskew/changelog.gz usr/share/doc/ros-lidar-deskew/README.md \
  usr/share/doc/ros-lidar-deskew/docs/PARAMETERS.md; do
  grep -qx "./$path" <<<"$files" || { echo "FAIL: the package lacks /$path"; exit 1; }
done
# Only what a downstream package needs: not the simulators', scoring's or calibration's headers
# (their code is linked into the executables), no Python bytecode.
if grep -E '^\./usr/include/lidar_deskew/(sim|eval)/|bag_calibrate\.h$|__pycache__|liblidar_deskew_(sim|eval|calibrate)' \
  <<<"$files"; then
  echo "FAIL: the package holds files that no downstream package needs"
  exit 1
fi
dpkg-deb -I "$deb" triggers | grep -qx "activate-noawait ldconfig" || { echo "FAIL: no ldconfig trigger"; exit 1; }
dpkg-deb -I "$deb" shlibs | grep -qx "liblidar_deskew_core $soversion ros-lidar-deskew (>= $version)" ||
  { echo "FAIL: no shlibs entry for liblidar_deskew_core"; exit 1; }
if grep -E '/(setup|local_setup)\.[a-z]+$|_setup_util\.py$|\.catkin$|/env\.sh$' <<<"$files"; then
  echo "FAIL: workspace setup files in the package"
  exit 1
fi

dpkg-deb -x "$deb" "$scratch/root"
mkdir -p "$scratch/home"
env -i HOME="$scratch/home" ROS_HOME="$scratch/ros" PATH=/usr/bin:/bin:/usr/sbin:/sbin LANG=C.UTF-8 \
  unshare --mount --propagation private --pid --fork --kill-child --mount-proc \
  bash "$repo/test/check_deb.sh" --inside "$scratch" "$repo"
