// The rig (DimensionalLaneModel) in SIMD lanes with a linearly implicit integrator (issue 41): ROS34PW2
// (Rang & Angermann, BIT 45, 2005) — 4 stages, order 3, an embedded order-2 solution for the error
// estimate, L-stable and stiffly accurate — with its own adaptive step in every lane, on state and
// tangent (Benettin) together. `integrator = "rosenbrock"` in a rig map (engine/evaluate.cc).
//
// Why this method. The rig is stiff only through the Stribeck friction: where a body sticks, the law's
// slope (≈ 10³ N s/m) puts eigenvalues of ≈ −10⁴ s⁻¹ into the velocity rows, which caps an explicit
// method's step at ≈ 0.2 ms (RK4, Rk4Substeps) or makes Dormand–Prince crawl, while the motion itself
// is smooth on the scale of a millisecond. A linearly implicit method takes the stiff part through one
// linear solve per stage with I − hγJ, and L-stability damps a stuck velocity's fast mode in one step.
// The Jacobian is exact: J from the law's slope (Eval), the forcing's time derivative, and for the
// tangent the augmented system's coupling block H = ∂(J(x) w)/∂x from the law's curvature
// (EvalCurvature, JacDirection), so state and tangent together are integrated by a Rosenbrock method of
// order 3. (ROS34PW2 is also a W-method: without H it keeps order 3 formally; the maps measured the same
// within a point at rtol 1e-5; H costs one directional derivative and product per stage, and the exact
// form is kept.)
// I − hγJ has the rig's structure (rows 0 and 2 are x0' = x1, x2' = x3): eliminating k0 and k2 leaves a
// 2 × 2 system in k1, k3, solved in closed form (one division per step); the augmented matrix is block
// triangular, so the tangent goes through the same solves.
//
// Error control. err = RMS over the 8 components of the embedded difference Σ (b_i − b̂_i) k_i, each
// over its scale: atol + rtol·max(|x_i|, |x1_i|) for the state, one scale atol + rtol·max_i max(|w_i|,
// |w1_i|) for the tangent (its size and direction matter, not its components'; scales per component
// cost 25 % more steps at the same rtol). A step is taken when err ≤ 1; the next is h·0.9 err^(−1/4)
// (two square roots: exact, so the same bits at every width), within [0.2, 5]·h and at most
// min(0.8/Ω, 4 dt).
//
// Lanes. A lane runs its own item through chunks of output steps (up to the next renormalisation,
// re-anchoring, window start or end: the RK4 lanes' schedule); its steps are its own, the last one of a
// chunk lands on the chunk's end exactly. All lanes take each trial step together; a lane keeps it only
// if it passes (blends, not arithmetic: a lane's bits do not change while it waits), and a lane whose
// chunk has ended is served at once (recorder, renormalisation, the next chunk or the next item), so a
// block of W lanes costs the lanes' average number of steps, not the most any lane needs at each moment
// (measured: 7.7 of 8 lanes busy per trial on the example's map). Output points inside a step come from
// the cubic Hermite interpolants of y and y' (values and slopes at the step's ends: the method's own
// order of error; y'' as the slope of y''s). Every decision a lane's arithmetic depends on is the lane's
// own, and per-lane work (recorder, renormalisation, anchoring) is scalar code: a point's bits do not
// depend on W, its lane or its neighbours, and the one-point path is this kernel at W = 1.
// The forcing sin(Ω t) at a stage time t + c h is sin(Ω t)·cos(Ω c h) + cos(Ω t)·sin(Ω c h), with
// (sin, cos)(Ω t) carried per lane by the same rotation from step to step and anchored (libm) at every
// chunk's start, and (sin, cos)(Ω c h) from their Taylor polynomials (Ω h ≤ kMaxPhasePerStep).
#ifndef BISTABLE_DYNAMICS_ENSEMBLE_ROSENBROCK_H_
#define BISTABLE_DYNAMICS_ENSEMBLE_ROSENBROCK_H_

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include "dynamics/cancel.h"
#include "dynamics/dimensional_model.h"
#include "dynamics/ensemble_rk4.h"
#include "dynamics/lane_run.h"
#include "dynamics/lanes.h"
#include "dynamics/point_spec.h"
#include "dynamics/window_recorder.h"

