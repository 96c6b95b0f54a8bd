// The ensemble kernel: fixed-step RK4 (the paper's method) of up to W grid points side by side in
// SIMD lanes (structure of arrays, lane = point), with
//  - one tangent vector per lane for the Benettin LLE, integrated by the same RK4 stages
//    (variational equation w' = J(x) w) and renormalised every `renorm_every` steps;
//  - the forcing phase advanced by exact rotation (cos/sin of Ωh/2 per lane), re-anchored with
//    sin/cos of Ω·nh every kReanchor steps so the phase error stays at rounding level;
//  - the energy quadratures ∫P, ∫max(P,0), W_m, W_r over the window by the trapezoid rule on the
//    step ends with the Euler–Maclaurin end correction (4th order, one integrand evaluation per step),
//    so the balance ∫P = W_m + W_r + ΔE holds to the order of RK4's truncation error.
// A lane's arithmetic never depends on other lanes or on W (no reductions across lanes; fused
// multiply-adds only where written, as Fma, and exact): the same point gives bit-identical results
// at any lane width. Ordinary steps run in a call-free loop (RunFast); the few special ones
// (window start, strobes, renormalisation, re-anchoring, the end) in the general loop of Run.
// Cancellation (dynamics/cancel.h) is polled at the re-anchoring steps, every kReanchor steps.
#ifndef BISTABLE_DYNAMICS_ENSEMBLE_RK4_H_
#define BISTABLE_DYNAMICS_ENSEMBLE_RK4_H_

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include "dynamics/cancel.h"
#include "dynamics/lane_run.h"
#include "dynamics/lanes.h"
#include "dynamics/nondim_models.h"
#include "dynamics/window_recorder.h"

namespace bistable {

// One lane's inputs.
struct LaneInput {
  CellCoeffs<double> coeffs;
  double alpha = 0, omega = 0;    // α, Ω
  std::array<double, 4> x0 = {};  // initial (y_m, y_m', y_r, y_r')
  // A chain resumed at KernelSettings::step0 > 0 (RunChain): the tangent and forcing phase a window's
  // raw record gave (final_tangent, final_sin, final_cos), x0 its final_state.
  std::array<double, 4> resume_tangent = {};
  double resume_sin = 0, resume_cos = 1;
};

struct KernelSettings {
  double h = 0.01;       // step
  long n_total = 50000;  // steps in [0, t_end]
  long n_keep = 25000;   // first window step
  int renorm_every = 50;
  int sample_every = 5;
  bool keep_samples = false;  // y_m samples (spectrum, Rosenstein)
  bool keep_rows = false;     // full rows (trace)
  double strobe_phase = 0;    // φ of the strobes τ_k = (φ + 2πk)/Ω (Poincaré section, period)
  // RunChain only: windows of this many steps from n_keep, and the step the lanes start from (0, or
  // where they resume; n_keep ≥ step0).
  long window_steps = 0;
  long step0 = 0;
  // Steps of h over [0, t_end], the window its second half, no samples kept (the benchmarks' and tests' runs).
  static KernelSettings Window(double h, double t_end) {
    KernelSettings ks;
    ks.h = h;
    ks.n_total = std::lround(t_end / h);
    ks.n_keep = ks.n_total / 2;
    ks.keep_samples = false;
    return ks;
  }
};

template <class Model, int W>
class EnsembleRk4 {
 public:
  static constexpr int D = Model::kDim;
  static constexpr long kReanchor = 1024;
  static_assert(kReanchor == kCancelCheckSteps, "cancellation is polled where the phase is re-anchored");
  using V = Vec<W>;

  // Integrates lanes[0..n) (1 ≤ n ≤ W) and fills out[0..n). Unused lanes repeat lane 0. Returns
  // false when cancellation was requested before the end: the run stopped early and out[0..n) hold
  // no result (marked diverged, steps short of n_total) — callers must discard them.
  static bool Run(const LaneInput* lanes, int n, const KernelSettings& s, RawLane* out) {
    return RunImpl(lanes, n, s, out, static_cast<WindowSink*>(nullptr));
  }

