#!/usr/bin/env bash
# The per-cloud path of this tree against an older commit's, side by side on one machine: bench_cloud of
# both (Release, bench/build.sh) run alternately on one core, ROUNDS rounds of 5 repetitions each, and
# the median over every round of each side's medians, with their ratio (this tree / the other).
#   bash bench/compare_cloud.sh [COMMIT]     (default 214e6ab, version 0.2.0; ROUNDS=3)
# The other commit's sources are extracted (git archive) into .build/bench_ref/COMMIT and built there,
# with this tree's bench/build.sh when that commit has none (REF_DIR: another folder for them). Other
# benchmarks: FILTER (a regex; default the whole path and its halves).
set -euo pipefail
export PATH=/usr/bin:/bin:$PATH
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
ref=${1:-214e6ab}
rounds=${ROUNDS:-3}
filter=${FILTER:-'^(BM_CloudNodeletPath|BM_CloudPrepare|BM_CloudCorrectAndBuild)$'}
ours=$(bash "$repo/bench/build.sh" bench_cloud)
ref_dir=${REF_DIR:-$repo/.build/bench_ref/$ref}
if [ ! -d "$ref_dir" ]; then
  mkdir -p "$ref_dir"
  git -C "$repo" archive "$ref" | tar -x -C "$ref_dir"
fi
[ -e "$ref_dir/bench/build.sh" ] || cp "$repo/bench/build.sh" "$ref_dir/bench/build.sh"
theirs=$(bash "$ref_dir/bench/build.sh" bench_cloud)

# Prints "NAME BENCHMARK NS_PER_POINT" for each benchmark's median of 5.
run() {
  taskset -c 0 "$2" --benchmark_filter="$filter" --benchmark_min_time=0.5 --benchmark_repetitions=5 \
    --benchmark_report_aggregates_only=true 2>/dev/null |
    awk -v side="$1" '/_median/ { for (i = 2; i <= NF; i++) if ($i ~ /^ns_per_point=/) {
      value = $i; sub(/ns_per_point=/, "", value); sub(/_median$/, "", $1)
      factor = value ~ /ms$/ ? 1e6 : value ~ /us$/ ? 1e3 : 1; sub(/[mun]?s$/, "", value)
      print side, $1, value * factor } }'
}
for round in $(seq "$rounds"); do
  run ours "$ours"
  run "$ref" "$theirs"
done | awk -v ref="$ref" -v rounds="$rounds" '
  { values[$2 " " $1] = values[$2 " " $1] " " $3; if (!($2 in seen)) { seen[$2] = 1; names[++count] = $2 } }
  function median(list,   n, v, i, j, t) {
    n = split(list, v, " ")
    for (i = 1; i <= n; i++) for (j = i + 1; j <= n; j++) if (v[j] < v[i]) { t = v[i]; v[i] = v[j]; v[j] = t }
    return n % 2 ? v[(n + 1) / 2] : (v[n / 2] + v[n / 2 + 1]) / 2
  }
  END {
    printf "ns per point, median of %d rounds (each a median of 5), run alternately on one core\n", rounds
    printf "%-26s %10s %10s %8s\n", "benchmark", "this tree", ref, "ratio"
    for (k = 1; k <= count; k++) {
      name = names[k]; a = median(values[name " ours"]); b = median(values[name " " ref])
      printf "%-26s %10.2f %10.2f %8.2f\n", name, a, b, a / b
    }
  }'
