#!/usr/bin/env bash
# The install tree (after catkin_make install) holds what users need: libraries, headers, executables,
# nodelets.xml, launch files, rviz configs, the demo's bag and the package manifest; and not what only
# the executables need (the simulators', scoring's and calibration's libraries and headers).
set -euo pipefail
prefix=${1:?install prefix}
status=0
for path in \
  lib/liblidar_deskew_core.so \
  lib/liblidar_deskew_ros.so \
  lib/liblidar_deskew_node.so \
  lib/liblidar_deskew_bag.so \
  lib/lidar_deskew/deskew_core_demo \
  lib/lidar_deskew/deskew_simulate \
  lib/lidar_deskew/deskew_metrics \
  lib/lidar_deskew/deskew_calibrate \
  include/lidar_deskew/core/deskew.h \
  include/lidar_deskew/core/rebin.h \
  include/lidar_deskew/ros/tf_motion.h \
  include/lidar_deskew/ros/scan_pipeline.h \
  include/lidar_deskew/node/laser_scan_deskew_node.h \
  include/lidar_deskew/node/config_params.h \
  include/lidar_deskew/DeskewScanConfig.h \
  include/lidar_deskew/DeskewCloudConfig.h \
  include/lidar_deskew/bag/bag_deskew.h \
  share/lidar_deskew/package.xml \
  share/lidar_deskew/nodelets.xml \
  share/lidar_deskew/launch/core_demo.launch \
  share/lidar_deskew/launch/deskew.launch \
  share/lidar_deskew/launch/demo.launch \
  share/lidar_deskew/config/deskew.yaml \
  share/lidar_deskew/rviz/scan_deskew.rviz \
  share/lidar_deskew/rviz/scan_deskew_time.rviz \
  share/lidar_deskew/rviz/cloud_deskew.rviz \
  share/lidar_deskew/launch/demo_cloud.launch \
  share/lidar_deskew/data/neato_xv11/test_drive.bag \
  share/lidar_deskew/data/neato_xv11/NOTICE \
  lib/liblidar_deskew_nodelets.so \
  lib/lidar_deskew/deskew_node \
  lib/lidar_deskew/deskew_cloud_node \
  share/lidar_deskew/launch/deskew_cloud.launch \
  lib/lidar_deskew/deskew_bag \
  share/lidar_deskew/cmake/lidar_deskewConfig.cmake; do
  if [ -e "$prefix/$path" ]; then echo "ok      $path"; else echo "MISSING $path"; status=1; fi
done
for path in include/lidar_deskew/sim include/lidar_deskew/eval include/lidar_deskew/bag/bag_calibrate.h \
  lib/liblidar_deskew_sim.so lib/liblidar_deskew_sim_bag.so lib/liblidar_deskew_eval.so \
  lib/liblidar_deskew_calibrate.so; do
  if [ -e "$prefix/$path" ]; then echo "NEEDLESS $path"; status=1; fi
done
# the installed demo runs from the install tree
if [ $status -eq 0 ]; then
  # as a user would: source the install space, then run from it
  (set +u; source "$prefix/setup.bash"; "$prefix/lib/lidar_deskew/deskew_core_demo" | grep -q "UTM-30LX") ||
    { echo "installed demo did not run"; status=1; }
  (set +u; source "$prefix/setup.bash"; "$prefix/lib/lidar_deskew/deskew_simulate" --list | grep -q "ILD26TRI/high/arc") ||
    { echo "installed deskew_simulate did not run"; status=1; }
  (set +u; source "$prefix/setup.bash"; "$prefix/lib/lidar_deskew/deskew_bag" --help | grep -q "usage:") ||
    { echo "installed deskew_bag did not run"; status=1; }
fi
exit $status