namespace bistable {

struct RosenbrockTolerances {
  double rtol = 5e-6, atol = 1e-9;  // the rig's integrator = "rosenbrock" defaults (sweep_spec.cc)
  // Tests only (convergence order): every step this long (dt a whole multiple of it), no error control.
  double fixed_step = 0;
};

// ROS34PW2 in the standard form (Hairer & Wanner IV.7): (I − hγJ) k_i = h f(x + Σ α_ij k_j, t + α_i h)
// + hJ Σ γ_ij k_j + γ_i h² f_t, x1 = x + Σ b_i k_i, error Σ (b_i − b̂_i) k_i.
struct Ros34pw2 {
  static constexpr double gamma = 4.3586652150845900e-01;
  static constexpr double a21 = 8.7173304301691801e-01, a31 = 8.4457060015369423e-01, a32 = -1.1299064236484185e-01,
                          a41 = 0.0, a42 = 0.0, a43 = 1.0;
  static constexpr double g21 = -8.7173304301691801e-01, g31 = -9.0338057013044082e-01, g32 = 5.4180672388095326e-02,
                          g41 = 2.4212380706095346e-01, g42 = -1.2232505839045147e+00, g43 = 5.4526025533510214e-01;
  static constexpr double b1 = 2.4212380706095346e-01, b2 = -1.2232505839045147e+00, b3 = 1.5452602553351020e+00,
                          b4 = 4.3586652150845900e-01;
  static constexpr double bh1 = 3.7810903145819369e-01, bh2 = -9.6042292212423178e-02, bh3 = 5.0000000000000000e-01,
                          bh4 = 2.1793326075422950e-01;
  static constexpr double c2 = a21, c3 = a31 + a32;                                 // stage times (c4 = 1)
  static constexpr double gs1 = gamma, gs2 = g21 + gamma, gs3 = g31 + g32 + gamma;  // γ_i = Σ_j γ_ij (γ_4 = 0)
};

// (sin θ, cos θ) for |θ| ≤ kMaxPhasePerStep by their Taylor polynomials (to θ^17 and θ^18: truncation
// below 2e-19), Horner in θ² with fused multiply-adds: the same bits at every width.
template <int W>
BISTABLE_INLINE void SinCosSmall(Vec<W> th, Vec<W>* s, Vec<W>* c) {
  static constexpr double ks[8] = {-1.0 / 6,
                                   1.0 / 120,
                                   -1.0 / 5040,
                                   1.0 / 362880,
                                   -1.0 / 39916800,
                                   1.0 / 6227020800.0,
                                   -1.0 / 1307674368000.0,
                                   1.0 / 355687428096000.0};
  static constexpr double kc[9] = {-1.0 / 2,
                                   1.0 / 24,
                                   -1.0 / 720,
                                   1.0 / 40320,
                                   -1.0 / 3628800,
                                   1.0 / 479001600.0,
                                   -1.0 / 87178291200.0,
                                   1.0 / 20922789888000.0,
                                   -1.0 / 6402373705728000.0};
  const Vec<W> t2 = th * th;
  Vec<W> ps = Splat<W>(ks[7]);
  for (int i = 6; i >= 0; --i) ps = Fma(ps, t2, Splat<W>(ks[i]));
  Vec<W> pc = Splat<W>(kc[8]);
  for (int i = 7; i >= 0; --i) pc = Fma(pc, t2, Splat<W>(kc[i]));
  *s = Fma(th * t2, ps, th);
  *c = Fma(t2, pc, Splat<W>(1.0));
}

template <int W>
class EnsembleRosenbrock {
 public:
  using V = Vec<W>;
  using Model = DimensionalLaneModel;
  using Input = Model::Input;
  using Lanes = Model::Lanes<W>;
  using Jac = typename Lanes::Jac;
  static constexpr int kD = 4;
  static constexpr long kReanchor = kCancelCheckSteps;  // output steps between phase re-anchors (and polls)

