#!/usr/bin/env bash
# Regenerates docs/RESULTS_CLOUDS.md and results/cloud_*.tsv: the multi-line simulator's scenarios
# (VLP-16 and OS1-64 in the 3D hall, planar motions and rough ground) as bags (noise off and on), each
# cloud scored against the true surfaces: raw, constant velocity between two poses, ours, one tf lookup
# per point, and the noise floor (the same clouds corrected with the true trajectory) with ours /
# floor. Then the smooth drives (deskew_simulate --list-cloud-smooth: the twist changes between tf
# samples) at tf 10, 20 and 50 Hz, noise off, with interpolation linear and twist. The page leaves out
# the columns that every row of a table shares (layout, clouds, sigma); the TSVs hold them. Work files
# go to .build/cloud_experiments/.
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
mkdir -p "$work" "$repo/results"

row_header='| scenario | raw RMS / p95 / max | two poses, constant velocity | ours | one tf lookup per point | truth-corrected (noise floor) | ours / floor |
| --- | --- | --- | --- | --- | --- | ---: |'
# A deskew_metrics --cloud row without its layout, clouds and sigma columns; the same row as TSV.
short_row() { awk -F'|' '{ print "|" $2 "|" $6 "|" $7 "|" $8 "|" $9 "|" $10 "|" $11 "|" }'; }
row_tsv() { awk -F' *\\| *' '{ out = $2; for (i = 3; i < NF; i++) out = out "\t" $i; print out }'; }
clouds_tsv="$repo/results/cloud_experiments.tsv"
printf 'scenario\tlayout\tclouds\tsigma_mm\traw\ttwo_poses\tours\tone_tf_lookup_per_point\tnoise_floor\tours_over_floor\n' \
  > "$clouds_tsv"
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
    row=$("$bin/deskew_metrics" --cloud "$work/$slug-$noise.bag" "$work/$slug-$noise.truth" --markdown)
    echo "$row" | row_tsv >> "$clouds_tsv"
    rows+=$(echo "$row" | short_row)$'\n'
    rm -f "$work/$slug-$noise.bag" "$work/$slug-$noise.truth"
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
smooth_tsv="$repo/results/cloud_smooth.tsv"
printf 'scenario\ttf_hz\ttwo_poses\tours_linear\tours_twist\tone_tf_lookup_per_point\ttwist_one_query_per_point\n' \
  > "$smooth_tsv"
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
    printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$scenario" "$rate" "$(cell "$linear" 7)" "$(cell "$linear" 8)" "$(cell "$twist" 8)" \
      "$(cell "$linear" 9)" "$(cell "$twist" 9)" >> "$smooth_tsv"
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

Generated by \`bash scripts/cloud_experiments.sh\` (tf at ${tf_rate} Hz); do not edit by hand. Every
column: \`results/cloud_experiments.tsv\`, \`results/cloud_smooth.tsv\`. How clouds are corrected:
[CLOUDS.md](CLOUDS.md); the simulator: [TESTING.md](TESTING.md).

Each row is one recording of \`deskew_simulate --cloud-scenario\`: 10 sweeps at 10 Hz in a 40 × 10 m
hall 3 m high, every point ray-cast from the sensor's true pose at its column's firing time, the mount
tilted (roll 1°, pitch 2°), \`/tf\` odom → base_link at ${tf_rate} Hz from the true 3D pose. VLP16: 16
rings, 1800 columns, written as Velodyne's driver (\`time\` float32 s, stamped at the last packet);
OS1-64: 64 rings, 1024 columns, organized with zeros for no return, as Ouster's (\`t\` uint32 ns).
Normal: 1.5 m/s and 2 rad/s; high: 6 m/s and 5 rad/s; \`rough\`: z ±2 cm, pitch ±2°, roll ±1.5°
oscillating. Noise on: range σ 30 mm.

\`deskew_metrics --cloud\` scores every return's distance to the true surfaces, mm (RMS / p95 / max),
placed with the true pose at the reference time: **raw**; **two poses, constant velocity** (lerp +
slerp between tf's poses at the sweep's first and last return, as KISS-ICP-class pipelines do);
**ours** (\`CloudProcessor\`, the nodelet's and deskew_bag's path); **one tf lookup per point** (ours
with \`exact: true\`); **noise floor**: the same cloud moved with the TRUE trajectory (no tf, no MRPT),
the best any correction can do; **ours / floor** (noise on only). Each moving scenario is compared
with its own floor: where the robot is and how it is tilted decide the incidences, hence the floor.

$tables$summary

### Motion that changes between samples

\`deskew_simulate --list-cloud-smooth\`: speed and turn rate following cosines (periods 2 s and 1.3 s),
13 sweeps, noise off, tf at 10, 20 and 50 Hz, each bag scored with \`interpolation: linear\` (tf2's)
and \`twist\` (the default), RMS / max mm. **one tf lookup per point**: the linear run with \`exact:
true\`; **twist, one query per point**: the twist run with \`exact: true\`. At 10 Hz tf's samples fall
on the sweeps' ends, so linear is the two-pose correction there.

| scenario | tf Hz | two poses, constant velocity | ours, linear | ours, twist | one tf lookup per point | twist, one query per point |
| --- | ---: | --- | --- | --- | --- | --- |
$smooth_rows
$smooth_summary
MD
echo "wrote docs/RESULTS_CLOUDS.md and results/cloud_*.tsv"
