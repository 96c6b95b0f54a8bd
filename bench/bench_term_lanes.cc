// A term model in lanes against the hand-written rig kernel (issue 42): the paper's Table 2 rig as
// effect-library terms (TermModel::FromDimensional: linear, stiffness_y3, viscous, damping_y2, friction on
// each body), run by RunTermLanes, against the same rig run by RunDimensionalLanes — state 4 + tangent 4
// both, the same RK4 step (the rig's Rk4Substeps), the same points (A0 = 0.5 … 11 mm, f0 = 2 … 5.5 Hz,
// t 0–2 s, output step 1 ms, as bench_lanes), in one process, interleaved, so the ratio shares whatever load
// the machine has. Lane-steps: RK4 steps × lanes. Prints the CPU, ISA and lane width first
// (dynamics/host_lanes.h), then the ratio, then how far the two runs' window measures are apart per point
// (the operations differ: the term model sums θ φ term by term, the hand kernel factors its polynomial).
//   build/bench/bench_term_lanes [rounds]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "bench/bench_timing.h"
#include "dynamics/ensemble_generic.h"
#include "dynamics/host_lanes.h"
#include "dynamics/lanes.h"
#include "dynamics/term_model.h"

namespace bistable {
namespace {

constexpr int kW = kSweepLanes;
constexpr int kPoints = 16;
static_assert(kPoints % kW == 0);

KernelSettings Settings() { return KernelSettings::Window(1e-3, 2.0); }

double A0(int p) { return (0.5 + 0.7 * p) * 1e-3; }
double Omega(int p) { return 2 * M_PI * (2.0 + 0.23 * p); }

}  // namespace
}  // namespace bistable

int main(int argc, char** argv) {
  using namespace bistable;
  const int rounds = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  std::printf("%s\n", HostLanesLine().c_str());
  const DimensionalParams rig = DimensionalParams::BistableTable2();
  auto terms = TermModel::FromDimensional(rig);
  if (!terms.ok() || !ValidateTermModel(*terms).ok()) {
    std::fprintf(stderr, "bench_term_lanes: %s\n", terms.status().ToString().c_str());
    return 1;
  }
  const KernelSettings ks = Settings();
  const int substeps = Rk4Substeps(rig, ks.h);
  const double well = std::sqrt(-rig.k_lin / rig.k3);
  std::vector<DimensionalLaneInput> hand(kPoints);
  std::vector<TermLaneInput> term(kPoints);
  for (int p = 0; p < kPoints; ++p) {
    hand[p].params = rig;
    hand[p].base_amp = term[p].base_amp = A0(p);
    hand[p].omega = term[p].omega = Omega(p);
    hand[p].amp = term[p].amp = A0(p) * Omega(p) * Omega(p);
    hand[p].x0[0] = term[p].x0[0] = well;
    term[p].model = &*terms;
  }
  std::vector<RawLane> out_hand(kPoints), out_term(kPoints);
  double t_hand = 0, t_term = 0;
  for (int r = 0; r < rounds; ++r) {
    t_hand += bistable_bench::Seconds([&] {
      for (int b = 0; b < kPoints; b += kW) RunDimensionalLanes<kW>(&hand[b], kW, ks, substeps, &out_hand[b]);
    });
    t_term += bistable_bench::Seconds([&] {
      for (int b = 0; b < kPoints; b += kW) RunTermLanes<kW>(&term[b], kW, ks, substeps, &out_term[b]);
    });
  }
  const double steps = static_cast<double>(rounds) * kPoints * ks.n_total * substeps;
  std::printf(
      "lane-steps/s per core, %d interleaved rounds of %d rig points (RK4 %d substeps per 1 ms, state 4+4, "
      "%d lanes)\n",
      rounds, kPoints, substeps, kW);
  std::printf("  hand-written rig kernel (DimensionalLaneModel)   %8.2f M/s   1\n", steps / t_hand * 1e-6);
  std::printf("  term model of the same rig (TermLaneModel)       %8.2f M/s   %.3fx the hand kernel\n",
              steps / t_term * 1e-6, t_hand / t_term);
  std::printf(
      "window measures, term model vs hand kernel, per point (A0 mm, f0 Hz): rel. diff of max|v_abs|, "
      "y_max, LLE diff [1/s], wells\n");
  const double window_s = (ks.n_total - ks.n_keep) * ks.h;
  int same_wells = 0;
  double worst_v = 0;
  for (int p = 0; p < kPoints; ++p) {
    const RawLane &a = out_hand[p], &b = out_term[p];
    const double dv = std::fabs(b.vabs_max - a.vabs_max) / std::fabs(a.vabs_max);
    const double dy = std::fabs(b.y_max - a.y_max) / std::fabs(a.y_max);
    const double dl = (b.log_growth - a.log_growth) / window_s;
    const bool wa = a.y_min < 0 && a.y_max > 0, wb = b.y_min < 0 && b.y_max > 0;
    same_wells += wa == wb;
    worst_v = std::max(worst_v, dv);
    std::printf("  %5.2f %5.2f   %9.2e %9.2e %+9.2e   %s/%s\n", A0(p) * 1e3, Omega(p) / (2 * M_PI), dv, dy, dl,
                wa ? "interwell" : "intrawell", wb ? "interwell" : "intrawell");
  }
  std::printf("same well class on %d of %d points; largest rel. diff of max|v_abs| %.2e\n", same_wells, kPoints,
              worst_v);
  return 0;
}
