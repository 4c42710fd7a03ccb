#!/usr/bin/env bash
# Regenerates docs/RESULTS_CLOUDS.md: the multi-line simulator's scenarios (VLP-16 and OS1-64 in the 3D
# hall, planar motions and rough ground) as bags (noise off and on), each cloud scored against the true
# surfaces: raw, constant velocity between two poses, ours, one tf lookup per point, and the noise floor
# (the same clouds corrected with the true trajectory) with ours / floor. Then the smooth drives
# (deskew_simulate --list-cloud-smooth: the twist changes between tf samples) at tf 10, 20 and 50 Hz,
# noise off, with interpolation linear and twist. Work files go to .build/cloud_experiments/.
#   bash scripts/cloud_experiments.sh [--tf-rate HZ]   (the rate of the first tables)
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
tf_rate=50
if [ "${1:-}" = "--tf-rate" ]; then tf_rate=${2:?}; fi

bash "$repo/scripts/install_deps.sh" >/dev/null
bash "$repo/scripts/build_workspace.sh" >/dev/null
bin="$repo/.build/ws/devel/lib/lidar_deskew"
work="$repo/.build/cloud_experiments"
rm -rf "$work"
mkdir -p "$work"

row_header='| scenario | layout | clouds | σ mm | raw RMS / p95 / max | two poses, constant velocity | ours | one tf lookup per point | truth-corrected (noise floor) | ours / floor |
| --- | --- | ---: | ---: | --- | --- | --- | --- | --- | ---: |'
tables=""
for noise in off on; do
  rows=""
  flag=""
  [ "$noise" = on ] && flag="--noise"
  while read -r scenario; do
    slug=$(echo "$scenario" | tr '/' '_')
    # Ouster's organized layout for the OS1-64, Velodyne's (stamped at the last packet) for the VLP-16
    convention=velodyne_last
    case "$scenario" in OS1-64/*) convention=ouster ;; esac
    "$bin/deskew_simulate" --cloud-scenario "$scenario" --convention "$convention" --tf-rate "$tf_rate" \
      --bag "$work/$slug-$noise.bag" --truth "$work/$slug-$noise.truth" $flag >/dev/null
    rows+=$("$bin/deskew_metrics" --cloud "$work/$slug-$noise.bag" "$work/$slug-$noise.truth" --markdown)$'\n'
  done < <("$bin/deskew_simulate" --list-clouds)
  tables+="### Noise $noise"$'\n\n'"$row_header"$'\n'"$rows"$'\n'
  [ "$noise" = on ] && noisy_rows=$rows
done
# Motion that changes between samples: the smooth drives at tf 10, 20 and 50 Hz, noise off, each bag
# scored with interpolation linear and twist (RMS / max of one run's columns: 7 two poses, 8 ours,
# 9 exact: true, one query per point).
printf 'interpolation: linear\n' > "$work/linear.yaml"
printf 'interpolation: twist\n' > "$work/twist.yaml"
cell() { echo "$1" | awk -F'|' -v c="$2" '{split($c, v, " / "); gsub(/ /, "", v[1]); gsub(/ /, "", v[3]); print v[1] " / " v[3]}'; }
smooth_rows=""
while read -r scenario; do
  slug=$(echo "$scenario" | tr '/' '_')
  convention=velodyne_last
  case "$scenario" in OS1-64/*) convention=ouster ;; esac
  for rate in 10 20 50; do
    bag="$work/smooth-$slug-$rate.bag" truth="$work/smooth-$slug-$rate.truth"
    "$bin/deskew_simulate" --cloud-scenario "$scenario" --convention "$convention" --tf-rate "$rate" \
      --bag "$bag" --truth "$truth" >/dev/null
    linear=$("$bin/deskew_metrics" --cloud "$bag" "$truth" --markdown --params "$work/linear.yaml")
    twist=$("$bin/deskew_metrics" --cloud "$bag" "$truth" --markdown --params "$work/twist.yaml")
    smooth_rows+="| $scenario | $rate | $(cell "$linear" 7) | $(cell "$linear" 8) | **$(cell "$twist" 8)** | $(cell "$linear" 9) | $(cell "$twist" 9) |"$'\n'
    rm -f "$bag" "$truth"
  done
done < <("$bin/deskew_simulate" --list-cloud-smooth)
# Twist's RMS over linear's per row: the range, and the rows where twist's RMS is the larger.
smooth_summary=$(echo "$smooth_rows" | awk -F'|' 'NF > 2 {
    split($5, l, " / "); split($6, t, " / "); gsub(/[* ]/, "", t[1]); ratio = t[1] / l[1]
    scenario = $2; rate = $3; gsub(/ /, "", scenario); gsub(/ /, "", rate)
    if (n++ == 0 || ratio < low) low = ratio; if (ratio > high) high = ratio
    if (ratio > 1) worse = worse (worse == "" ? "" : ", ") sprintf("%s at %s Hz (%.3f)", scenario, rate, ratio)
  } END {
    printf "Ours: twist RMS / linear RMS from %.3f to %.3f; twist the larger in: %s.", low, high, worse == "" ? "none" : worse
  }')

# Noise on: the worst ours / floor (the last column) and its scenario; the floors' range beside the
# standing robots' RMS.
summary=$(echo "$noisy_rows" | awk -F'|' 'NF > 2 {
    ratio = $(NF - 1) + 0; floor = $(NF - 2) + 0; scenario = $2; gsub(/ /, "", scenario)
    if (ratio > worst) { worst = ratio; at = scenario }
    if (scenario ~ /static/) { standing = standing (standing == "" ? "" : " and ") sprintf("%.2f", floor) }
    else { if (low == "" || floor < low) low = floor; if (floor > high) high = floor }
  } END {
    printf "With noise on, ours / floor is at most %.3f (%s).\nThe moving scenarios'"'"' floors are %.2f-%.2f mm RMS,", worst, at, low, high
    printf " the standing robots'"'"' %s mm.", standing
  }')

cat > "$repo/docs/RESULTS_CLOUDS.md" <<MD
# Multi-line LIDARs: the 3D simulation as numbers

Generated by \`bash scripts/cloud_experiments.sh\` (tf at ${tf_rate} Hz); do not edit by hand.

Each row is one recording of \`deskew_simulate --cloud-scenario\`: a spinning multi-line LIDAR in a
40 × 10 m hall 3 m high (walls, floor, ceiling, pillars), 10 sweeps at 10 Hz, every point ray-cast
from the sensor's true pose at its column's firing time. VLP-16: 16 rings ±15°, 1800 columns, dense,
written as Velodyne's driver writes it (\`time\` float32 s, stamped at the last packet); OS1-64: 64
rings ±16.6°, 1024 columns, organized with zeros for no return, as Ouster's (\`t\` uint32 ns). The mount
is tilted (roll 1°, pitch 2°); the bag holds \`/points\`, \`/tf\` odom → base_link at ${tf_rate} Hz (the
true 3D pose) and \`/tf_static\`. \`rough\` adds z ±2 cm, pitch ±2° and roll ±1.5° oscillating at 3, 2.3
and 1.7 Hz. Speeds as the planar suite: normal 1.5 m/s and 2 rad/s, high 6 m/s and 5 rad/s.

\`deskew_metrics --cloud\` reads every \`/tf\` into one tf2 buffer and scores every return of every cloud:
its distance to the true surfaces in mm (RMS / p95 / max), placed with the sensor's true pose at the
reference time (the first return's time, read from the data):

- **raw**: as measured;
- **two poses, constant velocity**: each point moved by the motion interpolated (lerp + slerp) between
  tf's poses at the sweep's first and last return, what KISS-ICP-class pipelines do;
- **ours**: \`CloudProcessor\`, knots every 5 ms plus tf's own sample times (the live nodelet's and
  deskew_bag's path);
- **one tf lookup per point**: the same with \`exact: true\`;
- **truth-corrected (noise floor)**: every return of the same recorded cloud moved to the reference
  time with the TRUE trajectory (the simulator's pose at the point's own time, relative to the one at
  the reference time; no tf, no MRPT), scored the same way: what is left is the range noise alone, the
  best any correction can do on this recording;
- **ours / floor**: our RMS over the floor's (noise on only: with noise off the floor is float32
  rounding, 0.00 mm).

Noise off leaves each method's own error: tf is linear between its samples, and we follow tf. With
noise on, range noise σ = 30 mm moves points along their beams. The floor then depends on the
scenario, not only on σ: a point's distance to the surface it hit is about its noise times the
cosine of the incidence, and where the robot is, and how it is tilted, decides the incidences. So
each moving scenario is compared with its own floor, not with the standing robot's RMS. What ours
adds to the floor is about its own error of the noise-off table, in quadrature.

$tables$summary

### Motion that changes between samples

The smooth drives (\`deskew_simulate --list-cloud-smooth\`), as the planar ones of
[RESULTS.md](RESULTS.md): the speed follows a cosine of period 2 s from its peak through zero into
reverse, the turn rate one of period 1.3 s (normal: 1.5 m/s and 2 rad/s; high: 6 m/s and 5 rad/s,
the sensor off the rotation centre; rough: the normal drive on the rough ground above), so the twist
changes at every instant, between tf's samples too. From (-10, -1.5), 13 sweeps (1.3 s: one period of
the turn rate), noise off, tf at 10, 20 and 50 Hz. Each bag scored twice by \`deskew_metrics --cloud
--params\`, with \`interpolation: linear\` (tf2's line between samples) and \`interpolation: twist\` (the
default); RMS / max in mm against the true surfaces. **one tf lookup per point** is the linear run with
\`exact: true\` (a tf2 lookup per point); **twist, one query per point** the twist run with \`exact:
true\` (the fitted motion asked at every point instead of at knots). At 10 Hz tf's samples fall on the
sweeps' ends, so linear is the two-pose correction there.

| scenario | tf Hz | two poses, constant velocity | ours, linear | ours, twist | one tf lookup per point | twist, one query per point |
| --- | ---: | --- | --- | --- | --- | --- |
$smooth_rows
$smooth_summary
MD
echo "wrote docs/RESULTS_CLOUDS.md"