  // Integrates the n items in[0..n) (any n ≥ 1) in W lanes, a lane taking the next item as soon as its
  // own is done, and fills out[0..n); r.steps = accepted steps, r.rhs_evals = 4 per trial step of the
  // item. False when cancellation was requested before the end: out[0..n) then hold no result and must
  // be discarded. All items share the rig's parameters (in[0]'s) and the settings s.
  static bool Run(const Input* in, int n, const KernelSettings& s, const RosenbrockTolerances& tol, RawLane* out) {
    const Lanes m(in[0]);
    St st(m);
    st.dt = Splat<W>(s.h);
    st.rtol = Splat<W>(tol.rtol);
    st.atol = Splat<W>(tol.atol);
    st.fixed = tol.fixed_step > 0;
    const long max_chunk = std::min<long>(s.renorm_every, kReanchor);
    std::vector<V> buf(3 * (max_chunk + 1));  // y, y', y'' at a chunk's output points 0..K, per lane
    Bufs b{buf.data(), buf.data() + (max_chunk + 1), buf.data() + 2 * (max_chunk + 1)};
    std::optional<WindowRecorder<2, 1>> rec[W];
    LaneJob job[W];
    int next_item = 0;
    // Lanes to (re)start a chunk, as bits; the vector F, J evaluation of a chunk's start is shared.
    unsigned long start = 0;
    // Lane l takes the job's next item (to start with the others in `start`), or idles when none is left.
    auto take_next = [&](int l) {
      if (next_item < n) {
        Load(l, next_item, in[next_item], s, tol, &st, &job[l], &rec[l]);
        ++next_item;
        start |= 1ul << l;
      } else {
        job[l].item = -1;
      }
    };
    for (int l = 0; l < W; ++l) take_next(l);
    StartChunks(m, s, start, b, &st, job, rec);
    long polls = 0;
    for (;;) {
      const unsigned long live = PositiveMask(st.active);
      if (!live) break;
      if ((++polls & 4095) == 0 && CancelRequested()) [[unlikely]]
        return MarkCancelled(n, 0, out);
      Trial(m, b, &st);
      // Lanes that reached their chunk's end (or gave up): record, renormalise, finish or go on.
      const unsigned long ended = live & ~PositiveMask(st.active);
      if (!ended) continue;
      start = 0;
      for (int l = 0; l < W; ++l) {
        if (!(ended >> l & 1)) continue;
        if (EndChunk(l, s, b, &st, &job[l], &*rec[l], out)) {
          start |= 1ul << l;
          continue;
        }
        take_next(l);  // the item is done: the lane takes the next one
      }
      StartChunks(m, s, start, b, &st, job, rec);
    }
    return true;
  }

 private:
  // Everything per lane: the state, the item's constants, and where the lane is in its chunk.
  struct St {
    explicit St(const Lanes& m) : j(m) {}
    V x[kD], w[kD], f[kD];           // state, tangent, F(x, t) (the first stage's value)
    Jac j;                           // J(x)
    typename Lanes::Curv c;          // the friction laws' curvatures at x (the tangent's coupling block)
    V h;                             // the lane's next trial step
    V sn, cs;                        // (sin, cos)(Ω t) at the lane's time
    V tau, len, next;                // time done in the chunk, its length, the next output point to fill
    V active = V{};                  // 1 while the lane is inside a chunk
    V emit = V{};                    // 1 when the chunk is in the window (its output points are kept)
    V accepted = V{}, tried = V{};   // the item's accepted and trial steps (counts in doubles)
    V amp, omega, amp_omega, h_max;  // the item's forcing and largest step
    V dt, rtol, atol;
    bool fixed = false;  // fixed steps (RosenbrockTolerances::fixed_step): every trial is taken
  };
  struct Bufs {
    V *y, *v, *a;
  };
  // A lane's item and its place on the output grid (scalars: the same code at every width).
  struct LaneJob {
    int item = -1;
    long n0 = 0, n1 = 0;  // the chunk's output steps [n0, n1]
    double omega = 0, rot_c = 1, rot_s = 0;
    double sn0 = 0, cs0 = 1;  // the phase anchored at n0
    bool diverged = false;
  };

  static BISTABLE_INLINE V Blend(V take, V a, V b) {
    return SelectLess<W>(Splat<W>(0.0), take, a, b);
  }  // take > 0 ? a : b

  // (I − sJ) k = r for the rig's J (rows 0, 2 identities; a, b rows 1, 3), precomputed per step.
  struct Solver {
    V s, sa0, sa2, sb0, sb2, p, q, u, v, inv;
    BISTABLE_INLINE Solver(V s_, const V* a, const V* b) : s(s_) {
      const V one = Splat<W>(1.0);
      sa0 = s * a[0], sa2 = s * a[2], sb0 = s * b[0], sb2 = s * b[2];
      p = one - s * Fma(s, a[0], a[1]);
      q = -(s * Fma(s, a[2], a[3]));
      u = -(s * Fma(s, b[0], b[1]));
      v = one - s * Fma(s, b[2], b[3]);
      inv = one / Fma(p, v, -(q * u));
    }
    BISTABLE_INLINE void Solve(const V* r, V* k) const {
      const V r1 = Fma(sa0, r[0], Fma(sa2, r[2], r[1]));
      const V r3 = Fma(sb0, r[0], Fma(sb2, r[2], r[3]));
      k[1] = Fma(v, r1, -(q * r3)) * inv;
      k[3] = Fma(p, r3, -(u * r1)) * inv;
      k[0] = Fma(s, k[1], r[0]);
      k[2] = Fma(s, k[3], r[2]);
    }
  };

