#!/usr/bin/env bash
# deskew_calibrate as a user runs it: its exit status says the outcome (docs/CALIBRATION.md) and the file
# holds only what was told. A steady circle (one constant twist, beams reversed): the offset cannot
# show, exit 4, the file reverses the beams and has no stamp_at / time_offset line. The Neato bag: the
# whole timing, exit 0, a time_offset within the sweep before the stamp. A straight line: nothing told,
# exit 3, no file. A bag without the topic: exit 1. The LDS-01 driver's convention (deskew_simulate
# --driver): stamp_at end and reversed beams written. Edited bags (tf shorter than the scans at both
# ends, legacy tf/tfMessage, header.seq all 0): exit 0, the scans tf does not cover counted.
# Usage: check_calibrate_cli.sh DESKEW_CALIBRATE DESKEW_SIMULATE NEATO_BAG
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
calibrate=${1:?deskew_calibrate} simulate=${2:?deskew_simulate} neato=${3:?neato bag}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
status=0
cases=0
fail() { echo "FAILED: $*"; status=1; }

expect() {  # NAME EXPECTED_STATUS ARGS...
  local name=$1 expected=$2 code=0
  shift 2
  cases=$((cases + 1))
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
offset=$(awk '/^time_offset:/ { print $2 }' "$work/neato.yaml" 2>/dev/null || true)
awk -v o="$offset" 'BEGIN { exit !(o < -0.02 && o > -0.2) }' || fail "neato: time_offset $offset not within the sweep before the stamp"

"$simulate" --scenario LDS-01/normal/translation --noise --bag "$work/line.bag" --truth "$work/line.truth" >/dev/null
expect line 3 "$work/line.bag" --scan-topic /scan --output "$work/line.yaml"
[ ! -e "$work/line.yaml" ] || fail "line: a file was written"
grep -q "nothing told (too flat): the score is too flat" "$work/line.out" || fail "line: the flat score is not named"

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
cases=$((cases + 1))
code=0
"$simulate" --driver no_such_driver --bag "$work/x.bag" --truth "$work/x.truth" 2>/dev/null || code=$?
[ "$code" = 1 ] || fail "--driver no_such_driver: exit $code, expected 1"
cases=$((cases + 1))
# Real bags edited as recorders and drivers leave them (rosbag's own Python API): tf starting 1 s
# after the first scan and ending 1 s before the last, with the stamps 0.5 s late or early (a scan kept
# under the shifted stamp has its raw stamp outside tf: extrapolation into the future, or the past);
# /tf recorded as the legacy tf/tfMessage; every header.seq 0.
cat >"$work/edit_bag.py" <<'PYTHON'
import sys, rosbag
mode, source, target = sys.argv[1:4]
bag = rosbag.Bag(source)
stamps = [m.header.stamp.to_sec() for _, m, _ in bag.read_messages(topics=['/scan'])]
first, last, middle = min(stamps), max(stamps), 0.5 * (min(stamps) + max(stamps))
with rosbag.Bag(target, 'w') as out:
    for topic, msg, t in bag.read_messages():
        header = None
        if mode == 'trim_tf' and topic in ('/tf', '/odom'):
            stamp = (msg.transforms[0].header if topic == '/tf' else msg.header).stamp.to_sec()
            if stamp < first + 1.0 or stamp > last - 1.0:
                continue
        if mode == 'legacy_tf' and topic in ('/tf', '/tf_static'):
            header = {'topic': topic, 'type': 'tf/tfMessage', 'md5sum': msg._md5sum,
                      'message_definition': msg._full_text}
        if mode == 'seq0':
            if hasattr(msg, 'header'):
                msg.header.seq = 0
            for transform in getattr(msg, 'transforms', []):
                transform.header.seq = 0
        if mode == 'frame_change':
            if topic == '/scan' and msg.header.stamp.to_sec() > middle:
                msg.header.frame_id = 'laser_renamed'
            if topic == '/tf_static':
                renamed = type(msg.transforms[0])()
                renamed.header, renamed.transform = msg.transforms[0].header, msg.transforms[0].transform
                renamed.child_frame_id = 'laser_renamed'
                msg.transforms.append(renamed)
        out.write(topic, msg, t, connection_header=header)
PYTHON
edit() { /usr/bin/python3 "$work/edit_bag.py" "$@"; }
for late in 0.5 -0.5; do
  "$simulate" --scenario LDS-01/normal/turns --noise --stamp-error $late --bag "$work/late.bag" --truth "$work/late.truth" >/dev/null
  edit trim_tf "$work/late.bag" "$work/trimmed$late.bag"
  expect "trimmed$late" 0 "$work/trimmed$late.bag" --scan-topic /scan --output "$work/trimmed$late.yaml"
  grep -q "left out: 1[0-9] scans tf does not cover" "$work/trimmed$late.out" || fail "trimmed$late: the scans left out are not counted"
  offset=$(awk '/^time_offset:/ { print $2 }' "$work/trimmed$late.yaml" 2>/dev/null || true)
  awk -v o="$offset" -v t="$late" 'BEGIN { exit !(o + t < 0.002 && o + t > -0.002) }' ||
    fail "trimmed$late: time_offset $offset, the truth is minus $late"
done
"$simulate" --scenario LDS-01/normal/turns --noise --reversed --bag "$work/turns.bag" --truth "$work/turns.truth" >/dev/null
for mode in legacy_tf seq0; do
  edit $mode "$work/turns.bag" "$work/$mode.bag"
  expect $mode 0 "$work/$mode.bag" --scan-topic /scan --output "$work/$mode.yaml"
  grep -q '^beam_order: reversed$' "$work/$mode.yaml" || fail "$mode: beam_order reversed not found"
done
# The scans' frame_id renamed halfway (both frames mounted alike): the change is named, the frame most
# scans have is calibrated.
edit frame_change "$work/turns.bag" "$work/frame_change.bag"
expect frame_change 0 "$work/frame_change.bag" --scan-topic /scan --output "$work/frame_change.yaml"
grep -q "frame_id changes midway: [0-9]* scans are in another frame than laser (laser_renamed: " \
  "$work/frame_change.out" || fail "frame_change: the change of frame is not named"
# The shape check (scans a short time apart whose turn differs, aligned by a free rigid scan match):
# an RPLIDAR robot as the TurtleBot4's (ranges against the spin, stamped 131.6 ms after the first beam,
# 20 ms odometry): the timing written brings shapes well below raw (the truth-corrected scans: about
# 0.3), the message's leaves them worse than raw.
"$simulate" --driver rplidar --stamp-error 0.1316 --duration 8 --noise --bag "$work/rplidar.bag" --truth "$work/rplidar.truth" >/dev/null
expect rplidar 0 "$work/rplidar.bag" --output "$work/rplidar.yaml"
grep -q '^beam_order: reversed$' "$work/rplidar.yaml" || fail "rplidar: beam_order reversed not written"
ratio() { sed -n "s/^    $1: \([0-9.]*\) (quartiles.*/\1/p" "$2"; }
awk -v r="$(ratio 'the estimated timing' "$work/rplidar.out")" 'BEGIN { exit !(r != "" && r <= 0.5) }' ||
  fail "rplidar: shapes under the estimate not at most 0.5x raw"
awk -v r="$(ratio "the message's timing" "$work/rplidar.out")" 'BEGIN { exit !(r != "" && r > 1.0) }' ||
  fail "rplidar: shapes under the message's timing not worse than raw"
# Odometry that reports 0.4x the true rotation: the rotation check names it, with the figure, in what is
# not told.
"$simulate" --scenario LDS-01/normal/turns --noise --odom-yaw-scale 0.4 --bag "$work/yaw.bag" --truth "$work/yaw.truth" >/dev/null
expect yaw 4 "$work/yaw.bag" --output "$work/yaw.yaml"
grep -q "not told (.*tf's rotation does not fit the scans: scan matching sees 2\.[3-7][0-9]x tf's rotation" "$work/yaw.out" ||
  fail "yaw: the rotation's misfit is not named in what is not told"
[ "$status" = 0 ] && echo "$cases passed, 0 failed"
exit "$status"
