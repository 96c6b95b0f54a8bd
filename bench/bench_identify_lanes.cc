// Identification's plain simulations one by one against the same simulations side by side in SIMD lanes
// (SimulateOutputsLanes, the spectral objective's forward-difference columns): for 2, 4 and 8 lanes, the time
// of L scalar simulations over the time of one pack of L, alternating in one run (min of the repetitions), on
// a 20 s synthetic record of the paper's rig (120 Hz) with a Duffing model and with the rig's friction model.
// Prints ratios (> 1: the lanes are faster); the machine's absolute speed drifts, the ratio less.
// The widths are identification's pack sizes (2, 4, 8: it packs up to kMaxSimLanes columns whatever the
// CPU), so all three run; the first line says the CPU and the engine's lane width W (dynamics/host_lanes.h),
// and a row wider than W is marked: its packs span several registers.
//   build/bench/bench_identify_lanes [REPETITIONS]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "bench/bench_timing.h"
#include "dynamics/host_lanes.h"
#include "dynamics/lanes.h"
#include "identify/model.h"
#include "identify/synthetic.h"

using namespace bistable;
using bistable_bench::Seconds;

namespace {}  // namespace

int main(int argc, char** argv) {
  const int reps = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  std::printf("%s\n", HostLanesLine().c_str());
  DimensionalParams p = DimensionalParams::LinearTable2();
  p.has_resonator = false;
  SyntheticOptions o;
  o.a0_m = 0.010;
  auto rec = MakeSyntheticRecord(p, o, "chirp 10 mm");
  if (!rec.ok()) return std::fprintf(stderr, "error: %s\n", rec.status().ToString().c_str()), 1;
  const Setup setup;
  auto r = PrepareRecord(*rec, setup, 0, rec->t.size(), 0.0, rec->name);
  if (!r.ok()) return std::fprintf(stderr, "error: %s\n", r.status().ToString().c_str()), 1;
  struct Case {
    const char* name;
    const char* terms;
    std::vector<double> theta;
  } cases[] = {{"duffing", "main.linear,main.stiffness_y3,main.viscous", {484.9, 1e5, 3.2}},
               {"friction", "main.linear,main.viscous,main.damping_y2,main.friction", {484.9, 3.2, 8.9e3, 1.2, 0.65}}};
  std::printf("%-9s %5s %9s %12s %12s %8s\n", "model", "lanes", "substeps", "scalar_s", "lanes_s", "ratio");
  for (const Case& c : cases) {
    IdentModel m;
    m.terms = *ParseTerms(c.terms);
    m.m_main = 0.282;
    m.theta = c.theta;
    const int sub = SubstepsFor(m, m.theta, *r);
    for (int lanes : {2, 4, 8}) {
      std::vector<std::vector<double>> ths(static_cast<size_t>(lanes), m.theta);
      for (int l = 0; l < lanes; ++l)
        ths[static_cast<size_t>(l)][static_cast<size_t>(l) % m.theta.size()] *= 1.0 + 1e-6 * l;
      std::vector<const std::vector<double>*> ptrs;
      for (const auto& th : ths) ptrs.push_back(&th);
      double best_scalar = 1e300, best_lanes = 1e300;
      bool ok = true;
      for (int k = 0; k < reps; ++k) {
        best_scalar = std::min(best_scalar, Seconds([&] {
                                 for (const auto& th : ths) {
                                   SimOutputs so;
                                   ok = SimulateOutputs(m, th, {}, *r, setup, sub, 0, false, &so) && ok;
                                 }
                               }));
        best_lanes = std::min(best_lanes, Seconds([&] {
                                std::vector<SimOutputs> outs;
                                ok = SimulateOutputsLanes(m, ptrs, *r, setup, sub, &outs) && ok;
                              }));
      }
      if (!ok) return std::fprintf(stderr, "error: a simulation failed\n"), 1;
      std::printf("%-9s %5d %9d %12.4f %12.4f %8.2f%s\n", c.name, lanes, sub, best_scalar, best_lanes,
                  best_scalar / best_lanes, lanes > kSweepLanes ? "   (wider than the CPU's lanes)" : "");
    }
  }
  return 0;
}