  // A lane takes item i: its constants, the start state and tangent (the RK4 lanes' start), a first
  // trial step of dt/10, a fresh recorder; its first chunk is started by StartChunks.
  static void Load(int l, int i, const Input& in, const KernelSettings& s, const RosenbrockTolerances& tol, St* st,
                   LaneJob* job, std::optional<WindowRecorder<2, 1>>* rec) {
    job->item = i;
    job->n0 = job->n1 = 0;
    job->diverged = false;
    job->omega = in.omega;
    Vec<1> rs, rc;
    SinCosSmall<1>(Vec<1>{in.omega * s.h}, &rs, &rc);  // the per-output-step rotation of the recorder's phase
    job->rot_s = rs[0], job->rot_c = rc[0];
    st->amp[l] = in.amp;
    st->omega[l] = in.omega;
    st->amp_omega[l] = in.amp * in.omega;
    // The largest step: the stage polynomials' phase range, and 4 output steps (the output points'
    // cubic Hermite interpolation keeps the method's own order of error).
    st->h_max[l] = tol.fixed_step > 0 ? tol.fixed_step : std::min(kMaxPhasePerStep / in.omega, 4.0 * s.h);
    const int td = in.params.TangentDims();
    for (int d = 0; d < kD; ++d) {
      st->x[d][l] = in.x0[d];
      // (1, 1, 1, 1)/√4, or (1, 1, 0, 0)/√2 without a resonator: the adaptive path's start (generic_point.h)
      st->w[d][l] = d < td ? 1.0 / std::sqrt(static_cast<double>(td)) : 0.0;
    }
    st->h[l] = tol.fixed_step > 0 ? tol.fixed_step : 0.1 * s.h;
    st->accepted[l] = st->tried[l] = 0.0;
    rec->reset();
    rec->emplace(&in.base_amp, &in.omega, s.h, s.n_keep, s.sample_every, s.keep_samples, s.keep_rows, s.strobe_phase);
  }

  // Starts the next chunk of the lanes in `lanes` (each at its job's n1, which becomes n0): the phase
  // anchored there (libm), F and J at the state with it (one vector evaluation, kept in those lanes),
  // the chunk's first output point, and the window's first point when the chunk starts at n_keep.
  static void StartChunks(const Lanes& m, const KernelSettings& s, unsigned long lanes, const Bufs& b, St* st,
                          LaneJob* job, std::optional<WindowRecorder<2, 1>>* rec) {
    if (!lanes) return;
    V take = Splat<W>(0.0);
    for (int l = 0; l < W; ++l) {
      if (!(lanes >> l & 1)) continue;
      LaneJob& jb = job[l];
      jb.n0 = jb.n1;
      long n1 = std::min({s.n_total, RoundUpTo(jb.n0 + 1, s.renorm_every), RoundUpTo(jb.n0 + 1, kReanchor)});
      if (jb.n0 < s.n_keep) n1 = std::min(n1, s.n_keep);
      jb.n1 = n1;
      const double t = static_cast<double>(jb.n0) * s.h;
      jb.sn0 = std::sin(jb.omega * t), jb.cs0 = std::cos(jb.omega * t);
      st->sn[l] = jb.sn0, st->cs[l] = jb.cs0;
      st->tau[l] = 0.0;
      st->len[l] = s.h * static_cast<double>(n1 - jb.n0);
      st->next[l] = 1.0;
      st->active[l] = 1.0;
      st->emit[l] = jb.n0 >= s.n_keep ? 1.0 : 0.0;
      take[l] = 1.0;
    }
    V f[kD];
    Jac j(m);
    typename Lanes::Curv c;
    m.EvalCurvature(st->x, st->amp * st->sn, f, &j, &c);
    st->c.m = Blend(take, c.m, st->c.m), st->c.r = Blend(take, c.r, st->c.r);
    for (int d = 0; d < kD; ++d) st->f[d] = Blend(take, f[d], st->f[d]);
    st->j.fy = Blend(take, j.fy, st->j.fy), st->j.fyd = Blend(take, j.fyd, st->j.fyd);
    st->j.gz = Blend(take, j.gz, st->j.gz), st->j.gzd = Blend(take, j.gzd, st->j.gzd);
    for (int l = 0; l < W; ++l) {
      if (!(lanes >> l & 1)) continue;
      b.y[0][l] = st->x[0][l], b.v[0][l] = st->x[1][l], b.a[0][l] = st->f[1][l];
      if (job[l].n0 == s.n_keep) {
        const Vec<1> o[2] = {{b.y[0][l]}, {b.v[0][l]}}, d[2] = {{b.v[0][l]}, {b.a[0][l]}};
        rec[l]->OnStep(s.n_keep, o, d, o, d, Vec<1>{job[l].cs0});
      }
    }
  }

