#include "dynamics/point.h"
#include "dynamics/settle.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

#include "dynamics/cancel.h"
#include "dynamics/dopri5.h"
#include "dynamics/eigen_bounds.h"
#include "dynamics/nondim_system.h"

namespace bistable {
namespace {

// The adaptive path: Dormand–Prince 5(4) on (x, w, q), sampled at τ = n·dt by dense output and fed
// to the same WindowRecorder as the kernel. The tangent is renormalised every renorm_every·dt
// (integration restarts there), the quadratures run only inside the window. Cancellation is polled
// after every accepted step; a cancelled run sets *cancelled and returns no record.
template <class Model>
RawLane RunAdaptive(const PointSpec& spec, bool* cancelled) {
  constexpr int D = Model::kDim;
  using Aug = AugmentedNondimSystem<Model>;
  const LaneInput lane = LaneFor(spec);
  const KernelSettings ks = KernelSettingsFor(spec);
  Aug sys(lane.coeffs, lane.alpha, lane.omega);
  typename Aug::State z = Aug::State::Zero(sys.dim());
  for (int d = 0; d < D; ++d) z[d] = lane.x0[d], z[D + d] = (d % 2 == 0 ? 1.0 : -1.0) / std::sqrt(double(D));

  AdaptiveOptions opt;
  opt.rtol = spec.integration.rtol;
  opt.atol = spec.integration.atol;
  opt.h_max = ks.h * ks.renorm_every;
  Dopri5<Aug> stepper(sys, opt);
  WindowRecorder<D, 1> rec(&lane.alpha, &lane.omega, ks.h, ks.n_keep, ks.sample_every, ks.keep_samples, ks.keep_rows,
                           ks.strobe_phase);
  const CellCoeffs<Vec<1>> c1{{lane.coeffs.k_lin}, {lane.coeffs.eps}, {lane.coeffs.eta},
                              {lane.coeffs.eta_r}, {lane.coeffs.phi}, {lane.coeffs.lambda2}};
  RawLane raw;
  Vec<1> xp[D], dp[D], x1[D], d1[D];
  long next_sample = ks.n_keep;
  typename Aug::State zi(sys.dim());
  auto sample = [&](long n, const typename Aug::State& zz) {
    const double t = static_cast<double>(n) * ks.h;
    for (int d = 0; d < D; ++d) x1[d][0] = zz[d];
    const Vec<1> f = {lane.alpha * lane.omega * lane.omega * std::sin(lane.omega * t)};
    Model::Rhs(c1, x1, f, d1);
    const Vec<1> cs = {std::cos(lane.omega * t)};
    if (n == ks.n_keep) {
      rec.OnStep(n, x1, d1, x1, d1, cs);
      raw.e_start = Model::Energy(c1, x1)[0];
    } else {
      rec.OnStep(n, xp, dp, x1, d1, cs);
    }
    for (int d = 0; d < D; ++d) xp[d] = x1[d], dp[d] = d1[d];
  };
  auto observer = [&](const Dopri5<Aug>& st) {
    ThrowIfCancelled();
    while (next_sample <= ks.n_total && static_cast<double>(next_sample) * ks.h <= st.t() + 1e-12 * st.t()) {
      st.Interpolate(static_cast<double>(next_sample) * ks.h, zi);
      sample(next_sample++, zi);
    }
  };
  const auto ignore = [](const Dopri5<Aug>&) { ThrowIfCancelled(); };

  long seg_start = 0;
  bool diverged = false;
  try {
    while (seg_start < ks.n_total) {
      ThrowIfCancelled();
      long seg_end = std::min(seg_start + ks.renorm_every, ks.n_total);
      if (seg_start < ks.n_keep && seg_end > ks.n_keep) seg_end = ks.n_keep;
      const bool in_window = seg_start >= ks.n_keep;
      sys.set_window(in_window);
      const double t0 = static_cast<double>(seg_start) * ks.h, t1 = static_cast<double>(seg_end) * ks.h;
      if (seg_start == ks.n_keep) sample(ks.n_keep, z), next_sample = ks.n_keep + 1;
      const OdeTermination term =
          in_window ? stepper.Integrate(t0, z, t1, observer) : stepper.Integrate(t0, z, t1, ignore);
      if (term != OdeTermination::kOk || !std::isfinite(z[0]) || std::fabs(z[0]) > 1e8) {
        diverged = true;
        break;
      }
      const double nrm = z.segment(D, D).norm();
      BISTABLE_EIGEN_BOUNDS_BEGIN
      z.segment(D, D) /= nrm;
      BISTABLE_EIGEN_BOUNDS_END
      if (in_window) rec.AddLogGrowth(Vec<1>{std::log(nrm)});
      seg_start = seg_end;
    }
  } catch (const CancelUnwind&) {
    *cancelled = true;
    return RawLane{};
  }
  const double e_start = raw.e_start;
  raw = std::move(rec.Lane(0));
  raw.e_start = e_start;
  for (int d = 0; d < D; ++d) x1[d][0] = z[d];
  raw.e_end = Model::Energy(c1, x1)[0];
  raw.q_p = z[2 * D], raw.q_in = z[2 * D + 1], raw.q_m = z[2 * D + 2], raw.q_r = z[2 * D + 3];
  raw.diverged = diverged;
  for (int d = 0; d < D; ++d) raw.final_state[d] = z[d];
  raw.steps = stepper.summary().accepted;
  raw.rhs_evals = stepper.summary().rhs_evals;
  return raw;
}

}  // namespace

LaneInput LaneFor(const PointSpec& spec) {
  LaneInput in;
  const bool bistable = IsBistable(spec.model), res = HasResonator(spec.model);
  in.coeffs.k_lin = bistable ? -1.0 : 1.0;
  in.coeffs.eps = bistable ? spec.params.eps : 0.0;
  in.coeffs.eta = spec.params.eta;
  in.coeffs.eta_r = res ? spec.params.eta_r : 0.0;
  in.coeffs.phi = res ? spec.params.phi : 0.0;
  in.coeffs.lambda2 = res ? spec.params.lambda * spec.params.lambda : 0.0;
  in.alpha = spec.alpha;
  in.omega = spec.omega;
  in.x0 = InitialState(spec);
  return in;
}

KernelSettings KernelSettingsFor(const PointSpec& spec) {
  KernelSettings k;
  k.h = spec.integration.dt;
  k.n_total = StepsFor(spec.integration.t_end, spec.integration.dt);
  k.n_keep = StepsFor(spec.integration.t_keep, spec.integration.dt);
  k.renorm_every = spec.metrics.renorm_every;
  k.sample_every = spec.metrics.sample_every;
  k.keep_samples = true;
  k.keep_rows = spec.metrics.keep_samples;
  k.strobe_phase = spec.metrics.poincare_phase;
  return k;
}

double KaplanYorkeDimension(std::vector<double> e) {
  std::sort(e.begin(), e.end(), std::greater<double>());
  double partial = 0;
  for (size_t j = 0; j < e.size(); ++j) {
    if (partial + e[j] < 0) return j == 0 ? 0.0 : static_cast<double>(j) + partial / std::fabs(e[j]);
    partial += e[j];
  }
  return static_cast<double>(e.size());
}

StatusOr<LyapunovSpectrum> EvaluateLyapunovSpectrum(const PointSpec& spec) {
  BISTABLE_RETURN_IF_ERROR(ValidatePointSpec(spec));
  if (spec.integration.integrator != IntegratorKind::kRk4)
    return Status::InvalidArgument("integrator", std::string("integrator = '") +
                                                     IntegratorName(spec.integration.integrator) +
                                                     "' violates the Lyapunov spectrum's integrator = 'rk4'");
  const LaneInput lane = LaneFor(spec);
  const KernelSettings ks = KernelSettingsFor(spec);
  const double window = spec.integration.t_end - spec.integration.t_keep;
  double sums[4] = {};
  bool diverged = false;
  const bool res = HasResonator(spec.model);
  const bool done = res ? EnsembleRk4<CoupledModel, 1>::RunSpectrum(lane, ks, sums, &diverged)
                        : EnsembleRk4<SingleModel, 1>::RunSpectrum(lane, ks, sums, &diverged);
  if (!done) return CancelledStatus();
  LyapunovSpectrum out;
  const int dim = res ? 4 : 2;
  out.diverged = diverged;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int j = 0; j < dim; ++j) out.exponents.push_back(diverged ? nan : sums[j] / window);
  for (double e : out.exponents) out.sum += e;
  const CellCoeffs<double>& c = lane.coeffs;
  out.divergence = -(c.eta + c.phi * c.eta_r + c.eta_r);
  std::vector<double> flow = out.exponents;
  flow.push_back(0.0);  // the forcing phase's direction
  out.kaplan_yorke = diverged ? nan : KaplanYorkeDimension(flow);
  return out;
}

