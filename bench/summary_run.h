// Shared by the benchmarks' reporters.
#pragma once

#include <benchmark/benchmark.h>

namespace lidar_deskew::bench {

/// The run a summary shows for one benchmark: the median of its repetitions, or the run itself when
/// it is not repeated; never a failed run.
inline bool isSummaryRun(const benchmark::BenchmarkReporter::Run& run) {
  using Run = benchmark::BenchmarkReporter::Run;
  const bool median = run.run_type == Run::RT_Aggregate && run.aggregate_name == "median";
  const bool single = run.run_type == Run::RT_Iteration && run.repetitions <= 1;
  return !run.error_occurred && (median || single);
}

}  // namespace lidar_deskew::bench
