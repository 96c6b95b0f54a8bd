// The lane kernel for the models outside the cell kernel (series chains, the dimensional rig):
// fixed-step RK4 of up to W sweep points side by side (one point per lane), with one tangent vector
// per lane (Benettin), the forcing phase advanced by exact rotation and re-anchored every kReanchor
// steps (as in ensemble_rk4.h), and an "output cell" — a position, its velocity and the base motion —
// fed to the same WindowRecorder and metric code as every other path. No energy quadratures (the
// ratios are not defined for these models; they stay NaN).
//
// A model M provides
//   M::kDim                 state size, or 0 when it is known only at run time (M::Lanes::dim())
//   M::Input                one lane's inputs: amp, omega (forcing f = amp sin(omega t) per unit mass),
//                           base_amp (base displacement amplitude, for the absolute velocity of the FRF),
//                           x0 (initial state) and the model's own coefficients
//   M::Lanes<W>             lane packs of the coefficients: constructed from lane 0 (the structure all
//                           lanes share), Load(l, input) per lane, and
//     Jac                   the state-dependent Jacobian entries one evaluation leaves behind
//     Eval(x, f, dx, &jac)  dx = F(x, f) and the entries of J(x)
//     Apply(jac, w, dw)     dw = J(x) w
//     Output(x, dx, o, do)  the output cell (position, velocity) and its time derivative
// Eval and Apply run per lane with the plain IEEE operations of lanes.h; transcendental terms (the
// Stribeck law's exp and tanh) call the scalar std:: functions lane by lane, so a point's bits do not
// depend on W or its neighbours: the one-point path is this kernel at W = 1.
//
// Stiff models take `substeps` RK4 steps per output step (h = dt / substeps); the recorder, the
// renormalisation and the window count output steps. Cancellation is polled every kReanchor RK4 steps.
#ifndef BISTABLE_DYNAMICS_ENSEMBLE_GENERIC_H_
#define BISTABLE_DYNAMICS_ENSEMBLE_GENERIC_H_

#include <cmath>
#include <limits>
#include <vector>

#include "dynamics/cancel.h"
#include "dynamics/dimensional_model.h"
#include "dynamics/ensemble_rk4.h"
#include "dynamics/lane_buf.h"
#include "dynamics/lanes.h"
#include "dynamics/series_model.h"
#include "dynamics/window_recorder.h"

namespace bistable {

template <class Model, int W>
class EnsembleGeneric {
 public:
  using V = Vec<W>;
  using Input = typename Model::Input;
  using Lanes = typename Model::template Lanes<W>;
  using Jac = typename Lanes::Jac;
  static constexpr int kD = Model::kDim;
  static constexpr long kReanchor = kCancelCheckSteps;

