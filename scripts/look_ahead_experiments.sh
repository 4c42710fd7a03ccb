#!/usr/bin/env bash
# The twist fit's look-ahead (fit_look_ahead) on noisy odometry: the noisy-odometry rows of
# docs/RESULTS.md's suite (10 % per 20 ms step, range noise on, seeds 1-5, tf at 50 Hz) scored with
# interpolation linear (tf's line), twist with look-ahead 0, 0.2, 0.5 and 1 s, laser_geometry and the
# floor (perfect odometry). Prints a TSV of cloud RMS [mm] per seed and the mean per scenario.
#   bash scripts/look_ahead_experiments.sh [SCENARIO...]
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bin="$repo/.build/ws/devel/lib/lidar_deskew"
work="$repo/.build/look_ahead"
mkdir -p "$work"
scenarios=("$@")
[ ${#scenarios[@]} -gt 0 ] || scenarios=(LDS-01/normal/arc LDS-01/high/arc UTM-30LX/normal/arc ILD26TRI/varying/varying ILD26TRI/normal/arc LDS-01/high/smooth)
look_aheads=(0 0.1 0.2 0.5 1)
printf 'interpolation: linear\n' > "$work/linear.yaml"
for l in "${look_aheads[@]}"; do printf 'interpolation: twist\nfit_look_ahead: %s\n' "$l" > "$work/twist-$l.yaml"; done
# rms ROW COLUMN: the RMS of a deskew_metrics --markdown row's column (6 cloud, 8 laser_geometry).
rms() { echo "$1" | awk -F'|' -v c="$2" '{split($c, v, " / "); gsub(/ /, "", v[1]); print v[1]}'; }
out="$work/look_ahead.tsv"
printf 'scenario\tseed\tfloor\tlinear\tlaser_geometry' > "$out"
for l in "${look_aheads[@]}"; do printf '\ttwist_%s' "$l" >> "$out"; done
printf '\n' >> "$out"
for scenario in "${scenarios[@]}"; do
  slug=$(echo "$scenario" | tr '/' '_')
  for seed in 1 2 3 4 5; do
    bag="$work/$slug-$seed.bag" truth="$work/$slug-$seed.truth"
    "$bin/deskew_simulate" --scenario "$scenario" --bag "$bag" --truth "$truth" --noise --seed "$seed" >/dev/null
    floor=$(rms "$("$bin/deskew_metrics" "$bag" "$truth" --markdown --params "$work/twist-0.yaml")" 6)
    "$bin/deskew_simulate" --scenario "$scenario" --bag "$bag" --truth "$truth" --noise --seed "$seed" \
      --odom-noise 0.1 --odom-seed "$seed" >/dev/null
    linear=$("$bin/deskew_metrics" "$bag" "$truth" --markdown --params "$work/linear.yaml")
    row="$scenario\t$seed\t$floor\t$(rms "$linear" 6)\t$(rms "$linear" 8)"
    for l in "${look_aheads[@]}"; do
      row+="\t$(rms "$("$bin/deskew_metrics" "$bag" "$truth" --markdown --params "$work/twist-$l.yaml")" 6)"
    done
    printf "$row\n" >> "$out"
    rm -f "$bag" "$truth"
  done
done
cat "$out"
echo
# Every column from the floor on (the last, twist_1, included).
awk -F'\t' 'NR == 1 { line = "scenario (mean of seeds)"; for (c = 3; c <= NF; c++) line = line "\t" $c; print line; next }
  { if (!($1 in n)) order[++k] = $1; n[$1]++; for (c = 3; c <= NF; c++) s[$1, c] += $c; columns = NF }
  END { for (i = 1; i <= k; i++) { key = order[i]; line = key
        for (c = 3; c <= columns; c++) line = line sprintf("\t%.2f", s[key, c] / n[key]); print line } }' "$out"