  // A chain of windows (settled labels, dynamics/settle.h): from s.step0 (0, or the step where every
  // lane resumes from LaneInput::resume) the lanes integrate to s.n_total, and every s.window_steps
  // steps from s.n_keep the window so far is handed to sink.OnWindow(raw, n, step, done) — the raw
  // records hold final_state/final_tangent/final_sin/final_cos, from which a later RunChain resumes
  // bit for bit — and a fresh window starts. The sink sets done[l] for lanes that need no more
  // windows; the run ends when every lane is done or at n_total. A lane's arithmetic, and so every
  // window's bits, is its own: done lanes keep stepping, unseen. False when cancelled.
  template <class Sink>
  static bool RunChain(const LaneInput* lanes, int n, const KernelSettings& s, Sink& sink) {
    return RunImpl(lanes, n, s, static_cast<RawLane*>(nullptr), &sink);
  }

  struct WindowSink {
    void OnWindow(RawLane*, int, long, bool*) {}
  };

 private:
  template <class Sink>
  static bool RunImpl(const LaneInput* lanes, int n, const KernelSettings& s, RawLane* out, Sink* sink) {
    double alpha[W], omega[W];
    CellCoeffs<V> c;
    V amp, x[D], w[D], rot_c, rot_s;
    LoadLanes(lanes, n, s.h, alpha, omega, &c, &amp, x, w, &rot_c, &rot_s);
    // The current window [win.n_keep, win.n_total]: the whole [n_keep, n_total] for Run, a link of
    // the chain for RunChain.
    KernelSettings win = s;
    if (sink) win.n_total = std::min(s.n_keep + s.window_steps, s.n_total);
    std::optional<WindowRecorder<D, W>> rec_holder;
    rec_holder.emplace(alpha, omega, s.h, win.n_keep, s.sample_every, s.keep_samples, s.keep_rows, s.strobe_phase);
    V sn, cs;
    if (s.step0 > 0) {
      for (int l = 0; l < W; ++l) {
        const LaneInput& in = lanes[l < n ? l : 0];
        sn[l] = in.resume_sin, cs[l] = in.resume_cos;
        for (int d = 0; d < D; ++d) w[d][l] = in.resume_tangent[d];
      }
    } else {
      AnchorPhase<W>(omega, 0, s.h, &sn, &cs);
    }
    V k1[D];
    Model::Rhs(c, x, amp * sn, k1);
    // ∫P, ∫max(P,0), W_m, W_r over the window: the composite trapezoid rule on the step ends with the
    // Euler–Maclaurin end correction, T − h²/12·(g'(end) − g'(start)), 4th order like RK4 itself.
    // q sums the integrands g at every window step's end; g0/gd0 are g and g' at the window's start,
    // g_last g at its end.
    V q[4] = {}, g0[4] = {}, gd0[4] = {}, g_last[4] = {};
    V om;
    for (int l = 0; l < W; ++l) om[l] = omega[l];
    V e_start = Splat<W>(0.0);
    bool diverged[W] = {};
    bool done[W] = {};
    V growth = Splat<W>(1.0);  // product of the tangent's norms since the last FlushGrowth
    int growth_batch = 0;

    // Ordinary steps (no window start, strobe, re-anchoring, renormalisation or end) run in RunFast,
    // whose loop holds no call; the loop below does the others one at a time. A trace (keep_rows)
    // takes the general path throughout.
    const Consts k{c, amp, rot_c, rot_s, s.h};
    for (long step = s.step0 + 1; step <= s.n_total; ++step) {
      WindowRecorder<D, W>& rec = *rec_holder;
      if (!s.keep_rows) {
        const long stop = NextSpecialStep(step, win, rec.next_due(), growth_batch);
        while (step < stop) {
          TangentState tg{&growth, &growth_batch, diverged, s.renorm_every};
          step = step > win.n_keep ? RunFast<true>(k, step, stop, x, k1, w, q, &sn, &cs, &rec, tg)
                                   : RunFast<false>(k, step, stop, x, k1, w, q, &sn, &cs, &rec, tg);
          if (rec.TurningPointBufferFull()) rec.FlushTurningPoints();
        }
      }
      if (step == win.n_keep + 1) {
        e_start = Model::Energy(c, x);
        rec.OnStep(win.n_keep, x, k1, x, k1, cs);
        Quad(c, x, amp * sn, g0);
        QuadRate(c, x, k1, amp * sn, amp * om * cs, g0, gd0);
      }
      // The step's start (turning points and strobes interpolate between both ends).
      V xp[D], kp[D];
      for (int d = 0; d < D; ++d) xp[d] = x[d], kp[d] = k1[d];
      Step(c, amp, rot_c, rot_s, s.h, x, k1, w, &sn, &cs);
      if (step > win.n_keep) {
        Quad(c, x, amp * sn, g_last);
        for (int i = 0; i < 4; ++i) q[i] = q[i] + g_last[i];
      }
      if (step % kReanchor == 0) {
        if (CancelRequested()) [[unlikely]] {
          if (out) MarkCancelled(n, step, out);
          return false;
        }
        AnchorPhase<W>(omega, step, s.h, &sn, &cs);
        Model::Rhs(c, x, amp * sn, k1);  // derivative consistent with the re-anchored phase
      }
      if (step > win.n_keep) rec.OnStep(step, xp, kp, x, k1, cs);
      if (step % s.renorm_every == 0 || step == win.n_keep || step == win.n_total) {
        if (step > win.n_keep) {
          Renormalise(w, &growth, diverged, x);
          const bool batch_done = ++growth_batch == kGrowthBatch || step == win.n_total;
          if (batch_done) growth_batch = 0;
          FlushGrowth(&growth, batch_done, &rec);
          if (batch_done) rec.EndGrowthBatch(step);
        } else {
          Renormalise(w, nullptr, diverged, x);  // growth before the window is not used
        }
      }
      if (sink && step == win.n_total) {
        // The window ends: its records to the sink, then a fresh window (or the end).
        RawLane raw[W];
        FinishWindow(c, amp, om, x, k1, w, sn, cs, q, g0, gd0, g_last, e_start, diverged, n, step, rec, raw);
        sink->OnWindow(raw, n, step, done);
        bool all = true;
        for (int l = 0; l < n; ++l) all = all && done[l];
        if (all || step == s.n_total) return true;
        win.n_keep = step;
        win.n_total = std::min(step + s.window_steps, s.n_total);
        rec_holder.reset();
        rec_holder.emplace(alpha, omega, s.h, win.n_keep, s.sample_every, s.keep_samples, s.keep_rows, s.strobe_phase);
        for (int i = 0; i < 4; ++i) q[i] = g0[i] = gd0[i] = g_last[i] = Splat<W>(0.0);
        growth = Splat<W>(1.0);
        growth_batch = 0;
      }
    }
    if (sink) return true;
    FinishWindow(c, amp, om, x, k1, w, sn, cs, q, g0, gd0, g_last, e_start, diverged, n, s.n_total, *rec_holder, out);
    return true;
  }