  // Lane l has reached its chunk's end (or gave up): the chunk's output points into its recorder, the
  // tangent renormalised where due. True when the item goes on (the next chunk is to be started);
  // false when it is done, its record written to out[item].
  static bool EndChunk(int l, const KernelSettings& s, const Bufs& b, St* st, LaneJob* job, WindowRecorder<2, 1>* rec,
                       RawLane* out) {
    for (int d = 0; d < kD; ++d)
      if (!std::isfinite(st->x[d][l])) job->diverged = true;  // includes a lane that gave up (Trial)
    if (st->emit[l] > 0 && !job->diverged) {
      double sn = job->sn0, cs = job->cs0;
      for (long i = 1; i <= job->n1 - job->n0; ++i) {
        const double sn1 = __builtin_fma(sn, job->rot_c, cs * job->rot_s),
                     cs1 = __builtin_fma(cs, job->rot_c, -(sn * job->rot_s));
        sn = sn1, cs = cs1;
        const Vec<1> o0[2] = {{b.y[i - 1][l]}, {b.v[i - 1][l]}}, d0[2] = {{b.v[i - 1][l]}, {b.a[i - 1][l]}};
        const Vec<1> o1[2] = {{b.y[i][l]}, {b.v[i][l]}}, d1[2] = {{b.v[i][l]}, {b.a[i][l]}};
        rec->OnStep(job->n0 + i, o0, d0, o1, d1, Vec<1>{cs});
      }
    }
    const long n1 = job->n1;
    if (!job->diverged && (n1 % s.renorm_every == 0 || n1 == s.n_keep || n1 == s.n_total)) {
      double n2 = st->w[0][l] * st->w[0][l];
      for (int d = 1; d < kD; ++d) n2 = n2 + st->w[d][l] * st->w[d][l];
      const double nrm = std::sqrt(n2), inv = 1.0 / nrm;
      bool bad = !std::isfinite(nrm);
      for (int d = 0; d < kD; ++d) {
        st->w[d][l] *= inv;
        bad |= !std::isfinite(st->x[d][l]) || std::fabs(st->x[d][l]) > 1e8;
      }
      if (bad)
        job->diverged = true;
      else if (n1 > s.n_keep)
        rec->AddLogGrowth(Vec<1>{std::log(nrm)});
    }
    if (!job->diverged && n1 < s.n_total) return true;
    // Done (or diverged: stopped early, stored as diverged with NaN metrics).
    RawLane& r = rec->Lane(0);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    r.q_p = r.q_in = r.q_m = r.q_r = nan;
    r.e_start = r.e_end = nan;
    r.diverged = job->diverged;
    r.steps = static_cast<long>(st->accepted[l]);
    r.rhs_evals = 4 * static_cast<long>(st->tried[l]);
    for (int d = 0; d < kD; ++d) r.final_state[d] = st->x[d][l], r.final_tangent[d] = st->w[d][l];
    const double t = static_cast<double>(s.n_total) * s.h;
    r.final_sin = std::sin(job->omega * t), r.final_cos = std::cos(job->omega * t);
    out[job->item] = std::move(r);
    return false;
  }

