// The wall time of one call, for the benchmarks' ratios (each benchmark times its baseline in the same run).
#ifndef BISTABLE_BENCH_BENCH_TIMING_H_
#define BISTABLE_BENCH_BENCH_TIMING_H_

#include <chrono>
#include <functional>

namespace bistable_bench {

inline double Seconds(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace bistable_bench

#endif  // BISTABLE_BENCH_BENCH_TIMING_H_