  // The window's quadratures closed with the end correction, and its records moved into out[0..n).
  static void FinishWindow(const CellCoeffs<V>& c, V amp, V om, const V* x, const V* k1, const V* w, V sn, V cs,
                           const V* q_in, const V* g0, const V* gd0, const V* g_last, V e_start, const bool* diverged,
                           int n, long step, WindowRecorder<D, W>& rec, RawLane* out) {
    const V e_end = Model::Energy(c, x);
    V gd_last[4], q[4];
    QuadRate(c, x, k1, amp * sn, amp * om * cs, g_last, gd_last);
    const double h = rec.h(), em = h * h / 12.0;
    for (int i = 0; i < 4; ++i) q[i] = h * (q_in[i] + 0.5 * (g0[i] - g_last[i])) - em * (gd_last[i] - gd0[i]);
    for (int l = 0; l < n; ++l) {
      RawLane& r = rec.Lane(l);
      r.q_p = q[0][l];
      r.q_in = q[1][l];
      r.q_m = q[2][l];
      r.q_r = q[3][l];
      r.e_start = e_start[l];
      r.e_end = e_end[l];
      r.diverged = diverged[l] || !std::isfinite(x[0][l]);
      r.steps = step;
      r.rhs_evals = 4 * step;
      for (int d = 0; d < D; ++d) r.final_state[d] = x[d][l], r.final_tangent[d] = w[d][l];
      r.final_sin = sn[l];
      r.final_cos = cs[l];
      out[l] = std::move(r);
    }
  }

