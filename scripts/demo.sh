#!/usr/bin/env bash
# The demo: installs what is missing, builds with CMake directly (no workspace needed), then
#  1. finds the timing of a real recording (Neato XV-11, data/neato_xv11/test_drive.bag) with
#     deskew_calibrate, reprocesses it with deskew_bag and that timing, and measures how well
#     overlapping scans agree in the odom frame, raw vs corrected;
#  2. simulates a high-speed recording (ILD26TRI, 6 m/s and 5 rad/s, laser off-centre), reprocesses it
#     and scores raw, corrected and laser_geometry against the truth;
#  3. writes before/after figures (raw red, corrected green) to .build/demo/.
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$repo/scripts/install_deps.sh"
build="$repo/.build/cmake"
cmake -S "$repo" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCATKIN_ENABLE_TESTING=OFF >/dev/null
cmake --build "$build" --target deskew_bag deskew_calibrate deskew_simulate deskew_metrics -j"${LIDAR_DESKEW_JOBS:-2}" >/dev/null
bin=$(dirname "$(find "$build" -type f -name deskew_bag -perm -u+x | head -n 1)")
out="$repo/.build/demo"
mkdir -p "$out"

echo "== 1. A real recording: Neato XV-11 (5 Hz, 361 beams), odometry at 5-7 Hz, fast turns"
# Its /stable_scan's timing is found from the data (the ROS convention, stamp = first beam, makes the
# scans less consistent); its laser mount is on /tf and, differently, on /tf_static: the /tf one is
# used (as live) and the other is reported.
rm -f "$out/neato_timing.yaml"
status=0
"$bin/deskew_calibrate" "$repo/data/neato_xv11/test_drive.bag" --scan-topic /stable_scan \
  --output "$out/neato_timing.yaml" || status=$?
timing=(--params "$out/neato_timing.yaml")
if [ "$status" -eq 3 ]; then
  echo "(the recording cannot tell the timing: corrected with the message's own)"
  timing=()
elif [ "$status" -eq 4 ]; then
  echo "(the beam order and period told, the offset not: corrected with those and the message's offset)"
elif [ "$status" -ne 0 ]; then
  exit "$status"
fi
"$bin/deskew_bag" "$repo/data/neato_xv11/test_drive.bag" "$out/neato_deskewed.bag" --quiet \
  --scan-topic /stable_scan "${timing[@]}" --consistency-figure "$out/neato_turn.csv"

echo
echo "== 2. A simulated high-speed recording with truth: ILD26TRI 8 Hz, 6 m/s and 5 rad/s, noise on"
"$bin/deskew_simulate" --scenario ILD26TRI/high/arc --noise --bag "$out/sim_high.bag" --truth "$out/sim_high.truth"
"$bin/deskew_bag" "$out/sim_high.bag" "$out/sim_high_deskewed.bag" --quiet
"$bin/deskew_metrics" "$out/sim_high.bag" "$out/sim_high.truth" --figure-csv "$out/sim_high.csv" --figure-scan 4

/usr/bin/python3 -s "$repo/scripts/plot_demo.py" turn "$out/neato_turn.csv" "$out/neato_turn.png" \
  "Neato XV-11 while turning: overlapping scans agree better once corrected"
/usr/bin/python3 -s "$repo/scripts/plot_demo.py" scan "$out/sim_high.csv" "$out/sim_high.png" \
  "ILD26TRI at 6 m/s and 5 rad/s: raw red, corrected green, true walls black"
echo
echo "figures: $out/neato_turn.png $out/sim_high.png"
