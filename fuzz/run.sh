#!/usr/bin/env bash
# Builds the libFuzzer targets with clang under ASan and UBSan and runs each for a bounded time.
#   bash fuzz/run.sh [SECONDS_PER_TARGET]      (default 60; the corpus in fuzz/corpus/ grows)
# Targets: fuzz_core (the ROS-free core) and fuzz_messages (LaserScan bytes through ScanProcessor).
# A finding leaves its input in .build/fuzz/ and makes the script exit non-zero.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-60}
out="$repo/.build/fuzz"
mkdir -p "$out"
flags=(-std=c++17 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -I"$repo/include" -I/usr/include/eigen3)
for module in poses math core typemeta serialization rtti containers system random config io bayes; do
  flags+=(-I/usr/include/mrpt/$module/include)
done
clang++ "${flags[@]}" "$repo/fuzz/fuzz_core.cpp" "$repo"/src/core/*.cpp -o "$out/fuzz_core" \
  -lmrpt-poses -lmrpt-math -lmrpt-serialization -lmrpt-rtti -lmrpt-core -lmrpt-system -lmrpt-containers
ros=(-I/usr/include/pcl-1.13 -I/usr/include/mrpt/ros1bridge/include)
clang++ "${flags[@]}" "${ros[@]}" "$repo/fuzz/fuzz_messages.cpp" "$repo"/src/core/*.cpp "$repo/src/ros/conversions.cpp" \
  "$repo/src/ros/scan_processor.cpp" "$repo/src/ros/params.cpp" -o "$out/fuzz_messages" \
  -lmrpt-ros1bridge -lmrpt-poses -lmrpt-math -lmrpt-serialization -lmrpt-rtti -lmrpt-core -lmrpt-system \
  -lmrpt-containers -lroscpp -lroscpp_serialization -lrostime -lcpp_common -lboost_system

status=0
for target in core messages; do
  mkdir -p "$repo/fuzz/corpus/$target"
  echo "== fuzz_$target, ${seconds} s"
  if ! "$out/fuzz_$target" -max_total_time="$seconds" -print_final_stats=1 -artifact_prefix="$out/$target-" \
      "$repo/fuzz/corpus/$target" > "$out/$target.log" 2>&1; then
    status=1
    grep -E "ERROR|SUMMARY|artifact" "$out/$target.log" || tail -20 "$out/$target.log"
  fi
  grep -E "stat::number_of_executed_units|^Done" "$out/$target.log" || true
done
exit $status