StatusOr<PointResult> EvaluatePoint(const PointSpec& spec) {
  BISTABLE_RETURN_IF_ERROR(ValidatePointSpec(spec));
  if (spec.integration.labels == LabelMode::kSettled) {  // one lane of the chain sweeps run (settle.h)
    PointResult r;
    if (!EvaluateSettled<1>(&spec, 1, &r)) return CancelledStatus();
    return r;
  }
  if (spec.integration.integrator == IntegratorKind::kRosenbrock)
    return Status::InvalidArgument("integrator",
                                   "integrator = 'rosenbrock' is for the rig's maps (model = 'dimensional'); "
                                   "points of the cell models use 'rk4' or 'adaptive'");
  RawLane raw;
  bool cancelled = false;
  if (spec.integration.integrator == IntegratorKind::kRk4) {
    const LaneInput lane = LaneFor(spec);
    cancelled = !RunKernel<1>(spec.model, &lane, 1, KernelSettingsFor(spec), &raw);
  } else if (HasResonator(spec.model)) {
    raw = RunAdaptive<CoupledModel>(spec, &cancelled);
  } else {
    raw = RunAdaptive<SingleModel>(spec, &cancelled);
  }
  if (cancelled) return CancelledStatus();
  return ComputePointMetrics(std::move(raw), spec);
}

}  // namespace bistable
