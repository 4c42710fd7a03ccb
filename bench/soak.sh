#!/usr/bin/env bash
# Soak run (not in CI): two deskews in one nodelet manager, 40 Hz x 1440 beams (/utm) plus 8 Hz x 360
# beams (/ild), with tf at 50 Hz, in real time. Samples the manager's RSS and CPU every 10 s and prints
# RSS growth after warm-up, CPU, and each deskew's diagnostics (drops by reason, latency).
#   bash bench/soak.sh [SECONDS]      # default 600; warm-up is the first 60 s (or a tenth of short runs)
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
export PYTHONNOUSERSITE=1
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
seconds=${1:-600}
warmup=$((seconds >= 600 ? 60 : seconds / 10))
out="$repo/.build/soak"
mkdir -p "$out"
bash "$repo/scripts/build_workspace.sh" -DCATKIN_ENABLE_TESTING=ON >/dev/null
(cd "$repo/.build/ws" && catkin_make latency_driver >/dev/null)
set +u; source "$repo/.build/ws/devel/setup.bash"; set -u
port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
export ROS_MASTER_URI=http://127.0.0.1:$port
roscore -p "$port" >"$out/roscore.log" 2>&1 &
core=$!
launch=""
trap 'kill $launch 2>/dev/null || true; sleep 2; kill $core 2>/dev/null || true; wait 2>/dev/null || true' EXIT
sleep 3
roslaunch "$repo/bench/soak.launch" >"$out/launch.log" 2>&1 &
launch=$!
manager=""
for _ in $(seq 50); do
  manager=$(pgrep -f "__name:=soak_manager" | head -n 1 || true)
  [ -n "$manager" ] && break
  sleep 0.2
done
[ -n "$manager" ] || { echo "soak: the nodelet manager did not start (see $out/launch.log)" >&2; exit 1; }
sleep 2
"$repo/.build/ws/devel/lib/lidar_deskew/latency_driver" --seconds "$seconds" \
  --sensor UTM-30LX:utm --sensor ILD26TRI:ild >"$out/driver.log" 2>&1 &
driver=$!

tick=$(getconf CLK_TCK)
samples="$out/samples.csv"
# steal: CPU time the hypervisor gave other guests while this one wanted to run (noisy neighbours).
echo "seconds,rss_kib,cpu_ticks,driver_ticks,machine_ticks,steal_ticks" >"$samples"
begin=$(date +%s.%N)
while kill -0 "$driver" 2>/dev/null; do
  now=$(date +%s.%N)
  rss=$(awk '/^VmRSS/ {print $2}' "/proc/$manager/status")
  ticks=$(awk '{print $14 + $15}' "/proc/$manager/stat")
  driver_ticks=$(awk '{print $14 + $15}' "/proc/$driver/stat" 2>/dev/null || echo 0)
  machine=$(awk '/^cpu / {print $2 + $3 + $4 + $5 + $6 + $7 + $8 + $9, $9}' /proc/stat)
  printf '%.1f,%s,%s,%s,%s,%s\n' "$(echo "$now - $begin" | bc)" "$rss" "$ticks" "$driver_ticks" \
    "${machine% *}" "${machine#* }" >>"$samples"
  sleep 10
done
wait "$driver" || { echo "soak: the driver failed:" >&2; cat "$out/driver.log" >&2; exit 1; }

echo "soak: ${seconds} s, one nodelet manager (pid $manager), samples in $samples"
awk -F, -v warmup="$warmup" -v tick="$tick" '
  BEGIN { n = 0 }
  NR == 1 { next }
  { t[n] = $1; rss[n] = $2; cpu[n] = $3; drv[n] = $4; all[n] = $5; steal[n] = $6; n++ }
  END {
    w = 0; while (w < n - 1 && t[w] < warmup) w++;
    printf "  RSS at start %d KiB, after warm-up (%.0f s) %d KiB, at the end (%.0f s) %d KiB\n", rss[0], t[w], rss[w], t[n-1], rss[n-1];
    printf "  RSS growth after warm-up: %+d KiB (target < 1024 KiB)\n", rss[n-1] - rss[w];
    max = 0; for (i = w; i < n; i++) if (rss[i] > max) max = rss[i];
    printf "  RSS max after warm-up: %d KiB\n", max;
    printf "  CPU of the manager after warm-up: %.1f %% of one core\n", 100 * (cpu[n-1] - cpu[w]) / tick / (t[n-1] - t[w]);
    printf "  CPU of the driver (tf, scans, output subscriber): %.1f %% of one core\n", 100 * (drv[n-2] - drv[0]) / tick / (t[n-2] - t[0]);
    printf "  steal (CPU taken by other guests of the host): %.1f %% of this machine over the run\n", 100 * (steal[n-1] - steal[0]) / (all[n-1] - all[0]);
    worst = 0; for (i = 1; i < n; i++) { d = (steal[i] - steal[i-1]) / (all[i] - all[i-1]); if (d > worst) worst = d }
    printf "  steal in the worst 10 s: %.1f %%\n", 100 * worst;
  }' "$samples"
cat "$out/driver.log"
