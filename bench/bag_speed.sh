#!/usr/bin/env bash
# deskew_bag throughput against a plain `rosbag filter` copy of the same bag, the two run in turn
# (deskew_bag pinned to one core), median of RUNS each.
#   bash bench/bag_speed.sh [SECONDS_OF_RECORDING] [--cloud] [--runs N]
# Default: a simulated 1440-beam, 40 Hz LaserScan recording (UTM-30LX, rotating). --cloud: a VLP-16
# recording (10 Hz, ~29,000 points a sweep, Velodyne's layout: `time` float32 s, stamped at the last
# packet) on a 6 m/s arc, corrected with `deskew_bag IN OUT --cloud-topic /points` and nothing else.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=120
cloud=false
runs=3
while [ $# -gt 0 ]; do
  case "$1" in
    --cloud) cloud=true ;;
    --runs) runs=${2:?}; shift ;;
    *) seconds=$1 ;;
  esac
  shift
done
bash "$repo/scripts/build_workspace.sh" >/dev/null
bin="$repo/.build/ws/devel/lib/lidar_deskew"
work="$repo/.build/bag_speed"
mkdir -p "$work"
if $cloud; then
  "$bin/deskew_simulate" --cloud-scenario VLP16/high/arc --convention velodyne_last --duration "$seconds" \
    --bag "$work/in.bag" --truth "$work/in.truth" >/dev/null
  messages="$(( ${seconds%.*} * 10 )) VLP-16 sweeps"
  deskew_args=(--cloud-topic /points)
  per=sweeps
else
  "$bin/deskew_simulate" --scenario UTM-30LX/normal/rotation --duration "$seconds" --bag "$work/in.bag" \
    --truth "$work/in.truth" >/dev/null
  messages="$(( ${seconds%.*} * 40 )) scans of 1440 beams"
  deskew_args=()
  per=scans
fi
count=${messages%% *}

elapsed() {  # wall seconds of a command, its output dropped
  local start
  start=$(date +%s.%N)
  "$@" >/dev/null
  echo "$(date +%s.%N) - $start" | bc
}
median() { sort -g | awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }

deskew_times=()
filter_times=()
for ((i = 0; i < runs; ++i)); do
  rm -f "$work/out.bag" "$work/filtered.bag"
  deskew_times+=("$(elapsed taskset -c 0 "$bin/deskew_bag" "$work/in.bag" "$work/out.bag" "${deskew_args[@]}" --quiet)")
  filter_times+=("$(elapsed rosbag filter "$work/in.bag" "$work/filtered.bag" "True")")
done
deskew=$(printf '%s\n' "${deskew_times[@]}" | median)
filter=$(printf '%s\n' "${filter_times[@]}" | median)
echo "recording: ${seconds} s, ${messages}, $(du -h "$work/in.bag" | cut -f1); output $(du -h "$work/out.bag" | cut -f1)"
echo "deskew_bag (one core), median of ${runs}: ${deskew} s, $(echo "$count / $deskew" | bc) ${per}/s  [${deskew_times[*]}]"
echo "rosbag filter copy, median of ${runs}:    ${filter} s  [${filter_times[*]}]"
echo "deskew_bag / rosbag filter time: $(echo "scale=3; $deskew / $filter" | bc)"