  // One trial step in every lane inside a chunk (h = 0 elsewhere: nothing is kept there). A lane whose
  // step falls below dt·1e-9 (or goes NaN) gives up: its chunk ends, the item is stored as diverged.
  // This function is longer than 120 lines on purpose: it is the hot loop's one ROS34PW2 step (four
  // stages of state and tangent, error estimate, step-size control, the accepted step's update), kept
  // in one function so the stage vectors kx, kw stay in registers and the compiler sees the whole step.
  // Helpers would pass a dozen lane vectors between them, and the maps' bits (compared bit for bit)
  // would then rest on how they are inlined; no split of it has been measured to be faster.
  static BISTABLE_INLINE void Trial(const Lanes& m, const Bufs& bf, St* st_p) {
    using R = Ros34pw2;
    St& st = *st_p;
    const V zero = Splat<W>(0.0), one = Splat<W>(1.0);
    // The trial step: the lane's proposal, or what is left of the chunk when the proposal reaches
    // within 1 % of its end (then it lands exactly); 0 in finished lanes. (sn, cs) is the forcing's
    // phase at the lane's time; the stages' phases are rotated from it by Ω c_i h.
    V a[4], b[4];
    m.JacRows(st.j, a, b);
    const V rest = st.len - st.tau;
    const V last = SelectLess<W>(Fma(Splat<W>(1.01), st.h, st.tau), st.len, zero, one);
    const V h = Blend(st.active, Blend(last, rest, st.h), zero);
    const V th2 = st.omega * (R::c2 * h), th3 = st.omega * (R::c3 * h), th4 = st.omega * h;
    V s2, c2, s3, c3, s4, c4;
    SinCosSmall<W>(th2, &s2, &c2);
    SinCosSmall<W>(th3, &s3, &c3);
    SinCosSmall<W>(th4, &s4, &c4);
    // f_t h² γ_i: the forcing's time derivative amp·Ω·cos(Ω t) at the step's start (row 1 only).
    const V ft = st.amp_omega * st.cs;
    const V h2ft = (h * h) * ft;
    const Solver sol(h * R::gamma, a, b);
    V kx[4][kD], kw[4][kD], r[kD], tmp[kD], xs[kD], ws[kD], fs[kD], gs[kD];
    Jac js(m);
    // Stage 1: f, J w at x (the step's start).
    m.Apply(st.j, st.w, gs);
    for (int d = 0; d < kD; ++d) r[d] = h * st.f[d];
    r[1] = Fma(Splat<W>(R::gs1), h2ft, r[1]);
    sol.Solve(r, kx[0]);
    // The tangent's rows of the augmented system: (I − hγJ) kw_i = h(J(x_i) w_i + J Σ γ_ij kw_j
    // + H(Σ γ_ij kx_j + γ kx_i)), H = ∂(J w)/∂x at the step's start (exact: a Rosenbrock method for
    // state and tangent together, so the tangent keeps its order where the friction is stiff).
    Jac dj(m);
    V hk[kD];
    auto coupling = [&](const V* u) BISTABLE_INLINE_LAMBDA {  // hk = H u
      m.JacDirection(st.x, st.c, u, &dj);
      m.Apply(dj, st.w, hk);
      hk[0] = hk[2] = zero;  // rows 0 and 2 (x0' = x1, x2' = x3) do not depend on x
    };
    for (int d = 0; d < kD; ++d) tmp[d] = R::gamma * kx[0][d];
    coupling(tmp);
    for (int d = 0; d < kD; ++d) r[d] = h * (gs[d] + hk[d]);
    sol.Solve(r, kw[0]);
    // Stages 2–4: stage point, F and J there, and hJ Σ γ_ij k_j.
    auto stage = [&](int i, const double* al, const double* ga, double gsum, V sn_i, V cs_i) BISTABLE_INLINE_LAMBDA {
      for (int d = 0; d < kD; ++d) {
        V xa = st.x[d], wa = st.w[d], gx = zero, gw = zero;
        for (int j = 0; j < i; ++j) {
          if (al[j] != 0.0) xa = Fma(Splat<W>(al[j]), kx[j][d], xa), wa = Fma(Splat<W>(al[j]), kw[j][d], wa);
          gx = Fma(Splat<W>(ga[j]), kx[j][d], gx), gw = Fma(Splat<W>(ga[j]), kw[j][d], gw);
        }
        xs[d] = xa, ws[d] = wa, tmp[d] = gx, r[d] = gw;  // r: Σ γ k of the tangent, for now
      }
      const V fi = st.amp * Fma(st.sn, cs_i, st.cs * sn_i);
      m.Eval(xs, fi, fs, &js);
      V jg[kD], jgw[kD], jw[kD];
      m.Apply(st.j, tmp, jg);  // J Σ γ_ij kx_j
      m.Apply(st.j, r, jgw);   // J Σ γ_ij kw_j
      m.Apply(js, ws, jw);     // the tangent's own right-hand side J(x_i) w_i
      for (int d = 0; d < kD; ++d) r[d] = h * (fs[d] + jg[d]);
      if (gsum != 0.0) r[1] = Fma(Splat<W>(gsum), h2ft, r[1]);
      sol.Solve(r, kx[i]);
      for (int d = 0; d < kD; ++d) tmp[d] = Fma(Splat<W>(R::gamma), kx[i][d], tmp[d]);
      coupling(tmp);
      for (int d = 0; d < kD; ++d) r[d] = h * ((jw[d] + jgw[d]) + hk[d]);
      sol.Solve(r, kw[i]);
    };
    static constexpr double al2[1] = {R::a21}, ga2[1] = {R::g21};
    static constexpr double al3[2] = {R::a31, R::a32}, ga3[2] = {R::g31, R::g32};
    static constexpr double al4[3] = {R::a41, R::a42, R::a43}, ga4[3] = {R::g41, R::g42, R::g43};
    stage(1, al2, ga2, R::gs2, s2, c2);
    stage(2, al3, ga3, R::gs3, s3, c3);
    stage(3, al4, ga4, 0.0, s4, c4);
    // The new state and tangent, the error estimate (RMS over state and tangent).
    V x1[kD], w1[kD], sum = zero;
    const V e1 = Splat<W>(R::b1 - R::bh1), e2 = Splat<W>(R::b2 - R::bh2), e3 = Splat<W>(R::b3 - R::bh3),
            e4 = Splat<W>(R::b4 - R::bh4);
    // sk per component: atol + rtol·max(|x|, |x1|) for the state; for the tangent (whose size and
    // direction matter, not its components') one scale atol + rtol·max_i max(|w_i|, |w1_i|).
    auto combine = [&](const V(*kk)[kD], const V* x0, V* x1o, bool common) BISTABLE_INLINE_LAMBDA {
      V e[kD], mx = zero;
      for (int d = 0; d < kD; ++d) {
        x1o[d] =
            Fma(Splat<W>(R::b4), kk[3][d],
                Fma(Splat<W>(R::b3), kk[2][d], Fma(Splat<W>(R::b2), kk[1][d], Fma(Splat<W>(R::b1), kk[0][d], x0[d]))));
        e[d] = Fma(e4, kk[3][d], Fma(e3, kk[2][d], Fma(e2, kk[1][d], e1 * kk[0][d])));
        mx = Max<W>(mx, Max<W>(Abs<W>(x0[d]), Abs<W>(x1o[d])));
      }
      const V inv_common = one / Fma(st.rtol, mx, st.atol);
      for (int d = 0; d < kD; ++d) {
        const V q = common ? e[d] * inv_common : e[d] / Fma(st.rtol, Max<W>(Abs<W>(x0[d]), Abs<W>(x1o[d])), st.atol);
        sum = Fma(q, q, sum);
      }
    };
    combine(kx, st.x, x1, false);
    combine(kw, st.w, w1, true);
    const V err = st.fixed ? zero : Sqrt<W>(sum * 0.125);
    // Accept where active and err ≤ 1 (NaN: rejected); the step-size factor 0.9 err^(−1/4) in [0.2, 5].
    const V ok = Blend(st.active, SelectLess<W>(err, Splat<W>(0x1.0000000000001p0), one, zero), zero);  // err ≤ 1
    // err^(−1/4) as two square roots (exact in IEEE arithmetic, so the same bits at every width):
    // a little more cautious than the asymptotic err^(−1/3) of a 2nd-order estimate.
    const V errc = SelectLess<W>(err, Splat<W>(1e300), Max<W>(err, Splat<W>(1e-10)), Splat<W>(1e10));  // NaN, inf: 1e10
    const V fac = Min<W>(Splat<W>(5.0), Max<W>(Splat<W>(0.2), Splat<W>(0.9) / Sqrt<W>(Sqrt<W>(errc))));
    // F and J at the new state (the next step's first stage), at its time t + h: the forcing phase
    // rotated by Ω h, which the lane keeps when it takes the step.
    const V sn1 = Fma(st.sn, c4, st.cs * s4), cs1 = Fma(st.cs, c4, -(st.sn * s4));
    V f1[kD];
    Jac j1(m);
    typename Lanes::Curv c1;
    m.EvalCurvature(x1, st.amp * sn1, f1, &j1, &c1);
    Emit(ok, st.tau, h, Blend(last, st.len, st.tau + h), st.x, st.f, x1, f1, st.dt, st.emit, &st.next, bf.y, bf.v,
         bf.a);
    for (int d = 0; d < kD; ++d) {
      st.x[d] = Blend(ok, x1[d], st.x[d]);
      st.w[d] = Blend(ok, w1[d], st.w[d]);
      st.f[d] = Blend(ok, f1[d], st.f[d]);
    }
    st.j.fy = Blend(ok, j1.fy, st.j.fy), st.j.fyd = Blend(ok, j1.fyd, st.j.fyd);
    st.j.gz = Blend(ok, j1.gz, st.j.gz), st.j.gzd = Blend(ok, j1.gzd, st.j.gzd);
    st.c.m = Blend(ok, c1.m, st.c.m), st.c.r = Blend(ok, c1.r, st.c.r);
    st.sn = Blend(ok, sn1, st.sn), st.cs = Blend(ok, cs1, st.cs);
    st.accepted = st.accepted + Blend(ok, one, zero);
    st.tried = st.tried + st.active;
    st.tau = Blend(ok, Blend(last, st.len, st.tau + h), st.tau);
    // Next proposal: h·fac, at most h_max; after a landing step not below the proposal it cut short.
    const V hn = Min<W>(h * fac, st.h_max);
    st.h = Blend(st.active, Blend(ok, Blend(last, Max<W>(hn, st.h), hn), hn), st.h);
    st.active = Blend(ok, Blend(last, zero, st.active), st.active);
    if (const unsigned long bad = PositiveMask(st.active) & ~PositiveMask(st.h - st.dt * 1e-9); bad) [[unlikely]]
      GiveUp(bad, st_p);
  }

