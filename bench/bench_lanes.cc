// Series chains and the dimensional rig in lanes (dynamics/ensemble_generic.h) against the cell
// kernel (RunKernel<W> on the coupled model, state 4 + tangent 4) and against the one-point-at-a-time
// path they replaced (RunGenericWindow: Eigen state, rk4.h or Dormand–Prince), all in one process,
// interleaved, so the ratios share whatever load the machine has. Kernel and window recorder only
// (no metric finalisation). Lane-steps: RK4 steps × lanes (the rig's substeps count as steps).
// The lanes run W = kSweepLanes wide, the engine's lane width (8 on AVX-512, 4 on AVX2; fixed at
// compile time), over the same 8 points on every machine (blocks of W, as a sweep runs them); the first
// line of the output says W, the ISA and the CPU (dynamics/host_lanes.h).
//   build/bench/bench_lanes [rounds]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "dynamics/eigen_bounds.h"
#include "dynamics/ensemble_generic.h"
#include "dynamics/generic_point.h"
#include "dynamics/host_lanes.h"
#include "dynamics/lanes.h"
#include "dynamics/point.h"

namespace bistable {
namespace {

constexpr int kW = kSweepLanes;  // the engine's width (dynamics/lanes.h)
constexpr int kPoints = 8;       // the points of each lane row, in blocks of kW
static_assert(kPoints % kW == 0);

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

KernelSettings Settings(double dt, double t_end) { return KernelSettings::Window(dt, t_end); }

// The cell kernel: coupled model + tangent, 8 points at Ω = 0.5, 0.6, ... (bench_kernel's block) in
// blocks of kW lanes.
double CoupledLaneSteps(int reps) {
  PointSpec s;
  s.model = ModelKind::kCoupled;
  s.alpha = 1.0;
  s.integration.t_end = 100;
  s.integration.t_keep = 50;
  KernelSettings ks = KernelSettingsFor(s);
  ks.keep_samples = false;
  std::vector<LaneInput> lanes(kPoints, LaneFor(s));
  for (int l = 0; l < kPoints; ++l) lanes[l].omega = 0.5 + 0.1 * l;
  std::vector<RawLane> out(kPoints);
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < reps; ++r)
    for (int b = 0; b < kPoints; b += kW) RunKernel<kW>(s.model, lanes.data() + b, kW, ks, out.data() + b);
  return static_cast<double>(reps) * kPoints * ks.n_total / Seconds(t0);
}

// Two bistable cells with resonators (state 8 + tangent 8), α = 1, Ω = 0.5, 0.6, ..., τ 0–100.
SeriesLaneInput SeriesLane(int l) {
  SeriesLaneInput in;
  in.cells.assign(2, SeriesCell{});
  in.omega = 0.5 + 0.1 * l;
  in.base_amp = 1.0;
  in.amp = in.base_amp * in.omega * in.omega;
  const Eigen::VectorXd x0 = SeriesModel(in.cells, in.base_amp, in.omega).WellState();
  in.x0.assign(x0.data(), x0.data() + x0.size());
  return in;
}
const KernelSettings kSeriesSettings = Settings(0.01, 100);

// The first `points` of the lane points (a multiple of W), in blocks of W lanes.
template <int W>
double SeriesLaneSteps(int points, int reps) {
  std::vector<SeriesLaneInput> in;
  for (int l = 0; l < points; ++l) in.push_back(SeriesLane(l));
  std::vector<RawLane> out(points);
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < reps; ++r)
    for (int b = 0; b < points; b += W) RunSeriesLanes<W>(in.data() + b, W, kSeriesSettings, out.data() + b);
  return static_cast<double>(reps) * points * kSeriesSettings.n_total / Seconds(t0);
}