 public:
  // Lyapunov spectrum (Benettin et al. 1980; Shimada & Nagashima 1979) of one point: D tangent
  // vectors through the same RK4 stages, re-orthonormalised by modified Gram–Schmidt (the QR
  // factorisation W = QR) at every renormalisation step of Run; log R_ii summed over the window,
  // into log_sums[0..D). The state takes exactly Run's operations (the same bits: a chaotic orbit is
  // the same orbit), and vector 0 exactly the operations of Run's tangent — Gram–Schmidt leaves the
  // first vector's direction alone and normalises it as Run does — so log_sums[0] is Run's log
  // growth up to the grouping of its logs. Lane 0 only. False when cancelled; *diverged when the
  // state blew up (the sums are then meaningless).
  static bool RunSpectrum(const LaneInput& in, const KernelSettings& s, double* log_sums, bool* diverged) {
    double alpha[W], omega[W];
    CellCoeffs<V> c;
    V amp, x[D], w[D][D], rot_c, rot_s;
    LoadLanes(&in, 1, s.h, alpha, omega, &c, &amp, x, w[0], &rot_c, &rot_s);  // w[0]: Run's tangent
    for (int j = 1; j < D; ++j)
      for (int d = 0; d < D; ++d) w[j][d] = Splat<W>(d == j ? 1.0 : 0.0);  // independent of w[0]
    V sums[D] = {};
    *diverged = false;
    V sn, cs;
    AnchorPhase<W>(omega, 0, s.h, &sn, &cs);
    V k1[D];
    Model::Rhs(c, x, amp * sn, k1);
    for (long step = 1; step <= s.n_total; ++step) {
      StepSpectrum(c, amp, rot_c, rot_s, s.h, x, k1, w, &sn, &cs);
      if (step % kReanchor == 0) {
        if (CancelRequested()) [[unlikely]]
          return false;
        AnchorPhase<W>(omega, step, s.h, &sn, &cs);
        Model::Rhs(c, x, amp * sn, k1);
      }
      if (step % s.renorm_every == 0 || step == s.n_keep || step == s.n_total) {
        V r[D];
        GramSchmidt(w, r);
        if (!std::isfinite(x[0][0]) || std::fabs(x[0][0]) > 1e8 || !std::isfinite(r[0][0])) {
          *diverged = true;
          return true;
        }
        if (step > s.n_keep)
          for (int j = 0; j < D; ++j)
            for (int l = 0; l < W; ++l) sums[j][l] += std::log(r[j][l]);
      }
    }
    for (int j = 0; j < D; ++j) log_sums[j] = sums[j][0];
    return true;
  }

 private:
  // Lane inputs into packs (unused lanes repeat lane 0), the forcing's half-step rotation, and the
  // tangent's fixed, generic start direction (it aligns with the leading direction in the transient).
  static void LoadLanes(const LaneInput* lanes, int n, double h, double* alpha, double* omega, CellCoeffs<V>* c, V* amp,
                        V* x, V* w, V* rot_c, V* rot_s) {
    for (int l = 0; l < W; ++l) {
      const LaneInput& in = lanes[l < n ? l : 0];
      alpha[l] = in.alpha;
      omega[l] = in.omega;
      c->k_lin[l] = in.coeffs.k_lin;
      c->eps[l] = in.coeffs.eps;
      c->eta[l] = in.coeffs.eta;
      c->eta_r[l] = in.coeffs.eta_r;
      c->phi[l] = in.coeffs.phi;
      c->lambda2[l] = in.coeffs.lambda2;
      (*amp)[l] = in.alpha * in.omega * in.omega;
      (*rot_c)[l] = std::cos(0.5 * in.omega * h);
      (*rot_s)[l] = std::sin(0.5 * in.omega * h);
      for (int d = 0; d < D; ++d) {
        x[d][l] = in.x0[d];
        w[d][l] = 1.0 / std::sqrt(static_cast<double>(D)) * (d % 2 == 0 ? 1.0 : -1.0);
      }
    }
  }

