#!/usr/bin/env bash
# deskew_calibrate as a user runs it: its exit status says the outcome (docs/CALIBRATION.md) and the file
# holds only what was told. A steady circle (one constant twist, beams reversed): the offset cannot
# show, exit 4, the file reverses the beams and has no stamp_at / time_offset line. The Neato bag: the
# whole timing, exit 0, a time_offset within the sweep before the stamp. A straight line: nothing told,
# exit 3, no file. A bag without the topic: exit 1. The LDS-01 driver's convention (deskew_simulate
# --driver): stamp_at end and reversed beams written.
# Usage: check_calibrate_cli.sh DESKEW_CALIBRATE DESKEW_SIMULATE NEATO_BAG
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
calibrate=${1:?deskew_calibrate} simulate=${2:?deskew_simulate} neato=${3:?neato bag}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
status=0
fail() { echo "FAILED: $*"; status=1; }

expect() {  # NAME EXPECTED_STATUS ARGS...
  local name=$1 expected=$2 code=0
  shift 2
  "$calibrate" "$@" >"$work/$name.out" 2>&1 || code=$?
  sed 's/^/  /' "$work/$name.out"
  [ "$code" = "$expected" ] || fail "$name: exit $code, expected $expected"
}

"$simulate" --scenario LDS-01/normal/circle --noise --reversed --bag "$work/circle.bag" --truth "$work/circle.truth" >/dev/null
expect circle 4 "$work/circle.bag" --scan-topic /scan --output "$work/circle.yaml" --curve "$work/circle.csv"
grep -q "turning too uniform" "$work/circle.out" || fail "circle: the cause is not named"
grep -q '^beam_order: reversed$' "$work/circle.yaml" || fail "circle: beam_order reversed not written"
if grep -q '^time_offset:\|^stamp_at:' "$work/circle.yaml"; then fail "circle: an offset was written"; fi
[ "$(grep -c '^coarse,' "$work/circle.csv")" -gt 100 ] || fail "circle: no coarse curve"

expect neato 0 "$neato" --scan-topic /stable_scan --output "$work/neato.yaml"
offset=$(awk '/^time_offset:/ { print $2 }' "$work/neato.yaml")
awk -v o="$offset" 'BEGIN { exit !(o < -0.02 && o > -0.2) }' || fail "neato: time_offset $offset not within the sweep before the stamp"

"$simulate" --scenario LDS-01/normal/translation --noise --bag "$work/line.bag" --truth "$work/line.truth" >/dev/null
expect line 3 "$work/line.bag" --scan-topic /scan --output "$work/line.yaml"
[ ! -e "$work/line.yaml" ] || fail "line: a file was written"

expect missing 1 "$neato" --scan-topic /no_such_topic

# As the TurtleBot3's LDS-01 driver writes its scans (docs/REAL_ROBOTS.md): stamped at the latest beam,
# ranges against the spin; 4 s of the turns drive tell both. --driver takes no other timing fault.
"$simulate" --driver hls_lfcd_lds --duration 4 --noise --bag "$work/lds.bag" --truth "$work/lds.truth" >/dev/null
expect lds 0 "$work/lds.bag" --output "$work/lds.yaml"
grep -q '^stamp_at: end$' "$work/lds.yaml" || fail "hls_lfcd_lds: stamp_at end not written"
grep -q '^beam_order: reversed$' "$work/lds.yaml" || fail "hls_lfcd_lds: beam_order reversed not written"
code=0
"$simulate" --driver rplidar --reversed --bag "$work/x.bag" --truth "$work/x.truth" 2>/dev/null || code=$?
[ "$code" = 2 ] || fail "--driver with --reversed: exit $code, expected 2"
code=0
"$simulate" --driver no_such_driver --bag "$work/x.bag" --truth "$work/x.truth" 2>/dev/null || code=$?
[ "$code" = 1 ] || fail "--driver no_such_driver: exit $code, expected 1"
[ "$status" = 0 ] && echo "5 passed, 0 failed"
exit "$status"
