// Cost per simulated second of the dimensional friction model (paper Table 2, bistable beam with
// resonator) at the paper's Stribeck velocities v_sp = 2 mm/s, v_t = 1 mm/s, base A0 = 10 mm at
// f0 = 3 Hz: Dormand–Prince 5(4) (explicit, adaptive) against Rosenbrock 2(3) (linearly implicit,
// L-stable), same tolerances, same process. Prints RHS evaluations, steps and wall time per
// simulated second, their ratio, and the difference between the two solutions at the end.
// Both are one point at a time (no lanes); the first line says the CPU and the build's lanes all the same
// (dynamics/host_lanes.h).
//   build/bench/bench_stiff [--benchmark_min_time=1]
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>

#include "dynamics/dimensional_model.h"
#include "dynamics/dopri5.h"
#include "dynamics/host_lanes.h"
#include "dynamics/rosenbrock23.h"

namespace bistable {
namespace {

constexpr double kSimSeconds = 4.0;

DimensionalModel Model(double v_sp, double v_t) {
  DimensionalParams p = DimensionalParams::BistableTable2();
  p.fric_m.v_sp = p.fric_r.v_sp = v_sp;
  p.fric_m.v_t = p.fric_r.v_t = v_t;
  return DimensionalModel(p, SineBase(0.010, 3.0));
}

AdaptiveOptions Tol() {
  AdaptiveOptions o;
  o.rtol = 1e-5;
  o.atol = 1e-8;
  return o;
}

DimensionalModel::State Start() {
  DimensionalModel::State x;
  x << 0.023, 0, 0, 0;  // at rest in the positive well (δs ≈ 23 mm)
  return x;
}

template <class Stepper>
void Run(benchmark::State& state, double v_sp, double v_t) {
  const DimensionalModel m = Model(v_sp, v_t);
  OdeSummary sum;
  for (auto _ : state) {
    Stepper st(m, Tol());
    DimensionalModel::State x = Start();
    st.Integrate(0.0, x, kSimSeconds);
    sum = st.summary();
    benchmark::DoNotOptimize(x);
  }
  state.counters["rhs_per_sim_s"] = static_cast<double>(sum.rhs_evals) / kSimSeconds;
  state.counters["steps_per_sim_s"] = static_cast<double>(sum.accepted + sum.rejected) / kSimSeconds;
  state.counters["sim_s_per_wall_s"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * kSimSeconds, benchmark::Counter::kIsRate);
}

void BM_Dopri5_PaperStribeck(benchmark::State& s) { Run<Dopri5<DimensionalModel>>(s, 0.002, 0.001); }
void BM_Rosenbrock23_PaperStribeck(benchmark::State& s) { Run<Rosenbrock23<DimensionalModel>>(s, 0.002, 0.001); }
void BM_Dopri5_RaisedStribeck(benchmark::State& s) { Run<Dopri5<DimensionalModel>>(s, 0.02, 0.01); }
void BM_Rosenbrock23_RaisedStribeck(benchmark::State& s) { Run<Rosenbrock23<DimensionalModel>>(s, 0.02, 0.01); }
BENCHMARK(BM_Dopri5_PaperStribeck)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Rosenbrock23_PaperStribeck)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Dopri5_RaisedStribeck)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Rosenbrock23_RaisedStribeck)->Unit(benchmark::kMillisecond);

template <class Stepper>
double WallPerSimSecond(const DimensionalModel& m, AdaptiveOptions tol, DimensionalModel::State* end, OdeSummary* sum) {
  const auto t0 = std::chrono::steady_clock::now();
  Stepper st(m, tol);
  DimensionalModel::State x = Start();
  st.Integrate(0.0, x, kSimSeconds);
  *end = x;
  *sum = st.summary();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / kSimSeconds;
}

}  // namespace
}  // namespace bistable

int main(int argc, char** argv) {
  using namespace bistable;
  std::printf("%s\n", HostLanesLine().c_str());
  std::fflush(stdout);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  std::printf(
      "\nratio  per simulated second, paper Stribeck velocities (v_sp 2 mm/s, v_t 1 mm/s), Table 2 bistable + "
      "resonator\n"
      "%-22s %-6s | %-28s | %-28s | %-8s %s\n",
      "base motion", "rtol", "dopri5 rhs / steps / ms", "rosenbrock23 rhs / steps / ms", "wall", "|dy_end| mm");
  struct Scenario {
    double a0_mm, f0_hz, rtol;
  };
  for (const Scenario sc : {Scenario{10, 3, 1e-5}, Scenario{10, 3, 1e-3}, Scenario{1, 3, 1e-5}, Scenario{1, 3, 1e-3},
                            Scenario{0.3, 5, 1e-5}, Scenario{0.3, 5, 1e-3}}) {
    DimensionalParams p = DimensionalParams::BistableTable2();
    const DimensionalModel m(p, SineBase(sc.a0_mm * 1e-3, sc.f0_hz));
    AdaptiveOptions tol;
    tol.rtol = sc.rtol;
    tol.atol = sc.rtol * 1e-3;  // 1e-3 of the relative tolerance in m and m/s: below a micrometre
    DimensionalModel::State xe, xi;
    OdeSummary se, si;
    double we = 0, wi = 0;
    for (int r = 0; r < 3; ++r) {  // interleaved so both share the machine's load
      we += WallPerSimSecond<Dopri5<DimensionalModel>>(m, tol, &xe, &se);
      wi += WallPerSimSecond<Rosenbrock23<DimensionalModel>>(m, tol, &xi, &si);
    }
    char label[64];
    std::snprintf(label, sizeof label, "A0 %.1f mm, %.0f Hz", sc.a0_mm, sc.f0_hz);
    std::printf("%-22s %-6.0e | %8.0f %8.0f %9.3f | %8.0f %8.0f %9.3f | %6.2fx  %.2g\n", label, sc.rtol,
                se.rhs_evals / kSimSeconds, (se.accepted + se.rejected) / kSimSeconds, 1e3 * we / 3,
                si.rhs_evals / kSimSeconds, (si.accepted + si.rejected) / kSimSeconds, 1e3 * wi / 3, we / wi,
                1e3 * std::fabs(xe[0] - xi[0]));
  }
  std::printf("wall = dopri5 time / rosenbrock23 time (> 1: the implicit method is faster)\n");
  return 0;
}
