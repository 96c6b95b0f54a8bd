// Single-point and ensemble RK4 throughput on the coupled model with one tangent vector
// (the paper's map settings: h = 0.01, window from τ = 250). Reports RK4 steps/s per core as
// counters, and — after the Google Benchmark table — the ensemble/one-lane ratio measured in the
// same process (these machines are shared and noisy; compare ratios, not absolute times).
//   build/bench/bench_kernel [--benchmark_min_time=2]
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <vector>

#include "dynamics/point.h"

namespace bistable {
namespace {

PointSpec CoupledSpec(double t_end) {
  PointSpec s;
  s.model = ModelKind::kCoupled;
  s.alpha = 1.0;
  s.omega = 1.2;
  s.integration.t_end = t_end;
  s.integration.t_keep = t_end / 2;
  return s;
}

// W lanes of the coupled model at Ω = 0.5, 0.6, ... (a mix of periodic and chaotic points), kernel
// only: no samples kept, no metric finalisation.
struct LaneBlock {
  PointSpec spec = CoupledSpec(100);
  KernelSettings ks;
  std::vector<LaneInput> lanes;
  std::vector<RawLane> out;
  explicit LaneBlock(int w) : ks(KernelSettingsFor(spec)), lanes(w, LaneFor(spec)), out(w) {
    ks.keep_samples = false;
    for (int l = 0; l < w; ++l) lanes[l].omega = 0.5 + 0.1 * l;
  }
};

template <int W>
double LaneStepsPerSecond(int reps) {
  LaneBlock b(W);
  const PointSpec& s = b.spec;
  const KernelSettings& ks = b.ks;
  std::vector<LaneInput>& lanes = b.lanes;
  std::vector<RawLane>& out = b.out;
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < reps; ++r) RunKernel<W>(s.model, lanes.data(), W, ks, out.data());
  const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return static_cast<double>(reps) * W * ks.n_total / sec;
}

// Kernel only (no metric finalisation): lane-steps per second.
template <int W>
void BM_KernelCoupledTangent(benchmark::State& state) {
  LaneBlock b(W);
  for (auto _ : state) {
    RunKernel<W>(b.spec.model, b.lanes.data(), W, b.ks, b.out.data());
    benchmark::DoNotOptimize(b.out.data());
  }
  state.counters["rk4_steps_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * W * b.ks.n_total, benchmark::Counter::kIsRate);
}
BENCHMARK_TEMPLATE(BM_KernelCoupledTangent, 1)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_KernelCoupledTangent, 4)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_KernelCoupledTangent, 8)->Unit(benchmark::kMillisecond);
BENCHMARK_TEMPLATE(BM_KernelCoupledTangent, 16)->Unit(benchmark::kMillisecond);

// A whole `bistable point` evaluation at the paper's settings (τ 0–500), all metrics.
void BM_EvaluatePointCoupled(benchmark::State& state) {
  PointSpec s = CoupledSpec(500);
  s.metrics.rosenstein = state.range(0) != 0;
  for (auto _ : state) benchmark::DoNotOptimize(EvaluatePoint(s));
  state.counters["rk4_steps_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * 50000, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EvaluatePointCoupled)->Arg(0)->Arg(1)->ArgNames({"rosenstein"})->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace bistable

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  // Same-process ratio, interleaved to share whatever load the machine has.
  double one = 0, sixteen = 0;
  for (int round = 0; round < 3; ++round) {
    one += bistable::LaneStepsPerSecond<1>(20);
    sixteen += bistable::LaneStepsPerSecond<16>(4);
  }
  std::printf("\nratio  coupled+tangent RK4 lane-steps/s: 16 lanes %.1f M/s, 1 lane %.1f M/s, ratio %.2fx\n",
              sixteen / 3e6, one / 3e6, sixteen / one);
  return 0;
}
