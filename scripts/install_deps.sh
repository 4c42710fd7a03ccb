#!/usr/bin/env bash
# Installs the Debian bookworm packages lidar_deskew needs to build, test and run its demo.
# Idempotent: does nothing when every package is present. Works as root or through sudo.
set -euo pipefail
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH

PACKAGES=(
  # toolchain and test tools
  cmake g++ make git libgtest-dev libbenchmark-dev bc
  ccache  # shared by the workspace's and the Debian package's builds (scripts/compiler_cache.sh)
  lld  # the linker of the build scripts (scripts/compiler_cache.sh)
  # the Debian package: dpkg-shlibdeps, dpkg-architecture; its check (debian_package test)
  dpkg-dev lintian
  # fuzzing: clang with libFuzzer, ASan and UBSan
  clang libclang-rt-14-dev
  # ROS 1 from Debian: catkin, roscpp, nodelet, tf2, messages, rostest, rosbag
  catkin ros-core-dev libroscpp-dev libnodeletlib-dev pluginlib-dev libtf2-dev libtf2-ros-dev
  libsensor-msgs-dev libnav-msgs-dev libgeometry-msgs-dev libtf2-msgs-dev librostest-dev librosbag-dev
  python3-rosbag python3-rostest python3-roslaunch libnodeletlib-tools rosbash python3-rosnode python3-rostopic
  libdiagnostic-updater-dev python3-diagnostic-msgs  # the latter: rostopic echo /diagnostics
  libdynamic-reconfigure-config-init-mutex-dev python3-dynamic-reconfigure  # cfg/Deskew*.cfg, dynparam
  # geometry: Eigen, MRPT 2.5 poses and its ROS 1 bridge, PCL with pcl_ros, laser_geometry (reference)
  libeigen3-dev libmrpt-poses-dev libmrpt-ros1bridge-dev libpcl-ros-dev liblaser-geometry-dev
  # Python tools (figures, metrics): Debian's, never pip
  python3-numpy python3-matplotlib python3-yaml
  # rviz (demo.launch) and its test (rviz_neato): rviz and its headers (the test's status panel), a
  # virtual X screen with Mesa's software OpenGL, ImageMagick for the screenshot
  rviz librviz-dev xvfb libgl1-mesa-dri imagemagick
)

missing=()
for pkg in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q '^install ok installed$'; then
    missing+=("$pkg")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install_deps: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO="sudo"
fi
echo "install_deps: installing ${missing[*]}"
$SUDO apt-get update -q
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
