#!/usr/bin/env bash
# Real-time latency of the live deskew node (not a test: numbers for the issue notes). Starts its own
# roscore on a free port, the node, and bench/latency_driver for each sensor.
#   bash bench/latency.sh [SECONDS [NODE ARGUMENTS...]]   e.g. 30 _fit_look_ahead:=0.1
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-30}
shift || true
bash "$repo/scripts/build_workspace.sh" -DCATKIN_ENABLE_TESTING=ON >/dev/null
cd "$repo/.build/ws" && catkin_make latency_driver >/dev/null
set +u; source "$repo/.build/ws/devel/setup.bash"; set -u
port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://127.0.0.1:$port
roscore -p "$port" >/dev/null 2>&1 &
core=$!
trap 'kill $node $core 2>/dev/null || true; wait 2>/dev/null || true' EXIT
sleep 3
for sensor in UTM-30LX ILD26TRI; do
  "$repo/.build/ws/devel/lib/lidar_deskew/deskew_node" __name:=lidar_deskew "$@" >/dev/null 2>&1 &
  node=$!
  sleep 1
  "$repo/.build/ws/devel/lib/lidar_deskew/latency_driver" --seconds "$seconds" --sensor "$sensor"
  kill $node; wait $node 2>/dev/null || true
done
