// Identification's RK4 substeps on the snap-through rig with friction on both bodies (the bistable coupled family,
// 14 mm chirp 1–8 Hz, 120 Hz, 0.05 mm noise): the output's error on 0.125 s segments (the shooting objective's
// horizon, from the same measured states) at StableSubsteps, AccurateSubsteps, SubstepsFor and 1.5× SubstepsFor
// (a fit's held steps), against RK4 at 8× SubstepsFor, as a percentage of the output's RMS beside the record's
// noise in the same unit; and the time of a simulation with sensitivities over the time at SubstepsFor (< 1:
// faster). Rows for the truth, its friction forces ×4 (a declared fit's sticking friction) and without friction.
// The first line says the CPU.
//   build/bench/bench_identify_steps [REPETITIONS]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "bench/bench_timing.h"
#include "dynamics/host_lanes.h"
#include "identify/model.h"
#include "identify/synthetic.h"

using namespace bistable;
using bistable_bench::Seconds;

namespace {

// RMS over the record of a − b on the main output, as a percentage of the reference's RMS (NaN samples skipped).
double ErrorPercent(const std::vector<double>& a, const std::vector<double>& ref) {
  double se = 0, mean = 0, ss = 0;
  size_t n = 0;
  for (size_t i = 0; i < ref.size(); ++i)
    if (std::isfinite(a[i]) && std::isfinite(ref[i])) se += (a[i] - ref[i]) * (a[i] - ref[i]), mean += ref[i], ++n;
  if (n == 0) return NAN;
  mean /= static_cast<double>(n);
  for (size_t i = 0; i < ref.size(); ++i)
    if (std::isfinite(ref[i])) ss += (ref[i] - mean) * (ref[i] - mean);
  return 100.0 * std::sqrt(se / ss);
}

}  // namespace

int main(int argc, char** argv) {
  const int reps = argc > 1 ? std::max(1, std::atoi(argv[1])) : 3;
  std::printf("%s\n", HostLanesLine().c_str());
  const DimensionalParams p = DimensionalParams::BistableTable2();
  SyntheticOptions o;
  o.a0_m = 0.014, o.f_end_hz = 8, o.duration_s = 30, o.seed = 18;
  o.noise_m = o.input_noise_m = 0.05e-3;
  o.y0_m = std::sqrt(-p.k_lin / p.k3);
  auto rec = MakeSyntheticRecord(p, o, "coupled 14 mm");
  if (!rec.ok()) return std::fprintf(stderr, "error: %s\n", rec.status().ToString().c_str()), 1;
  const Setup setup;
  auto r = PrepareRecord(*rec, setup, 0, rec->t.size(), 0.0, rec->name);
  if (!r.ok()) return std::fprintf(stderr, "error: %s\n", r.status().ToString().c_str()), 1;
  const int every = static_cast<int>(std::lround(0.125 / r->dt));
  std::printf("record: %s, %zu samples at %.0f Hz, noise %.3f %% of the output's RMS; segments of %d samples\n",
              rec->name.c_str(), r->n(), 1.0 / r->dt, 100.0 * r->noise[0] / r->meas_scale, every);
  std::printf("%-12s %-16s %6s %10s %11s\n", "model", "substeps", "count", "error_%", "time_ratio");
  for (const double friction_scale : {1.0, 4.0, 0.0}) {
    IdentModel m = TruthModel(p, {});
    const std::vector<std::string> names = m.ParamNames();
    for (size_t j = 0; j < names.size(); ++j)
      if (names[j].find(".friction.") != std::string::npos) m.theta[j] *= friction_scale;
    const int full = SubstepsFor(m, m.theta, *r);
    // Every row restarts its segments from the same (measured) states.
    const size_t nseg = NumSegments(r->n(), every);
    std::vector<double> states(nseg * kStateDim, 0.0);
    for (size_t k = 0; k < nseg; ++k) {
      const auto x = MeasuredState(m, m.theta, *r, setup, k * static_cast<size_t>(every));
      std::copy(x.begin(), x.end(), states.begin() + static_cast<long>(k * kStateDim));
    }
    const SegmentStates seg{&states, true, true, nullptr};
    SimOutputs ref;
    if (!SimulateOutputs(m, m.theta, {}, *r, setup, 8 * full, every, true, &ref, nullptr, &seg))
      return std::fprintf(stderr, "error: the reference diverged\n"), 1;
    const char* model = friction_scale == 1.0 ? "truth" : friction_scale == 4.0 ? "friction x4" : "no friction";
    double t_full = 0;
    auto row = [&](const char* what, int n) {
      SimOutputs so;
      bool ok = true;
      double t = 1e300;
      for (int i = 0; i < reps; ++i)
        t = std::min(
            t, Seconds([&] { ok = SimulateOutputs(m, m.theta, {}, *r, setup, n, every, true, &so, nullptr, &seg); }));
      if (t_full == 0) t_full = t;
      std::printf("%-12s %-16s %6d %10.4f %11.3f%s\n", model, what, n, ok ? ErrorPercent(so.out[0], ref.out[0]) : NAN,
                  t / t_full, ok ? "" : "  (diverged)");
    };
    row("SubstepsFor", full);
    row("StableSubsteps", StableSubsteps(m, m.theta, *r));
    row("AccurateSubsteps", AccurateSubsteps(m, m.theta, *r));
    row("1.5 x SubstepsFor", (3 * full + 1) / 2);
  }
  return 0;
}
