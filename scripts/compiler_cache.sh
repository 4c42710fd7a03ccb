# Sourced by the build scripts: compiles through ccache, with one cache in .build/ccache shared by the
# catkin workspace (scripts/build_workspace.sh), the Debian package (scripts/build_deb.sh) and the plain
# CMake check (test/check_plain_cmake.sh). All are Release builds of the same sources with the same flags,
# laid out alike under .build/ (source through <dir>/src/lidar_deskew, objects in <dir>/build/lidar_deskew,
# devel space <dir>/devel): ccache makes paths relative to the repo (after resolving links), so the later
# builds find the workspace's objects (it checks the source, every header and the flags; a hit is the
# object the compiler made for the same input).
# Needs $repo (the repo's physical path). Sets compiler_cache_args (CMake arguments: the compiler launcher,
# cleared without ccache; the linker).
# LIDAR_DESKEW_CCACHE=0 turns it off.
compiler_cache_args=()
if [ "${LIDAR_DESKEW_CCACHE:-1}" != 0 ] && command -v ccache >/dev/null; then
  export CCACHE_DIR=${CCACHE_DIR:-$repo/.build/ccache}
  export CCACHE_BASEDIR=$repo
  export CCACHE_NOHASHDIR=1
  # Depend mode: on a miss, the compiler's own -MD list of headers keys the result (direct mode) instead
  # of a second preprocessor run; a fifth less CPU per compile on a fresh machine, and the later builds
  # still hit directly.
  export CCACHE_DEPEND=1
  # The core tests' precompiled headers (test/CMakeLists.txt) are cached, and the sources that use them
  # hit, only with these: the header is made just before its users, and ccache cannot see macros or
  # __TIME__ through it (none of our sources uses __TIME__ or __DATE__).
  export CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime
  export CCACHE_MAXSIZE=${CCACHE_MAXSIZE:-2G}
  compiler_cache_args=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
else
  compiler_cache_args=(-DCMAKE_CXX_COMPILER_LAUNCHER= -DCMAKE_C_COMPILER_LAUNCHER=)  # clears a cached one
fi
# LLVM's linker where installed (scripts/install_deps.sh installs it): a third of GNU ld's CPU per link,
# and the suite links some 70 libraries and executables on a fresh machine.
if command -v ld.lld >/dev/null; then
  compiler_cache_args+=(-DCMAKE_EXE_LINKER_FLAGS=-fuse-ld=lld -DCMAKE_SHARED_LINKER_FLAGS=-fuse-ld=lld
    -DCMAKE_MODULE_LINKER_FLAGS=-fuse-ld=lld)
fi