double SeriesGenericSteps(int points) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int p = 0; p < points; ++p) {
    const SeriesLaneInput in = SeriesLane(p % kPoints);
    SeriesModel m(in.cells, in.base_amp, in.omega);
    GenericWindow w;
    w.t_end = 100, w.t_keep = 50, w.dt = 0.01, w.keep_samples = false;
    w.amp = in.base_amp, w.omega = in.omega;
    w.position = [](const Eigen::VectorXd& x) { return x[4] - x[0]; };
    w.velocity = [](const Eigen::VectorXd& x) { return x[5]; };
    RunGenericWindow(m, m.WellState(), w);
  }
  return static_cast<double>(points) * kSeriesSettings.n_total / Seconds(t0);
}

// The rig (Table 2, bistable, friction at the paper's v_sp, v_t), 8 points from sticking to sliding:
// A0 = 0.5 … 11 mm, f0 = 2 … 5.5 Hz, t 0–2 s, output step 1 ms.
// kRigFree: the same rig with both bodies frictionless (F_s = F_c = 0: the law is skipped).
const DimensionalParams kRig = DimensionalParams::BistableTable2();
const DimensionalParams kRigFree = [] {
  DimensionalParams p = DimensionalParams::BistableTable2();
  p.fric_m = p.fric_r = Stribeck{0, 0};
  return p;
}();
const KernelSettings kRigSettings = Settings(1e-3, 2.0);
DimensionalLaneInput RigLane(int l, const DimensionalParams& rig = kRig) {
  DimensionalLaneInput in;
  in.params = rig;
  in.base_amp = (0.5 + 1.5 * l) * 1e-3;
  in.omega = 2 * M_PI * (2.0 + 0.5 * l);
  in.amp = in.base_amp * in.omega * in.omega;
  in.x0[0] = std::sqrt(-kRig.k_lin / kRig.k3);
  return in;
}

// The first `points` rig points (a multiple of W) in blocks of W lanes. Returns lane-steps/s; *sim adds
// simulated seconds per wall second.
template <int W>
double RigLaneSteps(int points, int reps, int substeps, double* sim, const DimensionalParams& rig = kRig) {
  std::vector<DimensionalLaneInput> in;
  for (int l = 0; l < points; ++l) in.push_back(RigLane(l, rig));
  std::vector<RawLane> out(points);
  const auto t0 = std::chrono::steady_clock::now();
  for (int r = 0; r < reps; ++r)
    for (int b = 0; b < points; b += W)
      RunDimensionalLanes<W>(in.data() + b, W, kRigSettings, substeps, out.data() + b);
  const double sec = Seconds(t0);
  *sim += reps * points * 2.0 / sec;
  return static_cast<double>(reps) * points * kRigSettings.n_total * substeps / sec;
}

// One point at a time: rk4.h at the lanes' step (output every step), or Dormand–Prince (the rig's
// default integrator, rtol 1e-6, atol 1e-9, as the sweep spec sets). Simulated seconds per wall second.
double RigGenericSim(int points, bool adaptive, int substeps) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int p = 0; p < points; ++p) {
    const DimensionalLaneInput in = RigLane(p % kPoints);
    DimensionalModel m(kRig, SineBase(in.base_amp, in.omega / (2 * M_PI)));
    GenericWindow w;
    w.t_end = 2.0, w.t_keep = 1.0, w.dt = 1e-3 / (adaptive ? 1 : substeps), w.keep_samples = false;
    w.adaptive = adaptive;
    w.tol.rtol = 1e-6, w.tol.atol = 1e-9;
    w.amp = in.base_amp, w.omega = in.omega;
    w.renorm_every = 50 * (adaptive ? 1 : substeps);
    w.position = [](const Eigen::VectorXd& x) { return x[0]; };
    w.velocity = [](const Eigen::VectorXd& x) { return x[1]; };
    BISTABLE_EIGEN_BOUNDS_BEGIN
    RunGenericWindow(m, Eigen::Map<const Eigen::Vector4d>(in.x0.data()), w);
    BISTABLE_EIGEN_BOUNDS_END
  }
  return points * 2.0 / Seconds(t0);
}

}  // namespace
}  // namespace bistable

