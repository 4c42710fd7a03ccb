#!/usr/bin/env bash
# Builds the libFuzzer targets with CMake and clang (-DLIDAR_DESKEW_FUZZ=ON: ASan and UBSan) and runs
# each for a bounded time.
#   bash fuzz/run.sh [SECONDS_PER_TARGET]      (default 60)
#   LIDAR_DESKEW_FUZZ_TARGETS="clouds" bash fuzz/run.sh 600    (some targets only; default all three)
# Targets: fuzz_core (the ROS-free core), fuzz_messages (LaserScan bytes through ScanProcessor) and
# fuzz_clouds (PointCloud2s, as bytes or built field by field, through CloudProcessor).
# The tracked corpus in fuzz/corpus/ is read, never written: new inputs go to .build/fuzz/new/TARGET
# (merge them with `FUZZER -merge=1 fuzz/corpus/TARGET .build/fuzz/new/TARGET` to keep them).
# A finding leaves its input in .build/fuzz/ and makes the script exit non-zero.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-60}
out="$repo/.build/fuzz"
build="$out/build"
mkdir -p "$out"
cmake -S "$repo" -B "$build" -DCMAKE_CXX_COMPILER=clang++ -DLIDAR_DESKEW_FUZZ=ON -DCATKIN_ENABLE_TESTING=OFF \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo >"$out/configure.log" 2>&1 || { cat "$out/configure.log"; exit 1; }
cmake --build "$build" --target fuzz_core fuzz_messages fuzz_clouds -j"${LIDAR_DESKEW_JOBS:-2}" >"$out/build.log" 2>&1 ||
  { tail -50 "$out/build.log"; exit 1; }

status=0
for target in ${LIDAR_DESKEW_FUZZ_TARGETS:-core messages clouds}; do
  binary=$(find "$build" -type f -name "fuzz_$target" -perm -u+x | head -n 1)
  mkdir -p "$out/new/$target"
  echo "== fuzz_$target, ${seconds} s"
  # libFuzzer adds new inputs to the first corpus folder only.
  if ! "$binary" -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="$out/$target-" \
      "$out/new/$target" "$repo/fuzz/corpus/$target" > "$out/$target.log" 2>&1; then
    status=1
    grep -E "ERROR|SUMMARY|artifact" "$out/$target.log" || tail -20 "$out/$target.log"
  fi
  grep -E "stat::number_of_executed_units|^Done" "$out/$target.log" || true
done
exit $status