  // Integrates in[0..n) (1 ≤ n ≤ W; unused lanes repeat lane 0) with `substeps` RK4 steps per output
  // step s.h, and fills out[0..n). False when cancellation was requested before the end: out[0..n)
  // then hold no result and must be discarded.
  static bool Run(const Input* in, int n, const KernelSettings& s, int substeps, RawLane* out) {
    Lanes m(in[0]);
    const int dim = kD > 0 ? kD : m.dim();
    State st(dim, m);
    double base_amp[W], omega[W];
    V amp, rot_c, rot_s;
    const double h = s.h / substeps;
    for (int l = 0; l < W; ++l) {
      const Input& li = in[l < n ? l : 0];
      m.Load(l, li);
      base_amp[l] = li.base_amp;
      omega[l] = li.omega;
      amp[l] = li.amp;
      rot_c[l] = std::cos(0.5 * li.omega * h);
      rot_s[l] = std::sin(0.5 * li.omega * h);
      for (int d = 0; d < dim; ++d) {
        st.x[d][l] = li.x0[d];
        // Fixed, generic initial tangent direction (as the cell kernel's).
        st.w[d][l] = 1.0 / std::sqrt(static_cast<double>(dim)) * (d % 2 == 0 ? 1.0 : -1.0);
      }
    }
    WindowRecorder<2, W> rec(base_amp, omega, s.h, s.n_keep, s.sample_every, s.keep_samples, s.keep_rows);
    V sn, cs;
    Anchor(omega, 0, h, &sn, &cs);
    m.Eval(st.x.data(), amp * sn, st.k1.data(), &st.j1);
    V prev[2], dprev[2];
    auto record = [&](long k) {
      V cur[2], dcur[2];
      m.Output(st.x.data(), st.k1.data(), cur, dcur);
      if (k == s.n_keep) rec.OnStep(k, cur, dcur, cur, dcur, cs);
      else rec.OnStep(k, prev, dprev, cur, dcur, cs);
      prev[0] = cur[0], prev[1] = cur[1], dprev[0] = dcur[0], dprev[1] = dcur[1];
    };
    bool diverged[W] = {};
    long step = 0;  // RK4 steps
    if (s.n_keep == 0) record(0);
    for (long k = 1; k <= s.n_total; ++k) {
      for (int sub = 0; sub < substeps; ++sub) {
        Step(m, dim, amp, rot_c, rot_s, h, st, &sn, &cs);
        if (++step % kReanchor == 0) {
          if (CancelRequested()) [[unlikely]] return Cancelled(n, step, out);
          Anchor(omega, step, h, &sn, &cs);
          m.Eval(st.x.data(), amp * sn, st.k1.data(), &st.j1);  // consistent with the re-anchored phase
        }
      }
      if (k >= s.n_keep) record(k);
      if (k % s.renorm_every == 0 || k == s.n_keep || k == s.n_total) {
        V lg;
        Renormalise(dim, st, &lg, diverged);
        if (k > s.n_keep) rec.AddLogGrowth(lg);
      }
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (int l = 0; l < n; ++l) {
      RawLane& r = rec.Lane(l);
      r.q_p = r.q_in = r.q_m = r.q_r = nan;
      r.e_start = r.e_end = nan;
      r.diverged = diverged[l];
      r.steps = step;
      r.rhs_evals = 4 * step;
      out[l] = std::move(r);
    }
    return true;
  }

 private:
  // State, tangent, the derivative at the step start and the stage scratch, sized once per run.
  struct State {
    State(int dim, const Lanes& m)
        : x(dim), w(dim), k1(dim), xs(dim), ws(dim), k(dim), l(dim), acc(dim), accw(dim), j1(m), j(m) {}
    LaneBuf<V, kD> x, w, k1, xs, ws, k, l, acc, accw;
    Jac j1, j;  // Jacobian entries at x (with k1) and at the current stage
  };

  [[gnu::cold, gnu::noinline]] static bool Cancelled(int n, long step, RawLane* out) {
    for (int l = 0; l < n; ++l) {
      out[l] = RawLane{};
      out[l].diverged = true;
      out[l].steps = step;
    }
    return false;
  }

  static void Anchor(const double* omega, long step, double h, V* sn, V* cs) {
    const double t = static_cast<double>(step) * h;
    for (int l = 0; l < W; ++l) {
      (*sn)[l] = std::sin(omega[l] * t);
      (*cs)[l] = std::cos(omega[l] * t);
    }
  }

  // One RK4 step of state and tangent. On entry k1 = F(x, f(t)) and j1 = J(x); on exit x, w advanced,
  // k1, j1 at the new x and f(t + h), (sn, cs) = (sin, cos)(Ω(t + h)). Stages are folded into running
  // sums as they are made (acc = ((k1 + 2k2) + 2k3) + k4), as in the cell kernel.
  static BISTABLE_INLINE void Step(const Lanes& m, int dim, V amp, V rot_c, V rot_s, double h, State& st, V* sn,
                                   V* cs) {
    const V s_mid = *sn * rot_c + *cs * rot_s, c_mid = *cs * rot_c - *sn * rot_s;
    const V s_end = s_mid * rot_c + c_mid * rot_s, c_end = c_mid * rot_c - s_mid * rot_s;
    const V fm = amp * s_mid, f1 = amp * s_end;
    const double hh = 0.5 * h, h6 = h / 6.0;
    m.Apply(st.j1, st.w.data(), st.l.data());
    for (int d = 0; d < dim; ++d) {
      st.acc[d] = st.k1[d], st.accw[d] = st.l[d];
      st.xs[d] = st.x[d] + hh * st.k1[d], st.ws[d] = st.w[d] + hh * st.l[d];
    }
    auto mid_stage = [&](double next) BISTABLE_INLINE_LAMBDA {
      m.Eval(st.xs.data(), fm, st.k.data(), &st.j);
      m.Apply(st.j, st.ws.data(), st.l.data());
      for (int d = 0; d < dim; ++d) {
        st.acc[d] = st.acc[d] + 2.0 * st.k[d], st.accw[d] = st.accw[d] + 2.0 * st.l[d];
        st.xs[d] = st.x[d] + next * st.k[d], st.ws[d] = st.w[d] + next * st.l[d];
      }
    };
    mid_stage(hh);
    mid_stage(h);
    m.Eval(st.xs.data(), f1, st.k.data(), &st.j);
    m.Apply(st.j, st.ws.data(), st.l.data());
    for (int d = 0; d < dim; ++d) {
      st.x[d] = st.x[d] + h6 * (st.acc[d] + st.k[d]);
      st.w[d] = st.w[d] + h6 * (st.accw[d] + st.l[d]);
    }
    *sn = s_end;
    *cs = c_end;
    m.Eval(st.x.data(), f1, st.k1.data(), &st.j1);
  }

  // w ← w/|w|, lg = log|w|. A lane whose state or tangent is no longer finite (or whose state left any
  // physical range, |x| > 1e8) is flagged and reset so it cannot slow its neighbours.
  static void Renormalise(int dim, State& st, V* lg, bool* diverged) {
    V n2 = st.w[0] * st.w[0];
    for (int d = 1; d < dim; ++d) n2 = n2 + st.w[d] * st.w[d];
    for (int l = 0; l < W; ++l) {
      const double nrm = std::sqrt(n2[l]);
      (*lg)[l] = std::log(nrm);
      const double inv = 1.0 / nrm;
      bool bad = !std::isfinite(nrm);
      for (int d = 0; d < dim; ++d) {
        st.w[d][l] *= inv;
        bad |= !std::isfinite(st.x[d][l]) || std::fabs(st.x[d][l]) > 1e8;
      }
      if (bad) {
        diverged[l] = true;
        for (int d = 0; d < dim; ++d) st.x[d][l] = 0.0, st.w[d][l] = (d == 0);
      }
    }
  }
};

// The two lane runs, instantiated once in ensemble_generic.cc for W = 1 (one point), 4 and 8 (sweeps:
// kSweepLanes). Series chains of 1–4 cells get a compile-time layout, longer ones a run-time one.
// False when cancelled (out[0..n) then hold no result). s.h is the output step; series chains take
// one RK4 step per output step, the rig `substeps` (Rk4Substeps).
template <int W>
bool RunSeriesLanes(const SeriesLaneInput* in, int n, const KernelSettings& s, RawLane* out);
template <int W>
bool RunDimensionalLanes(const DimensionalLaneInput* in, int n, const KernelSettings& s, int substeps, RawLane* out);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ENSEMBLE_GENERIC_H_
