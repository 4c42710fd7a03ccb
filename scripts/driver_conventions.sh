#!/usr/bin/env bash
# Regenerates the table of docs/REAL_ROBOTS.md "What the simulated drivers show": runs
# test_driver_conventions (each 2D driver's convention simulated on a turning drive, deskew_calibrate's
# estimate against the truth) and puts the rows it prints between the page's table markers. About 20 s
# once built. Exits non-zero when a driver misses its test.
#   bash scripts/driver_conventions.sh
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
bash "$repo/scripts/build_workspace.sh" >/dev/null
(cd "$repo/.build/ws" && catkin_make -j"${LIDAR_DESKEW_JOBS:-2}" test_driver_conventions >/dev/null)
output=$(mktemp)
trap 'rm -f "$output" "$output.md"' EXIT
status=0
"$repo/.build/ws/devel/lib/lidar_deskew/test_driver_conventions" >"$output" 2>&1 || status=$?
page="$repo/docs/REAL_ROBOTS.md"
awk -v rows="$output" '
  /<!-- driver table begin/ { print; print "| driver | first beam − stamp: truth | estimate ± 1σ | order | period used |";
    print "|---|---|---|---|---|"; while ((getline line < rows) > 0) if (line ~ /^\| /) print line; skip = 1; next }
  /<!-- driver table end/ { skip = 0 }
  !skip { print }' "$page" >"$output.md"
mv "$output.md" "$page"
[ "$status" = 0 ] || { grep -E "Failure|FAILED" "$output" || true; echo "test_driver_conventions failed"; }
exit "$status"