  // Step with D tangent vectors: the state's operations are Step's, and each vector's are Step's
  // tangent operations.
  static void StepSpectrum(const CellCoeffs<V>& c, V amp, V rot_c, V rot_s, double h, V* x, V* k1, V (*w)[D], V* sn,
                           V* cs) {
    const V s_mid = Fma(*sn, rot_c, *cs * rot_s), c_mid = Fma(*cs, rot_c, -(*sn * rot_s));
    const V s_end = Fma(s_mid, rot_c, c_mid * rot_s), c_end = Fma(c_mid, rot_c, -(s_mid * rot_s));
    const V fm = amp * s_mid, f1 = amp * s_end;
    const double hh = 0.5 * h, h6 = h / 6.0;
    V xs[D], k[D], acc[D], x_mid1[D], x_mid2[D], x_end[D];
    // The state's stages first (they do not depend on the tangents), keeping every stage point.
    for (int d = 0; d < D; ++d) acc[d] = k1[d], xs[d] = Fma(hh, k1[d], x[d]), x_mid1[d] = xs[d];
    Model::Rhs(c, xs, fm, k);
    for (int d = 0; d < D; ++d) acc[d] = Fma(2.0, k[d], acc[d]), xs[d] = Fma(hh, k[d], x[d]), x_mid2[d] = xs[d];
    Model::Rhs(c, xs, fm, k);
    for (int d = 0; d < D; ++d) acc[d] = Fma(2.0, k[d], acc[d]), xs[d] = Fma(h, k[d], x[d]), x_end[d] = xs[d];
    Model::Rhs(c, xs, f1, k);
    // Each tangent vector through the same stages at the same stage points.
    for (int j = 0; j < D; ++j) {
      V l[D], ws[D], accw[D];
      Model::Tangent(c, x, w[j], l);
      for (int d = 0; d < D; ++d) accw[d] = l[d], ws[d] = Fma(hh, l[d], w[j][d]);
      Model::Tangent(c, x_mid1, ws, l);
      for (int d = 0; d < D; ++d) accw[d] = Fma(2.0, l[d], accw[d]), ws[d] = Fma(hh, l[d], w[j][d]);
      Model::Tangent(c, x_mid2, ws, l);
      for (int d = 0; d < D; ++d) accw[d] = Fma(2.0, l[d], accw[d]), ws[d] = Fma(h, l[d], w[j][d]);
      Model::Tangent(c, x_end, ws, l);
      for (int d = 0; d < D; ++d) w[j][d] = Fma(h6, accw[d] + l[d], w[j][d]);
    }
    for (int d = 0; d < D; ++d) x[d] = Fma(h6, acc[d] + k[d], x[d]);
    *sn = s_end;
    *cs = c_end;
    Model::Rhs(c, x, f1, k1);
  }

  // Modified Gram–Schmidt: w ← Q, r[j] = R_jj. Vector 0 is normalised with Renormalise's operations.
  static void GramSchmidt(V (*w)[D], V* r) {
    for (int j = 0; j < D; ++j) {
      for (int i = 0; i < j; ++i) {
        V p = w[i][0] * w[j][0];
        for (int d = 1; d < D; ++d) p = Fma(w[i][d], w[j][d], p);
        for (int d = 0; d < D; ++d) w[j][d] = Fma(-p, w[i][d], w[j][d]);
      }
      V n2 = w[j][0] * w[j][0];
      for (int d = 1; d < D; ++d) n2 = Fma(w[j][d], w[j][d], n2);
      const V nrm = Sqrt<W>(n2);
      const V inv = 1.0 / nrm;
      for (int d = 0; d < D; ++d) w[j][d] = w[j][d] * inv;
      r[j] = nrm;
    }
  }

  struct Consts {
    CellCoeffs<V> c;
    V amp, rot_c, rot_s;
    double h;
  };

  // The renormalisation state RunFast advances: the window's growth product and its batch count,
  // the divergence flags, and the interval.
  struct TangentState {
    V* growth;
    int* growth_batch;
    bool* diverged;
    int renorm_every;
  };

  // The first step ≥ step that needs the general loop body (lane_run.h). Renormalisations run inside
  // RunFast except the window's one that completes a growth batch (its log is taken there).
  static long NextSpecialStep(long step, const KernelSettings& s, long next_strobe, int growth_batch) {
    const long batch_end = step <= s.n_keep ? s.n_total
                                            : RoundUpTo(step, s.renorm_every) +
                                                  static_cast<long>(kGrowthBatch - 1 - growth_batch) * s.renorm_every;
    return bistable::NextSpecialStep(step, s.n_total, s.n_keep, kReanchor, next_strobe, batch_end);
  }

