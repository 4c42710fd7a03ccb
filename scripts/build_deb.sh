#!/usr/bin/env bash
# Builds the Debian package .build/ros-lidar-deskew_<version>-1_<arch>.deb (upstream version from
# package.xml, Debian revision 1, arch from dpkg) for this machine's Debian, laid out like Debian's own
# ROS packages: built with CMake for prefix /usr in catkin's binary-package mode (no setup files), so
# the versioned libraries (SONAME .so.MAJOR.MINOR) and the CMake config go to /usr/lib/<multiarch>/,
# executables to /usr/lib/lidar_deskew/, launch, config, rviz and nodelets.xml to
# /usr/share/lidar_deskew/, headers to /usr/include/lidar_deskew/, the dynamic_reconfigure module to
# /usr/lib/python3/dist-packages/ (without bytecode), README.md and docs/ to /usr/share/doc/<package>/
# with the Debian changelog (changelog.Debian.gz), the project's CHANGELOG.rst (changelog.gz) and
# LICENSE (copyright). The control data has an ldconfig trigger and a shlibs file.
# Depends: dpkg-shlibdeps of the libraries and executables, plus the ROS tools that rosrun, roslaunch
# and the nodelet need, and python3 with dynamic_reconfigure for the Python module. Recommends: the
# -dev packages that find_package(lidar_deskew) needs, found with dpkg -S from the CMake configs of the
# installed config's dependencies. What lintian still says, and why: README.md, "Install as a Debian
# package" (test/check_deb.sh runs lintian).
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
upstream_version=$(sed -n 's:.*<version>\(.*\)</version>.*:\1:p' "$repo/package.xml" | head -n 1)
version=$upstream_version-1
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
    -DCATKIN_DEVEL_PREFIX="$work/devel" "${compiler_cache_args[@]}" -DLIDAR_DESKEW_WERROR=ON \
    -DCATKIN_BUILD_BINARY_PACKAGE=ON -DCATKIN_ENABLE_TESTING=OFF -DCMAKE_DISABLE_FIND_PACKAGE_benchmark=ON \
    >"$work/configure.log" || { cat "$work/configure.log" >&2; exit 1; }
fi
# A cold build takes minutes: say where it is (stderr; stdout carries only the .deb's path).
echo "build_deb.sh: building in $build (log: $work/build.log)" >&2
cmake --build "$build" -j"$jobs" 2>&1 | tee "$work/build.log" |
  awk '/^\[ *[0-9]+%\]/ { p = substr($0, 2, index($0, "%") - 2) + 0; if (p >= shown + 10) { shown = p;
       printf "build_deb.sh: %d%% built\n", p > "/dev/stderr" } }' ||
  { tail -n 40 "$work/build.log" >&2; exit 1; }
echo "build_deb.sh: packaging" >&2
rm -rf "$work/pkg"
DESTDIR="$stage" cmake --install "$build" --strip >/dev/null
# Python's bytecode is the machine's own business (it is written on first import, or by py3compile)
find "$stage" -name __pycache__ -type d -prune -exec rm -rf {} +
maintainer=$(sed -n 's:.*<maintainer email="\(.*\)">\(.*\)</maintainer>.*:\2 <\1>:p' "$repo/package.xml" | head -n 1)

# Documentation: README.md and docs/ as in the repo (the README's links stay valid), the licence, the
# project's changelog and a Debian changelog for this packaging, dated by the last commit of
# package.xml or CHANGELOG.rst (the same sources give the same package).
doc="$stage/usr/share/doc/$package"
install -D -m 644 "$repo/LICENSE" "$doc/copyright"
install -m 644 "$repo/README.md" "$doc/README.md"
(cd "$repo" && find docs -type f \( -name '*.md' -o -name '*.png' \) -exec install -D -m 644 {} "$doc/{}" \;)
gzip -9n <"$repo/CHANGELOG.rst" >"$doc/changelog.gz"
changelog_date=$(git -C "$repo" log -1 --format=%aD -- package.xml CHANGELOG.rst 2>/dev/null || true)
[ -n "$changelog_date" ] || changelog_date=$(date -R -r "$repo/package.xml")
cat <<CHANGELOG | gzip -9n >"$doc/changelog.Debian.gz"
$package ($version) unstable; urgency=medium

  * lidar_deskew $upstream_version, packaged by scripts/build_deb.sh. The changes
    of the software are in changelog.gz (the project's CHANGELOG.rst).

 -- $maintainer  $changelog_date
CHANGELOG

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
# (relative paths: our own libraries are then found in the package and need no dependency)
cd "$work/pkg"
mapfile -t elf_files < <(find "debian/$package/usr/lib" -type f \( -name '*.so.*' -o -perm -u+x \))
shlibs=$(dpkg-shlibdeps -O "${elf_files[@]}" 2>"$work/shlibdeps.log" | sed -n 's/^shlibs:Depends=//p')
[ -n "$shlibs" ] || { cat "$work/shlibdeps.log" >&2; echo "build_deb: dpkg-shlibdeps found no dependencies" >&2; exit 1; }
# rosrun (launch files, README), roslaunch and roscore, the nodelet manager and loader; the
# dynamic_reconfigure module lidar_deskew.cfg (Python 3, imports dynamic_reconfigure)
runtime="rosbash, python3-roslaunch, libnodeletlib-tools, python3:any, python3-dynamic-reconfigure"

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
Description: ROS 1 deskewing of 2D LIDAR scans and multi-line clouds
$description
CONTROL
# The libraries in ld.so's path: ldconfig runs after installation and removal (trigger), and packages
# built against them depend on this version or later (shlibs: name, SONAME version, dependency).
echo "activate-noawait ldconfig" >"$stage/DEBIAN/triggers"
for library in "$stage/usr/lib/$multiarch"/lib*.so.*.*.*; do
  soname=$(objdump -p "$library" | sed -n 's/^ *SONAME *//p')
  echo "${soname%%.so.*} ${soname#*.so.} $package (>= $version)"
done | LC_ALL=C sort >"$stage/DEBIAN/shlibs"
chmod 644 "$stage/DEBIAN/triggers" "$stage/DEBIAN/shlibs"
(cd "$stage" && find usr -type f | LC_ALL=C sort | xargs md5sum) >"$stage/DEBIAN/md5sums"
rm -f "$repo/.build/${package}_"*"_$arch.deb"  # an earlier version's
dpkg-deb --build --root-owner-group "$stage" "$deb" >/dev/null
echo "$contents" >"$stamp"
echo "$deb"
