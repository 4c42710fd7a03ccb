#!/usr/bin/env bash
# deskew_bag throughput on a simulated 1440-beam, 40 Hz recording, against a plain `rosbag filter` copy
# of the same bag.   bash bench/bag_speed.sh [SECONDS_OF_RECORDING]
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-120}
bash "$repo/scripts/build_workspace.sh" >/dev/null
bin="$repo/.build/ws/devel/lib/lidar_deskew"
work="$repo/.build/bag_speed"
mkdir -p "$work"
"$bin/deskew_simulate" --scenario UTM-30LX/normal/rotation --duration "$seconds" --bag "$work/in.bag" \
  --truth "$work/in.truth"
scans=$(( ${seconds%.*} * 40 ))
start=$(date +%s.%N)
taskset -c 0 "$bin/deskew_bag" "$work/in.bag" "$work/out.bag" --quiet >/dev/null
deskew=$(echo "$(date +%s.%N) - $start" | bc)
start=$(date +%s.%N)
rosbag filter "$work/in.bag" "$work/filtered.bag" "True" >/dev/null
filter=$(echo "$(date +%s.%N) - $start" | bc)
echo "recording: ${seconds} s, ${scans} scans of 1440 beams, $(du -h "$work/in.bag" | cut -f1)"
echo "deskew_bag (one core): ${deskew} s, $(echo "$scans / $deskew" | bc) scans/s"
echo "rosbag filter copy:    ${filter} s"
echo "deskew_bag / rosbag filter time: $(echo "scale=3; $deskew / $filter" | bc)"
