#!/usr/bin/env bash
# ctest rviz_neato: Debian's rviz under Xvfb, once per config of rviz/. The LaserScan configs
# (scan_deskew, scan_deskew_time) while the Neato bag plays through the live nodelet (rviz_neato.test:
# demo.launch and check_rviz.py); the cloud config (cloud_deskew) while a simulated VLP-16 bag (6 m/s
# arc, Velodyne's layout; made here with DESKEW_SIMULATE) plays through the live cloud nodelet
# (rviz_cloud.test: demo_cloud.launch and check_rviz.py). Fails when a display warns or errs, or when
# the screenshot lacks a display's colour.
# usage: rviz_neato.sh PROBE_PACKAGE_DIR OUT_DIR DESKEW_SIMULATE [CONFIG...]   (inside the workspace's env.sh)
# Screenshots and reports: OUT_DIR/CONFIG.png, OUT_DIR/CONFIG.png.txt.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
probe_dir=${1:?probe package dir}
out=${2:?output dir}
simulate=${3:?deskew_simulate}
shift 3
configs=("$@")
[ ${#configs[@]} -gt 0 ] || configs=(scan_deskew scan_deskew_time cloud_deskew)
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
rm -rf "$out"
mkdir -p "$out"

# A virtual screen of the configs' window size, on a display number Xvfb picks free.
Xvfb -displayfd 3 -screen 0 1280x800x24 -nolisten tcp 3>"$out/display" 2>"$out/xvfb.log" &
xvfb=$!
trap 'kill $xvfb 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -s "$out/display" ] && break; sleep 0.1; done
[ -s "$out/display" ] || { echo "Xvfb did not start:"; cat "$out/xvfb.log"; exit 1; }
export DISPLAY=:$(cat "$out/display")
# rviz finds the test-only status panel in the probe package.
export ROS_PACKAGE_PATH=$probe_dir:$ROS_PACKAGE_PATH

status=0
for config in "${configs[@]}"; do
  "$here/add_status_probe.py" "$here/../../rviz/$config.rviz" "$out/$config.rviz"
  start=$(date +%s)
  launch=(rviz_neato.test)
  if [[ $config == cloud_* ]]; then
    "$simulate" --cloud-scenario VLP16/high/arc --convention velodyne_first --bag "$out/vlp16.bag" \
      --truth "$out/vlp16.truth" >"$out/vlp16.log"
    launch=(rviz_cloud.test bag:="$out/vlp16.bag")
  fi
  # (not --text: with it, rostest exits 0 whatever the result)
  if rostest lidar_deskew "${launch[@]}" rviz_file:="$out/$config.rviz" screenshot:="$out/$config.png" \
       >"$out/$config.log" 2>&1 && [ "$(tail -1 "$out/$config.png.txt")" = PASS ]; then
    result=ok
  else
    result=FAILED status=1
  fi
  echo "== $config: $result in $(($(date +%s) - start)) s (log $out/$config.log)"
  cat "$out/$config.png.txt" 2>/dev/null || tail -40 "$out/$config.log"
done
exit $status
