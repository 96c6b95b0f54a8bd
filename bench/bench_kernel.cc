// Single-point and ensemble RK4 throughput on the coupled model with one tangent vector
// (the paper's map settings: h = 0.01, window from τ = 250). Reports RK4 steps/s per core as
// counters, and — after the Google Benchmark table — the ensemble/one-lane ratio measured in the
// same process (these machines are shared and noisy; compare ratios, not absolute times).
// The ensemble runs the engine's lane width W = kSweepLanes (8 on AVX-512, 4 on AVX2; fixed at compile
// time) and 2W (two registers per lane vector); the first line of the output says W, the ISA and the CPU
// (dynamics/host_lanes.h). --header prints only that line.
//   build/bench/bench_kernel [--benchmark_min_time=2] | [--header]
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "dynamics/benettin.h"
#include "dynamics/host_lanes.h"
#include "dynamics/lanes.h"
#include "dynamics/nondim_system.h"
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

// W lanes of the coupled model at Ω = 0.5, 0.6, ... (a mix of periodic and chaotic points) with a
// sweep's kernel settings at the paper's τ 0–500 (window from 250: quadratures, strobes, turning
// points, samples), kernel only: no metric finalisation.
struct LaneBlock {
  PointSpec spec = CoupledSpec(500);
  KernelSettings ks;
  std::vector<LaneInput> lanes;
  std::vector<RawLane> out;
  explicit LaneBlock(int w) : ks(KernelSettingsFor(spec)), lanes(w, LaneFor(spec)), out(w) {
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
// The same without the window (τ 0–500 all transient): state, tangent and renormalisation only — the
// work per step of ../shared/bench/reference_kernel.cc (bench/kernel_ratio.sh compares the two).
template <int W>
void BM_KernelNoWindow(benchmark::State& state) {
  LaneBlock b(W);
  b.ks.n_keep = b.ks.n_total;
  for (auto _ : state) {
    RunKernel<W>(b.spec.model, b.lanes.data(), W, b.ks, b.out.data());
    benchmark::DoNotOptimize(b.out.data());
  }
  state.counters["rk4_steps_per_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * W * b.ks.n_total, benchmark::Counter::kIsRate);
}
constexpr int kW = kSweepLanes;  // the engine's width (dynamics/lanes.h)

// Registered under the width's number ("BM_KernelNoWindow<8>"), which bench/kernel_ratio.sh reads.
template <int W>
void Register(const char* name, void (*fn)(benchmark::State&)) {
  benchmark::RegisterBenchmark((std::string(name) + "<" + std::to_string(W) + ">").c_str(), fn)
      ->Unit(benchmark::kMillisecond);
}
void RegisterKernels() {
  Register<kW>("BM_KernelNoWindow", BM_KernelNoWindow<kW>);
  Register<1>("BM_KernelCoupledTangent", BM_KernelCoupledTangent<1>);
  if constexpr (kW > 4) Register<4>("BM_KernelCoupledTangent", BM_KernelCoupledTangent<4>);
  Register<kW>("BM_KernelCoupledTangent", BM_KernelCoupledTangent<kW>);
  Register<2 * kW>("BM_KernelCoupledTangent", BM_KernelCoupledTangent<2 * kW>);
}

// One trajectory at a time through the generic path: Eigen state, RK4 on (x, J(x)w), no lanes.
double GenericStepsPerSecond() {
  const PointSpec s = CoupledSpec(100);
  const LaneInput in = LaneFor(s);
  NondimSystem<CoupledModel> sys(in.coeffs, in.alpha, in.omega);
  BenettinOptions o;
  o.h = 0.01;
  o.t_transient = 50;
  o.t_average = 50;
  o.renorm_every = 50;
  const auto t0 = std::chrono::steady_clock::now();
  const int reps = 10;
  for (int r = 0; r < reps; ++r) benchmark::DoNotOptimize(BenettinLle(sys, Eigen::Vector4d(1, 0, 1, 0), 0.0, o));
  const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return reps * 10000 / sec;
}

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
  using bistable::kW;
  if (argc == 2 && std::strcmp(argv[1], "--header") == 0)
    return std::printf("%s\n", bistable::HostLanesLine().c_str()), 0;
  std::printf("%s\n", bistable::HostLanesLine().c_str());
  std::fflush(stdout);
  bistable::RegisterKernels();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  // Same-process ratios, interleaved so all share whatever load the machine has.
  double generic = 0, one = 0, w = 0, w2 = 0;
  const int rounds = 3;
  for (int round = 0; round < rounds; ++round) {
    generic += bistable::GenericStepsPerSecond();
    one += bistable::LaneStepsPerSecond<1>(4);
    w += bistable::LaneStepsPerSecond<kW>(8 / kW);
    w2 += bistable::LaneStepsPerSecond<2 * kW>(1);
  }
  std::printf(
      "\nratio  coupled + tangent RK4, lane-steps/s per core (mean of %d interleaved rounds):\n"
      "  generic one-trajectory path (Eigen, rk4.h + benettin.h)  %7.1f M/s\n"
      "  kernel, 1 lane                                           %7.1f M/s\n"
      "  kernel, %2d lanes (the engine's width)                    %7.1f M/s   %.1fx generic, %.1fx 1-lane\n"
      "  kernel, %2d lanes (two registers per vector)              %7.1f M/s   %.1fx generic, %.1fx 1-lane\n",
      rounds, generic / rounds / 1e6, one / rounds / 1e6, kW, w / rounds / 1e6, w / generic, w / one, 2 * kW,
      w2 / rounds / 1e6, w2 / generic, w2 / one);
  return 0;
}