  // Steps [from, to), all ordinary (see NextSpecialStep); returns the next step to do, short of `to`
  // when the recorder's turning-point buffer filled up. Not inlined, with its state copied into
  // locals: a call clobbers every vector register, so the loop is kept free of them and its lane
  // vectors stay in registers (the general loop around it calls log, sin, cos and allocators).
  template <bool kWindow>
  [[gnu::noinline]] static long RunFast(const Consts& kc, long from, long to, V* x_io, V* k1_io, V* w_io, V* q_io,
                                        V* sn_io, V* cs_io, WindowRecorder<D, W>* rec, TangentState tg) {
    const Consts k = kc;
    V x[D], k1[D], w[D], q[4], sn = *sn_io, cs = *cs_io;
    for (int d = 0; d < D; ++d) x[d] = x_io[d], k1[d] = k1_io[d], w[d] = w_io[d];
    for (int i = 0; i < 4; ++i) q[i] = q_io[i];
    typename WindowRecorder<D, W>::Running r = rec->running();
    V* samples = kWindow ? rec->ReserveSamples(to - from) : nullptr;
    V growth = *tg.growth;
    int growth_batch = *tg.growth_batch;
    int until_renorm = tg.renorm_every - static_cast<int>((from - 1) % tg.renorm_every);
    long step = from;
    while (step < to) {
      const V y0 = x[0], v0 = x[1];
      Step(k.c, k.amp, k.rot_c, k.rot_s, k.h, x, k1, w, &sn, &cs);
      bool room = true;
      if constexpr (kWindow) {
        V g[4];
        Quad(k.c, x, k.amp * sn, g);
        for (int i = 0; i < 4; ++i) q[i] = q[i] + g[i];
        room = rec->Track(r, step, y0, v0, x, cs, samples);
      }
      if (--until_renorm == 0) {
        until_renorm = tg.renorm_every;
        Renormalise(w, kWindow ? &growth : nullptr, tg.diverged, x);
        if constexpr (kWindow) ++growth_batch;
      }
      ++step;
      if (!room) break;
    }
    *tg.growth = growth;
    *tg.growth_batch = growth_batch;
    for (int d = 0; d < D; ++d) x_io[d] = x[d], k1_io[d] = k1[d], w_io[d] = w[d];
    for (int i = 0; i < 4; ++i) q_io[i] = q[i];
    *sn_io = sn, *cs_io = cs;
    if constexpr (kWindow) {
      rec->running() = r;
      rec->CommitSamples(samples);
    }
    return step;
  }

  // Integrands of the window quadratures at state x under forcing f: P, max(P, 0), η y'², φη_r(y' − y_r')².
  static BISTABLE_INLINE void Quad(const CellCoeffs<V>& c, const V* x, V f, V* g) {
    const V p = Model::Power(c, x, f);
    g[0] = p;
    g[1] = Max<W>(p, Splat<W>(0.0));
    g[2] = Model::DissMain(c, x);
    g[3] = Model::DissRes(c, x);
  }
  // Their time derivatives along the flow (dx = F(x, f), fdot = df/dτ; g from Quad at the same point):
  // the end correction of the trapezoid rule. max(P, 0)' is P' where P > 0, else 0.
  static void QuadRate(const CellCoeffs<V>& c, const V* x, const V* dx, V f, V fdot, const V* g, V* gd) {
    gd[0] = Model::PowerRate(c, x, dx, f, fdot);
    for (int l = 0; l < W; ++l) gd[1][l] = g[0][l] > 0.0 ? gd[0][l] : 0.0;
    gd[2] = Model::DissMainRate(c, x, dx);
    gd[3] = Model::DissResRate(c, x, dx);
  }