  [[gnu::cold, gnu::noinline]] static void GiveUp(unsigned long lanes, St* st) {
    for (int l = 0; l < W; ++l) {
      if (!(lanes >> l & 1)) continue;
      st->active[l] = 0.0;
      st->h[l] = st->dt[l];
      for (int d = 0; d < kD; ++d) st->x[d][l] = std::numeric_limits<double>::quiet_NaN();  // seen by EndChunk
    }
  }

  // The output points t_0 + i dt in (tau, tau1] of the lanes that took their step (ok), by cubic Hermite
  // interpolation between (x0, f0) and (x1, f1) over the step h; `next` is each lane's next index.
  // A point at the step's end (θ = 1) gets x1 and f1 themselves.
  static BISTABLE_INLINE void Emit(V ok, V tau, V h, V tau1, const V* x0, const V* f0, const V* x1, const V* f1, V dt,
                                   V emit, V* next, V* by, V* bv, V* ba) {
    // (A chunk ends exactly at an output point, the last step lands there: i never passes the chunk.)
    const V zero = Splat<W>(0.0), one = Splat<W>(1.0);
    for (;;) {
      const V tg = *next * dt;  // the lane's next output point, from the chunk's start
      const V due = Blend(ok * emit, SelectLess<W>(tau1, tg, zero, one), zero);  // tg ≤ tau1, window chunks
      const unsigned long mask = PositiveMask(due);
      if (!mask) return;
      const V th = (tg - tau) / h, th2 = th * th, u = one - th;
      const V h00 = (Fma(Splat<W>(2.0), th, one) * u) * u, h10 = (th * u) * u;
      const V h01 = th2 * Fma(Splat<W>(-2.0), th, Splat<W>(3.0)), h11 = th2 * (th - one);
      const V g00 = Splat<W>(6.0) * (th2 - th), g10 = Fma(Splat<W>(3.0), th2, Fma(Splat<W>(-4.0), th, one));
      const V g11 = Fma(Splat<W>(3.0), th2, Splat<W>(-2.0) * th);
      // y from (y, y') at both ends; y' from (y', y''); y'' the slope of y''s cubic.
      const V y = Fma(h01, x1[0], Fma(h00, x0[0], h * Fma(h10, f0[0], h11 * f1[0])));
      const V v = Fma(h01, x1[1], Fma(h00, x0[1], h * Fma(h10, f0[1], h11 * f1[1])));
      const V a = Fma(g10, f0[1], Fma(g11, f1[1], (g00 * (x0[1] - x1[1])) / h));
      for (int l = 0; l < W; ++l) {
        if (!(mask >> l & 1)) continue;
        const long i = static_cast<long>((*next)[l]);
        by[i][l] = y[l], bv[i][l] = v[l], ba[i][l] = a[l];
      }
      *next = *next + due;
    }
  }
};

// Instantiated in ensemble_generic.cc for W = 1 (one point), 4 and 8 (sweeps: kSweepLanes).
template <int W>
bool RunDimensionalRosenbrock(const DimensionalLaneInput* in, int n, const KernelSettings& s,
                              const RosenbrockTolerances& tol, RawLane* out);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ENSEMBLE_ROSENBROCK_H_
