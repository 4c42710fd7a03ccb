#!/usr/bin/env bash
# Builds the Debian package .build/ros-lidar-deskew_<version>_<arch>.deb (version from package.xml,
# arch from dpkg) for this machine's Debian, laid out like Debian's own ROS packages: built with CMake
# for prefix /usr in catkin's binary-package mode (no setup files), so libraries and the CMake config
# go to /usr/lib/<multiarch>/, executables to /usr/lib/lidar_deskew/, launch, config, rviz and
# nodelets.xml to /usr/share/lidar_deskew/, headers to /usr/include/lidar_deskew/.
# Depends: dpkg-shlibdeps of the libraries and executables, plus the ROS tools that rosrun, roslaunch
# and the nodelet need. Recommends: the -dev packages that find_package(lidar_deskew) needs, found
# with dpkg -S from the CMake configs of the installed config's dependencies.
# The build folder .build/deb/build/lidar_deskew is kept: later runs rebuild only what changed, and repackage
# only when the installed files, this script or package.xml changed.
# Usage: scripts/build_deb.sh    (prints the path of the .deb)
set -euo pipefail
export PATH=/usr/bin:/bin:/usr/sbin:/sbin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd -P) # one path whether called through a link or not
script="$repo/scripts/build_deb.sh"
jobs=${LIDAR_DESKEW_JOBS:-2}
package=ros-lidar-deskew
version=$(sed -n 's:.*<version>\(.*\)</version>.*:\1:p' "$repo/package.xml" | head -n 1)
arch=$(dpkg --print-architecture)
multiarch=$(dpkg-architecture -qDEB_HOST_MULTIARCH)
work="$repo/.build/deb"
# Laid out like the catkin workspace (.build/ws: src/lidar_deskew, build/lidar_deskew, devel) so that the
# compiler cache serves this build the workspace's objects (scripts/compiler_cache.sh).
build="$work/build/lidar_deskew"
# dpkg-shlibdeps recognises the package's own libraries when the files lie in debian/<package>/
stage="$work/pkg/debian/$package"
deb="$repo/.build/${package}_${version}_${arch}.deb"

mkdir -p "$work/src"
ln -sfn "$repo" "$work/src/lidar_deskew"
source "$repo/scripts/compiler_cache.sh"
if [ ! -f "$build/CMakeCache.txt" ] || [ "$script" -nt "$build/CMakeCache.txt" ] ||
  [ "$repo/scripts/compiler_cache.sh" -nt "$build/CMakeCache.txt" ]; then
  cmake -S "$work/src/lidar_deskew" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX=/usr \
    -DCATKIN_DEVEL_PREFIX="$work/devel" "${compiler_cache_args[@]}" \
    -DCATKIN_BUILD_BINARY_PACKAGE=ON -DCATKIN_ENABLE_TESTING=OFF -DCMAKE_DISABLE_FIND_PACKAGE_benchmark=ON \
    >"$work/configure.log" || { cat "$work/configure.log" >&2; exit 1; }
fi
cmake --build "$build" -j"$jobs" >/dev/null
rm -rf "$work/pkg"
DESTDIR="$stage" cmake --install "$build" --strip >/dev/null
install -D -m 644 "$repo/LICENSE" "$stage/usr/share/doc/$package/copyright"

# Unchanged files, script and manifest: the .deb is up to date.
stamp="$work/contents.md5"
contents=$( (cd "$stage" && find . -type f | LC_ALL=C sort | xargs md5sum; cat "$repo/package.xml" "$script") | md5sum)
if [ -f "$deb" ] && [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$contents" ]; then
  echo "$deb"
  exit 0
fi

# Shared-library dependencies of every ELF file (executables and libraries).
mkdir -p "$work/pkg/debian"
printf 'Source: %s\n\nPackage: %s\nArchitecture: any\n' "$package" "$package" >"$work/pkg/debian/control"
# (relative paths: our own libraries are then found in the package and need no dependency; their
# unversioned sonames give warnings, kept in shlibdeps.log)
cd "$work/pkg"
mapfile -t elf_files < <(find "debian/$package/usr/lib" -type f \( -name '*.so' -o -perm -u+x \))
shlibs=$(dpkg-shlibdeps -O "${elf_files[@]}" 2>"$work/shlibdeps.log" | sed -n 's/^shlibs:Depends=//p')
[ -n "$shlibs" ] || { cat "$work/shlibdeps.log" >&2; echo "build_deb: dpkg-shlibdeps found no dependencies" >&2; exit 1; }
# rosrun (launch files, README), roslaunch and roscore, the nodelet manager and loader
runtime="rosbash, python3-roslaunch, libnodeletlib-tools"

# The packages holding what the installed CMake config finds: catkin, its catkin dependencies, Eigen, MRPT.
owner() { dpkg-query -S "$1" | head -n 1 | cut -d: -f1; }
config="$stage/usr/lib/$multiarch/cmake/lidar_deskew/lidar_deskewConfig.cmake"
dev_packages=("$(owner /usr/share/catkin/cmake/catkinConfig.cmake)" "$(owner /usr/include/eigen3/Eigen/Core)")
for dependency in $(sed -n 's/^set(depends "\(.*\)")$/\1/p' "$config" | tr ';' ' ') mrpt-poses mrpt-ros1bridge; do
  found=""
  for candidate in "/usr/lib/$multiarch/cmake/$dependency/${dependency}Config.cmake" \
    "/usr/share/$dependency/cmake/${dependency}Config.cmake" \
    "/usr/lib/$multiarch/cmake/$dependency/${dependency}-config.cmake"; do
    if [ -f "$candidate" ]; then
      found=$(owner "$candidate")
      break
    fi
  done
  [ -n "$found" ] || { echo "build_deb: no installed CMake config for $dependency" >&2; exit 1; }
  dev_packages+=("$found")
done
recommends=$(printf '%s\n' "${dev_packages[@]}" | LC_ALL=C sort -u | paste -sd, | sed 's/,/, /g')

maintainer=$(sed -n 's:.*<maintainer email="\(.*\)">\(.*\)</maintainer>.*:\2 <\1>:p' "$repo/package.xml" | head -n 1)
# package.xml's description, folded to 78 columns, one leading space per line
description=$(sed -n '/<description>/,/<\/description>/p' "$repo/package.xml" | sed 's:</*description>::' |
  tr -s ' \n' ' ' | sed 's/^ *//; s/ *$//' | fold -s -w 78 | sed 's/^/ /; s/ *$//')
mkdir -p "$stage/DEBIAN"
cat >"$stage/DEBIAN/control" <<CONTROL
Package: $package
Version: $version
Architecture: $arch
Maintainer: $maintainer
Installed-Size: $(du -sk --exclude=DEBIAN "$stage" | cut -f1)
Depends: $shlibs, $runtime
Recommends: $recommends
Suggests: rviz
Section: science
Priority: optional
Description: ROS 1 deskewing of 2D LIDAR scans: nodelet, node and bag tools
$description
CONTROL
(cd "$stage" && find usr -type f | LC_ALL=C sort | xargs md5sum) >"$stage/DEBIAN/md5sums"
dpkg-deb --build --root-owner-group "$stage" "$deb" >/dev/null
echo "$contents" >"$stamp"
echo "$deb"