  // One RK4 step of state and tangent. On entry k1 = F(x, f(t)); on exit x, w advanced,
  // k1 = F(x_new, f(t + h)), (sn, cs) = (sin, cos)(Ω(t + h)).
  static BISTABLE_INLINE void Step(const CellCoeffs<V>& c, V amp, V rot_c, V rot_s, double h, V* x, V* k1, V* w, V* sn,
                                   V* cs) {
    const V s_mid = Fma(*sn, rot_c, *cs * rot_s), c_mid = Fma(*cs, rot_c, -(*sn * rot_s));
    const V s_end = Fma(s_mid, rot_c, c_mid * rot_s), c_end = Fma(c_mid, rot_c, -(s_mid * rot_s));
    const V fm = amp * s_mid, f1 = amp * s_end;
    const double hh = 0.5 * h, h6 = h / 6.0;
    // Stages are folded into running sums as they are made, acc = ((k1 + 2k2) + 2k3) + k4 (each
    // "+ 2k" one fused multiply-add, exact in the product), and x ← x + h/6·acc is fused as well:
    // fewer operations and a shorter dependency chain per stage than separate multiplies and adds.
    V xs[D], ws[D], k[D], l[D], acc[D], accw[D];
    Model::Tangent(c, x, w, l);
    for (int d = 0; d < D; ++d) {
      acc[d] = k1[d], accw[d] = l[d];
      xs[d] = Fma(hh, k1[d], x[d]), ws[d] = Fma(hh, l[d], w[d]);
    }
    // Stages 2 and 3: evaluate at the midpoint, add twice into the sums, step the next stage point
    // (by h/2 after stage 2, by h after stage 3).
    auto mid_stage = [&](double next) BISTABLE_INLINE_LAMBDA {
      Model::Rhs(c, xs, fm, k);
      Model::Tangent(c, xs, ws, l);
      for (int d = 0; d < D; ++d) {
        acc[d] = Fma(2.0, k[d], acc[d]), accw[d] = Fma(2.0, l[d], accw[d]);
        xs[d] = Fma(next, k[d], x[d]), ws[d] = Fma(next, l[d], w[d]);
      }
    };
    mid_stage(hh);
    mid_stage(h);
    Model::Rhs(c, xs, f1, k);
    Model::Tangent(c, xs, ws, l);
    for (int d = 0; d < D; ++d) {
      x[d] = Fma(h6, acc[d] + k[d], x[d]);
      w[d] = Fma(h6, accw[d] + l[d], w[d]);
    }
    *sn = s_end;
    *cs = c_end;
    Model::Rhs(c, x, f1, k1);
  }

  // w ← w/|w|, and *growth ×= |w| (unless growth is null). Lanes that blew up are flagged and reset
  // so they cannot poison timing.
  static BISTABLE_INLINE void Renormalise(V* w, V* growth, bool* diverged, V* x) {
    V n2 = w[0] * w[0];
    for (int d = 1; d < D; ++d) n2 = Fma(w[d], w[d], n2);
    const V nrm = Sqrt<W>(n2);
    const V inv = 1.0 / nrm;
    for (int d = 0; d < D; ++d) w[d] = w[d] * inv;
    if (growth) *growth = *growth * nrm;
    for (int l = 0; l < W; ++l) {
      if (!std::isfinite(x[0][l]) || std::fabs(x[0][l]) > 1e8 || !std::isfinite(nrm[l])) {
        diverged[l] = true;
        for (int d = 0; d < D; ++d) x[d][l] = 0.0, w[d][l] = (d == 0);
      }
    }
  }

  // Σ log|w| over the window, one log per kGrowthBatch renormalisations instead of one each: the
  // norms multiply into growth, whose log goes to the recorder at the end of a batch (all lanes) or
  // as soon as a lane's product leaves [1e-150, 1e150] (that lane) — decisions of each lane's own,
  // so its bits do not depend on its neighbours or on W.
  static constexpr int kGrowthBatch = 16;
  static void FlushGrowth(V* growth, bool all, WindowRecorder<D, W>* rec) {
    V lg = Splat<W>(0.0);
    bool any = false;
    for (int l = 0; l < W; ++l) {
      const double g = (*growth)[l];
      if (all || !(g >= 1e-150 && g <= 1e150)) {
        lg[l] = std::log(g);
        (*growth)[l] = 1.0;
        any = true;
      }
    }
    if (any) rec->AddLogGrowth(lg);
  }
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_ENSEMBLE_RK4_H_
