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
// Eval and Apply run per lane with the plain IEEE operations and exact fused multiply-adds of lanes.h;
// transcendental terms (the Stribeck law's exp and tanh) use the project's lane functions
// (lane_math.h), the same code at every width, so a point's bits do not depend on W or its
// neighbours: the one-point path is this kernel at W = 1.
//
// Stiff models take `substeps` RK4 steps per output step (h = dt / substeps); the recorder, the
// renormalisation, the re-anchoring and the window count output steps. The loop has the cell kernel's
// structure: ordinary output steps in a call-free loop (RunFast; the state copied into locals so the
// lane vectors stay in registers), the special ones (window start, strobes, renormalisation,
// re-anchoring with the cancellation poll every ≤ kReanchor RK4 steps, the end) in the general loop.
#ifndef BISTABLE_DYNAMICS_ENSEMBLE_GENERIC_H_
#define BISTABLE_DYNAMICS_ENSEMBLE_GENERIC_H_

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "dynamics/cancel.h"
#include "dynamics/dimensional_model.h"
#include "dynamics/ensemble_rk4.h"
#include "dynamics/lane_buf.h"
#include "dynamics/lane_run.h"
#include "dynamics/lanes.h"
#include "dynamics/ode.h"
#include "dynamics/series_model.h"
#include "dynamics/term_model.h"
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
    const int dim = Dim(m);
    State st(dim, m);
    Scratch sc(dim, m);  // the stage values of a run-time layout (kD = 0); fixed layouts keep them local
    double base_amp[W], omega[W];
    Consts k;
    k.h = s.h / substeps;
    k.substeps = substeps;
    for (int l = 0; l < W; ++l) {
      const Input& li = in[l < n ? l : 0];
      m.Load(l, li);
      base_amp[l] = li.base_amp;
      omega[l] = li.omega;
      k.amp[l] = li.amp;
      k.rot_c[l] = std::cos(0.5 * li.omega * k.h);
      k.rot_s[l] = std::sin(0.5 * li.omega * k.h);
      const int td = TangentDims(m, dim);
      for (int d = 0; d < dim; ++d) {
        st.x[d][l] = li.x0[d];
        // Fixed, generic initial tangent direction (as the cell kernel's), on the model's tangent components.
        st.w[d][l] = d < td ? 1.0 / std::sqrt(static_cast<double>(td)) * (d % 2 == 0 ? 1.0 : -1.0) : 0.0;
      }
    }
    WindowRecorder<2, W> rec(base_amp, omega, s.h, s.n_keep, s.sample_every, s.keep_samples, s.keep_rows,
                             s.strobe_phase);
    V sn, cs;
    AnchorPhase<W>(omega, 0, k.h, &sn, &cs);
    m.Eval(st.x.data(), k.amp * sn, st.k1.data(), &st.j1);
    // Re-anchoring (and the cancellation poll) at output steps, every ≤ kReanchor RK4 steps.
    const long reanchor = std::max<long>(1, kReanchor / substeps);
    bool diverged[W] = {};
    for (long step = 1; step <= s.n_total; ++step) {
      if (!s.keep_rows) {
        const long stop =
            NextSpecialStep(step, s.n_total, s.n_keep, reanchor, rec.next_due(), RoundUpTo(step, s.renorm_every));
        while (step < stop) {
          step = step > s.n_keep ? RunFast<true>(m, k, step, stop, &st, &sc, &sn, &cs, &rec)
                                 : RunFast<false>(m, k, step, stop, &st, &sc, &sn, &cs, &rec);
          if (rec.TurningPointBufferFull()) rec.FlushTurningPoints();
        }
      }
      V o0[2], d0[2], o1[2], d1[2];
      m.Output(st.x.data(), st.k1.data(), o0, d0);  // the step's start (strobes interpolate between both ends)
      if (step == s.n_keep + 1) rec.OnStep(s.n_keep, o0, d0, o0, d0, cs);
      OutputStep(m, dim, k, &st, &sc, &sn, &cs);
      if (step % reanchor == 0) {
        if (CancelRequested()) [[unlikely]]
          return MarkCancelled(n, step * substeps, out);
        AnchorPhase<W>(omega, step * substeps, k.h, &sn, &cs);
        m.Eval(st.x.data(), k.amp * sn, st.k1.data(), &st.j1);  // consistent with the re-anchored phase
      }
      if (step > s.n_keep) {
        m.Output(st.x.data(), st.k1.data(), o1, d1);
        rec.OnStep(step, o0, d0, o1, d1, cs);
      }
      if (step % s.renorm_every == 0 || step == s.n_keep || step == s.n_total) {
        V lg;
        Renormalise(dim, &st, step > s.n_keep ? &lg : nullptr, diverged);  // growth before the window is not used
        if (step > s.n_keep) rec.AddLogGrowth(lg);
      }
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const long rk4_steps = s.n_total * substeps;
    for (int l = 0; l < n; ++l) {
      RawLane& r = rec.Lane(l);
      r.q_p = r.q_in = r.q_m = r.q_r = nan;
      r.e_start = r.e_end = nan;
      r.diverged = diverged[l];
      r.steps = rk4_steps;
      r.rhs_evals = 4 * rk4_steps;
      out[l] = std::move(r);
    }
    return true;
  }

 private:
  struct Consts {
    V amp, rot_c, rot_s;
    double h;
    int substeps;
  };
  // State, tangent, and the derivative and Jacobian entries at x.
  struct State {
    State(int dim, const Lanes& m) : x(dim), w(dim), k1(dim), j1(m) {}
    LaneBuf<V, kD> x, w, k1;
    Jac j1;
  };
  // A step's stage points, stage values and running sums.
  struct Scratch {
    Scratch(int dim, const Lanes& m) : xs(dim), ws(dim), k(dim), l(dim), acc(dim), accw(dim), j(m) {}
    LaneBuf<V, kD> xs, ws, k, l, acc, accw;
    Jac j;
  };

  static BISTABLE_INLINE int Dim(const Lanes& m) {
    if constexpr (kD > 0) {
      return kD;
    } else {
      return m.dim();
    }
  }

  // Output steps [from, to), all ordinary (see NextSpecialStep); returns the next output step to do,
  // short of `to` when the recorder's turning-point buffer filled up. Not inlined, and with a fixed
  // layout the model, state and stage values copied into locals: the loop holds no call (a call
  // clobbers every vector register), so the lane vectors can stay in registers.
  template <bool kWindow>
  [[gnu::noinline]] static long RunFast(const Lanes& m, const Consts& kc, long from, long to, State* io, Scratch* sc_io,
                                        V* sn_io, V* cs_io, WindowRecorder<2, W>* rec) {
    if constexpr (kD > 0) {
      const Lanes mk = m;
      const Consts k = kc;
      State st = *io;
      Scratch sc(kD, mk);
      V sn = *sn_io, cs = *cs_io;
      const long step = FastLoop<kWindow>(mk, k, from, to, &st, &sc, &sn, &cs, rec);
      *io = st;
      *sn_io = sn, *cs_io = cs;
      return step;
    } else {
      return FastLoop<kWindow>(m, kc, from, to, io, sc_io, sn_io, cs_io, rec);
    }
  }

  template <bool kWindow>
  static BISTABLE_INLINE long FastLoop(const Lanes& m, const Consts& k, long from, long to, State* st, Scratch* sc,
                                       V* sn, V* cs, WindowRecorder<2, W>* rec) {
    const int dim = Dim(m);
    typename WindowRecorder<2, W>::Running r = rec->running();
    V* samples = kWindow ? rec->ReserveSamples(to - from) : nullptr;
    V o0[2], d0[2];
    if constexpr (kWindow) m.Output(st->x.data(), st->k1.data(), o0, d0);
    long step = from;
    while (step < to) {
      OutputStep(m, dim, k, st, sc, sn, cs);
      if constexpr (kWindow) {
        V o1[2], d1[2];
        m.Output(st->x.data(), st->k1.data(), o1, d1);
        if (!rec->Track(r, step++, o0[0], o0[1], o1, *cs, samples)) break;
        o0[0] = o1[0], o0[1] = o1[1];
      } else {
        ++step;
      }
    }
    if constexpr (kWindow) {
      rec->running() = r;
      rec->CommitSamples(samples);
    }
    return step;
  }

  // One output step: `substeps` RK4 steps.
  static BISTABLE_INLINE void OutputStep(const Lanes& m, int dim, const Consts& k, State* st, Scratch* sc, V* sn,
                                         V* cs) {
    for (int sub = 0; sub < k.substeps; ++sub) {
      if constexpr (kD > 0) {
        Scratch local(kD, m);
        Step(m, dim, k, st, &local, sn, cs);
      } else {
        Step(m, dim, k, st, sc, sn, cs);
      }
    }
  }

  // One RK4 step of state and tangent. On entry k1 = F(x, f(t)) and j1 = J(x); on exit x, w advanced,
  // k1, j1 at the new x and f(t + h), (sn, cs) = (sin, cos)(Ω(t + h)). Stages are folded into running
  // sums as they are made (acc = ((k1 + 2k2) + 2k3) + k4, each "+ 2k" and x + h/6·acc one fused
  // multiply-add), as in the cell kernel.
  static BISTABLE_INLINE void Step(const Lanes& m, int dim, const Consts& kc, State* st_p, Scratch* sc_p, V* sn,
                                   V* cs) {
    State& st = *st_p;
    Scratch& sc = *sc_p;
    const V rot_c = kc.rot_c, rot_s = kc.rot_s;
    const V s_mid = Fma(*sn, rot_c, *cs * rot_s), c_mid = Fma(*cs, rot_c, -(*sn * rot_s));
    const V s_end = Fma(s_mid, rot_c, c_mid * rot_s), c_end = Fma(c_mid, rot_c, -(s_mid * rot_s));
    const V fm = kc.amp * s_mid, f1 = kc.amp * s_end;
    const double h = kc.h, hh = 0.5 * h;
    const V hh_v = Splat<W>(hh), h_v = Splat<W>(h), h6_v = Splat<W>(h / 6.0), two = Splat<W>(2.0);
    m.Apply(st.j1, st.w.data(), sc.l.data());
#pragma GCC unroll 16
    for (int d = 0; d < dim; ++d) {
      sc.acc[d] = st.k1[d], sc.accw[d] = sc.l[d];
      sc.xs[d] = Fma(hh_v, st.k1[d], st.x[d]), sc.ws[d] = Fma(hh_v, sc.l[d], st.w[d]);
    }
    auto mid_stage = [&](V next) BISTABLE_INLINE_LAMBDA {
      m.Eval(sc.xs.data(), fm, sc.k.data(), &sc.j);
      m.Apply(sc.j, sc.ws.data(), sc.l.data());
#pragma GCC unroll 16
      for (int d = 0; d < dim; ++d) {
        sc.acc[d] = Fma(two, sc.k[d], sc.acc[d]), sc.accw[d] = Fma(two, sc.l[d], sc.accw[d]);
        sc.xs[d] = Fma(next, sc.k[d], st.x[d]), sc.ws[d] = Fma(next, sc.l[d], st.w[d]);
      }
    };
    mid_stage(hh_v);
    mid_stage(h_v);
    m.Eval(sc.xs.data(), f1, sc.k.data(), &sc.j);
    m.Apply(sc.j, sc.ws.data(), sc.l.data());
#pragma GCC unroll 16
    for (int d = 0; d < dim; ++d) {
      st.x[d] = Fma(h6_v, sc.acc[d] + sc.k[d], st.x[d]);
      st.w[d] = Fma(h6_v, sc.accw[d] + sc.l[d], st.w[d]);
    }
    *sn = s_end;
    *cs = c_end;
    m.Eval(st.x.data(), f1, st.k1.data(), &st.j1);
  }

  // w ← w/|w|, *lg = log|w| (unless lg is null). A lane whose state or tangent is no longer finite (or
  // whose state left any physical range, |x| > 1e8) is flagged and reset so it cannot slow its neighbours.
  static void Renormalise(int dim, State* st, V* lg, bool* diverged) {
    V n2 = st->w[0] * st->w[0];
    for (int d = 1; d < dim; ++d) n2 = n2 + st->w[d] * st->w[d];
    for (int l = 0; l < W; ++l) {
      const double nrm = std::sqrt(n2[l]);
      if (lg) (*lg)[l] = std::log(nrm);
      const double inv = 1.0 / nrm;
      bool bad = !std::isfinite(nrm);
      for (int d = 0; d < dim; ++d) {
        st->w[d][l] *= inv;
        bad |= !std::isfinite(st->x[d][l]) || std::fabs(st->x[d][l]) > 1e8;
      }
      if (bad) {
        diverged[l] = true;
        for (int d = 0; d < dim; ++d) st->x[d][l] = 0.0, st->w[d][l] = (d == 0);
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
// Term models (term_model.h: a model of effect-library terms, identify's), `substeps` from TermRk4Substeps.
template <int W>
bool RunTermLanes(const TermLaneInput* in, int n, const KernelSettings& s, int substeps, RawLane* out);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ENSEMBLE_GENERIC_H_
