// A windowed point run for any System with a Jacobian (series chains, the dimensional friction
// model): integrate state and tangent, renormalise the tangent (Benettin), and feed an "output
// cell" — a position, its velocity and the base motion — to the same WindowRecorder and metric code
// as the SIMD kernel. Metrics then come out in the system's own units (per time unit, rad per time
// unit, lengths of the state); energy ratios are not defined here and stay NaN.
// Cancellation (dynamics/cancel.h) is polled every kCancelCheckSteps RK4 steps, or after every
// accepted adaptive step; a cancelled run is no result (see RunGenericWindow).
#ifndef BISTABLE_DYNAMICS_GENERIC_POINT_H_
#define BISTABLE_DYNAMICS_GENERIC_POINT_H_

#include <cmath>
#include <functional>
#include <limits>

#include "dynamics/benettin.h"
#include "dynamics/cancel.h"
#include "dynamics/dopri5.h"
#include "dynamics/rk4.h"
#include "dynamics/window_recorder.h"

namespace bistable {

struct GenericWindow {
  double t_end = 500, t_keep = 250, dt = 0.01;  // run, window start, RK4 step / output grid
  bool adaptive = false;                        // Dormand–Prince with dense output instead of RK4
  AdaptiveOptions tol;
  int renorm_every = 50, sample_every = 5;
  bool keep_samples = true, keep_rows = false;
  double strobe_phase = 0;    // φ of the strobes τ_k = (φ + 2πk)/ω (Poincaré section, period)
  double amp = 1, omega = 1;  // base x0 = amp sin(omega t): absolute velocity = v_out + amp·omega·cos(omega t)
  // The output cell: its position and velocity as functions of the state (e.g. the last link's deflection).
  std::function<double(const Eigen::VectorXd&)> position, velocity;
};

// When cancellation stops the run early, *cancelled (if given) is set and the record returned is
// marked diverged with steps short of the run: it must be discarded, never stored (callers that pass
// no flag rely on CancelRequested() staying set, see cancel.h).
template <class System>
RawLane RunGenericWindow(const System& sys, const Eigen::VectorXd& x0, const GenericWindow& w,
                         bool* cancelled = nullptr) {
  const int n = sys.dim();
  const long n_total = std::lround(w.t_end / w.dt), n_keep = std::lround(w.t_keep / w.dt);
  TangentSystem<System> tan(sys);
  Eigen::VectorXd z(2 * n), zi(2 * n);
  z.head(n) = x0;
  const int td = TangentDims(sys, n);  // dimensional_model.h
  z.tail(n).setZero();
  z.tail(n).head(td).setConstant(1.0 / std::sqrt(static_cast<double>(td)));
  WindowRecorder<2, 1> rec(&w.amp, &w.omega, w.dt, n_keep, w.sample_every, w.keep_samples, w.keep_rows, w.strobe_phase);
  RawLane raw;
  Vec<1> xp[2], dp[2], x1[2], d1[2];
  typename System::State xs(n), dxs(n);
  // Output and its time derivative at grid step k (position' from a finite difference of the
  // position map along the flow: exact for the linear maps used here).
  auto sample = [&](long k, const Eigen::VectorXd& zz) {
    const double t = static_cast<double>(k) * w.dt;
    xs = zz.head(n);
    sys(t, xs, dxs);
    const Eigen::VectorXd xv = xs, dv = dxs;
    const double h = 1e-7;
    const double pos = w.position(xv), vel = w.velocity(xv);
    x1[0][0] = pos, x1[1][0] = vel;
    d1[0][0] = (w.position(xv + h * dv) - w.position(xv - h * dv)) / (2 * h);
    d1[1][0] = (w.velocity(xv + h * dv) - w.velocity(xv - h * dv)) / (2 * h);
    const Vec<1> cs = {std::cos(w.omega * t)};
    if (k == n_keep)
      rec.OnStep(k, x1, d1, x1, d1, cs);
    else
      rec.OnStep(k, xp, dp, x1, d1, cs);
    xp[0] = x1[0], xp[1] = x1[1], dp[0] = d1[0], dp[1] = d1[1];
  };
  bool diverged = false;
  long steps = 0, rhs = 0;
  auto stopped = [&](long at) {
    if (cancelled) *cancelled = true;
    RawLane none;
    none.diverged = true;
    none.steps = at;
    return none;
  };
  if (!w.adaptive) {
    Rk4<TangentSystem<System>> rk(tan);
    if (n_keep == 0) sample(0, z);
    for (long k = 1; k <= n_total && !diverged; ++k) {
      if (k % kCancelCheckSteps == 0 && CancelRequested()) [[unlikely]]
        return stopped(k);
      rk.Step(static_cast<double>(k - 1) * w.dt, z, w.dt);
      if (k >= n_keep) sample(k, z);
      if (k % w.renorm_every == 0 || k == n_keep || k == n_total) {
        const double nrm = z.tail(n).norm();
        if (!std::isfinite(nrm) || !z.head(n).allFinite()) diverged = true;
        z.tail(n) /= nrm;
        if (k > n_keep) rec.AddLogGrowth(Vec<1>{std::log(nrm)});
      }
    }
    steps = n_total;
    rhs = 4 * n_total;
  } else {
    Dopri5<TangentSystem<System>> dp5(tan, w.tol);
    long next = n_keep, seg = 0;
    auto observer = [&](const Dopri5<TangentSystem<System>>& st) {
      ThrowIfCancelled();
      while (next <= n_total && static_cast<double>(next) * w.dt <= st.t() * (1 + 1e-12)) {
        st.Interpolate(static_cast<double>(next) * w.dt, zi);
        sample(next++, zi);
      }
    };
    const auto transient = [](const Dopri5<TangentSystem<System>>&) { ThrowIfCancelled(); };
    try {
      while (seg < n_total && !diverged) {
        ThrowIfCancelled();
        long end = std::min(seg + w.renorm_every, n_total);
        if (seg < n_keep && end > n_keep) end = n_keep;
        if (seg == n_keep) sample(n_keep, z), next = n_keep + 1;
        const OdeTermination term =
            seg >= n_keep
                ? dp5.Integrate(static_cast<double>(seg) * w.dt, z, static_cast<double>(end) * w.dt, observer)
                : dp5.Integrate(static_cast<double>(seg) * w.dt, z, static_cast<double>(end) * w.dt, transient);
        const double nrm = z.tail(n).norm();
        if (term != OdeTermination::kOk || !std::isfinite(nrm) || !z.head(n).allFinite()) diverged = true;
        z.tail(n) /= nrm;
        if (seg >= n_keep) rec.AddLogGrowth(Vec<1>{std::log(nrm)});
        seg = end;
      }
    } catch (const CancelUnwind&) {
      return stopped(dp5.summary().accepted);
    }
    steps = dp5.summary().accepted;
    rhs = dp5.summary().rhs_evals;
  }
  raw = std::move(rec.Lane(0));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  raw.q_p = raw.q_in = raw.q_m = raw.q_r = nan;
  raw.e_start = raw.e_end = nan;
  raw.diverged = diverged;
  raw.steps = steps;
  raw.rhs_evals = rhs;
  return raw;
}

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_GENERIC_POINT_H_