int main(int argc, char** argv) {
  using namespace bistable;
  const int rounds = argc > 1 ? std::atoi(argv[1]) : 3;
  std::printf("%s\n", HostLanesLine().c_str());
  std::fflush(stdout);
  const int substeps = Rk4Substeps(kRig, kRigSettings.h), free_substeps = Rk4Substeps(kRigFree, kRigSettings.h);
  double coupled = 0, series_w = 0, series1 = 0, series_old = 0, rig_w = 0, rig1 = 0, sim_w = 0, sim1 = 0,
         rig_rk4_old = 0, rig_dp5_old = 0, free_w = 0, free_sim_same_h = 0, free_sim = 0;
  for (int r = 0; r < rounds; ++r) {
    coupled += CoupledLaneSteps(8);
    series_w += SeriesLaneSteps<kW>(kPoints, 4);
    series1 += SeriesLaneSteps<1>(1, 8);
    series_old += SeriesGenericSteps(8);
    rig_w += RigLaneSteps<kW>(kPoints, 1, substeps, &sim_w);
    free_w += RigLaneSteps<kW>(kPoints, 1, substeps, &free_sim_same_h, kRigFree);
    RigLaneSteps<kW>(kPoints, 4, free_substeps, &free_sim, kRigFree);
    rig1 += RigLaneSteps<1>(1, 2, substeps, &sim1);
    rig_rk4_old += RigGenericSim(2, false, substeps);
    rig_dp5_old += RigGenericSim(2, true, substeps);
  }
  const double k = 1.0 / rounds, M = 1e-6;
  coupled *= k, series_w *= k, series1 *= k, series_old *= k, rig_w *= k, rig1 *= k, sim_w *= k, sim1 *= k;
  rig_rk4_old *= k, rig_dp5_old *= k, free_w *= k, free_sim_same_h *= k, free_sim *= k;
  std::printf("lane-steps/s per core, mean of %d interleaved rounds (RK4 steps x lanes, kernel + window recorder)\n",
              rounds);
  std::printf("  cell kernel, coupled + tangent (state 4+4), %d lanes          %8.1f M/s   1\n", kW, coupled * M);
  std::printf("  series N=2 + tangent (state 8+8), %d lanes                    %8.1f M/s   %.2fx cell kernel\n", kW,
              series_w * M, series_w / coupled);
  std::printf("  series N=2, 1 lane (the one-point path)                      %8.1f M/s   %.2fx\n", series1 * M,
              series1 / coupled);
  std::printf("  series N=2, old per-point path (Eigen, rk4.h, generic_point)  %8.1f M/s   lanes %.1fx faster\n",
              series_old * M, series_w / series_old);
  std::printf(
      "  rig (Table 2, friction) + tangent (state 4+4), %d lanes       %8.1f M/s   %.2fx cell kernel"
      "   (%d substeps per 1 ms: h = %.3g s)\n",
      kW, rig_w * M, rig_w / coupled, substeps, 1e-3 / substeps);
  std::printf("  rig, 1 lane (the one-point path)                             %8.1f M/s   %.2fx\n", rig1 * M,
              rig1 / coupled);
  std::printf(
      "  rig without friction (F_s = F_c = 0, law skipped), %d lanes   %8.1f M/s   %.2fx cell kernel"
      "   (same h)\n",
      kW, free_w * M, free_w / coupled);
  std::printf("simulated seconds per wall second, rig, per core:\n");
  std::printf("  %d lanes, RK4 at h = %.3g s                                   %8.1f\n", kW, 1e-3 / substeps, sim_w);
  std::printf("  1 lane                                                       %8.1f\n", sim1);
  std::printf("  %d lanes without friction, same h / its own h = %.3g s         %8.1f / %.1f\n", kW,
              1e-3 / free_substeps, free_sim_same_h, free_sim);
  std::printf("  old per-point path, rk4.h at the same h                      %8.1f   lanes %.1fx faster\n",
              rig_rk4_old, sim_w / rig_rk4_old);
  std::printf("  old per-point path, Dormand-Prince rtol 1e-6 (the default)   %8.1f   lanes %.1fx faster\n",
              rig_dp5_old, sim_w / rig_dp5_old);
  return 0;
}
