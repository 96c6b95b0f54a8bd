// Collects, per lane, what the metrics of model.md §3 need from the steady-state window, one
// integration step at a time: max |absolute velocity| (FRF), extremes of y_m (motion type),
// stroboscopic samples at τ_k = (φ + 2πk)/Ω by cubic Hermite interpolation inside the step (period n
// and the Poincaré section; φ the section phase, 0 by default),
// decimated samples (spectrum, Rosenstein, trace) and the Benettin log-growth sum.
// Both the SIMD RK4 kernel (W lanes) and the adaptive path (W = 1) feed it, so the metrics are
// computed by one piece of code. Not thread-safe; one recorder per integration.
#ifndef BISTABLE_DYNAMICS_WINDOW_RECORDER_H_
#define BISTABLE_DYNAMICS_WINDOW_RECORDER_H_

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "base/limits.h"
#include "dynamics/lanes.h"

namespace bistable {

// Raw window record of one lane; turned into metrics by ComputePointMetrics.
struct RawLane {
  double vabs_max = 0;  // max |y_m' + αΩ cos Ωτ| over window steps
  double y_min = 0, y_max = 0;
  double log_growth = 0;  // Σ log(|w| before renormalisation) over the window
  // The same sum by batches of renormalisations (the kernel's growth batches, 16 renormalisations or
  // the rest of the window): block_logs[i] over block_steps[i] steps (the settled labels' σ_λ).
  std::vector<double> block_logs;
  std::vector<long> block_steps;
  std::vector<double> strobe_y, strobe_v;    // y_m, y_m' at τ_k = (φ + 2πk)/Ω in the window (φ: strobe phase)
  std::vector<double> strobe_yr, strobe_vr;  // y_r, y_r' at the same τ_k (models with a resonator, D = 4)
  long strobe_k0 = 0;                        // k of the first strobe (τ_k ≥ t_keep)
  std::vector<double> y_samples;             // y_m every sample_every steps
  std::vector<std::array<double, 5>> rows;   // (τ, y_m, y_m', y_r, y_r') when keep_rows
  std::vector<double> turning_points;        // y_m where y_m' changes sign in the window (bifurcation diagrams)
  std::array<double, 4> final_state = {0, 0, 0, 0};  // state at t_end (continuation of the next point)
  // Where a chain of windows (settled labels) resumes exactly: the tangent (normalised) and the
  // forcing phase (sin, cos)(Ωτ) as the kernel carries them at t_end.
  std::array<double, 4> final_tangent = {0, 0, 0, 0};
  double final_sin = 0, final_cos = 1;
  double q_p = 0, q_in = 0, q_m = 0, q_r = 0;  // ∫P, ∫max(P,0), W_m, W_r over the window
  double e_start = 0, e_end = 0;               // E at t_keep and t_end
  bool diverged = false;
  long steps = 0;
  long rhs_evals = 0;
};

template <int D, int W>
class WindowRecorder {
 public:
  using V = Vec<W>;

  // alpha/omega: per lane. h: step. n_keep: index of the first window step. sample_every: decimation.
  // strobe_phase: φ ∈ [0, 2π), the phase Ωτ mod 2π of the strobes (0: τ_k = 2πk/Ω, bit for bit as
  // without it).
  WindowRecorder(const double* alpha, const double* omega, double h, long n_keep, int sample_every, bool keep_samples,
                 bool keep_rows, double strobe_phase = 0.0)
      : h_(h), n_keep_(n_keep), sample_every_(sample_every), keep_samples_(keep_samples), keep_rows_(keep_rows) {
    for (int l = 0; l < W; ++l) {
      alpha_omega_[l] = alpha[l] * omega[l];
      strobe_period_[l] = 2.0 * M_PI / omega[l];
      strobe_offset_[l] = strobe_phase / omega[l];
      // First strobe index k with τ_k ≥ t_keep.
      next_k_[l] =
          static_cast<long>(std::ceil((static_cast<double>(n_keep) * h - strobe_offset_[l]) / strobe_period_[l]));
      lanes_[l].strobe_k0 = next_k_[l];
      Schedule(l);
    }
    run_.vabs_max = Splat<W>(0.0);
    run_.y_min = Splat<W>(std::numeric_limits<double>::infinity());
    run_.y_max = Splat<W>(-std::numeric_limits<double>::infinity());
    run_.until_sample = 1;  // the window's first step (n_keep) is sampled
  }

  ~WindowRecorder() {
    if (y_samples_.capacity() > Pool().capacity()) Pool() = std::move(y_samples_);
  }
  WindowRecorder(const WindowRecorder&) = delete;
  WindowRecorder& operator=(const WindowRecorder&) = delete;

  // Per-step running values of the window. The kernel's fast loop copies them into locals (registers)
  // for a run of ordinary steps and hands them back (running()).
  struct Running {
    V vabs_max, y_min, y_max;
    int until_sample;
  };
  Running& running() { return run_; }

  // The call-free part of window step n (> n_keep, or == n_keep for the window's first point), which
  // goes from (y0, v0) = (y_m, y_m') at its start to x1: turning points into the buffer, extremes, and every
  // sample_every-th y_m written to *samples (room reserved by ReserveSamples). No strobes: callers use it only for
  // steps with none due (OnStep does the rest). Returns false when the turning-point buffer is full: flush before the
  // next step (Track needs room for one entry).
  BISTABLE_INLINE bool Track(Running& r, long n, V y0, V v0, const V* x1, V cos_end, V*& samples) {
    // Turning points: y_m' changes sign within the step; y_m at the crossing
    // is found when the buffer is flushed (FlushTurningPoints).
    if (n > n_keep_) {
      if (PositiveMask(v0) != PositiveMask(x1[1])) tp_buf_[tp_count_++] = {y0, v0, x1[0], x1[1]};
    }
    const V vabs = Abs<W>(x1[1] + Load(alpha_omega_) * cos_end);
    r.vabs_max = Max<W>(r.vabs_max, vabs);
    r.y_min = Min<W>(r.y_min, x1[0]);
    r.y_max = Max<W>(r.y_max, x1[0]);
    if (--r.until_sample == 0) {
      r.until_sample = sample_every_;
      if (keep_samples_) *samples++ = x1[0];
    }
    return tp_count_ < kTpBuffer;
  }

  bool TurningPointBufferFull() const { return tp_count_ == kTpBuffer; }

  // Room for the samples of the next `steps` steps; returns where the next one goes.
  V* ReserveSamples(long steps) {
    const size_t need = n_samples_ + static_cast<size_t>(steps / sample_every_ + 1);
    if (keep_samples_ && y_samples_.size() < need) y_samples_.resize(std::max(need, 2 * y_samples_.size()));
    return y_samples_.data() + n_samples_;
  }
  void CommitSamples(const V* end) { n_samples_ = static_cast<size_t>(end - y_samples_.data()); }

  // y_m at each buffered crossing, by the cubic Hermite through both ends of its step (whose end
  // slopes are exactly those velocities), appended per lane in time order.
  void FlushTurningPoints() {
    for (int i = 0; i < tp_count_; ++i) {
      const TpEntry& e = tp_buf_[i];
      const unsigned long crossed = PositiveMask(e.v0) ^ PositiveMask(e.v1);
      for (int l = 0; l < W; ++l) {
        if (!(crossed >> l & 1)) continue;
        const double v0 = e.v0[l], v1 = e.v1[l], th = v0 / (v0 - v1);
        const double t2 = th * th, t3 = t2 * th;
        const double y = (2 * t3 - 3 * t2 + 1) * e.y0[l] + (t3 - 2 * t2 + th) * h_ * v0 + (-2 * t3 + 3 * t2) * e.y1[l] +
                         (t3 - t2) * h_ * v1;
        std::vector<double>& tp = lanes_[l].turning_points;
        // Keep the last ones only (bounded memory on long windows; sweeps store the last 64).
        if (tp.size() >= 2 * limits::kMaxTurningPointsKept)
          tp.erase(tp.begin(), tp.end() - limits::kMaxTurningPointsKept);
        tp.push_back(y);
      }
    }
    tp_count_ = 0;
  }

  // Step n (window steps n > n_keep) goes from τ = (n−1)h to τ = nh; x/d are state and derivative
  // at both ends (x0 is the state the step started from: turning points and strobes interpolate
  // between the ends); cos_end = cos(Ω nh) per lane. The first call (n == n_keep) passes the
  // window's start point as both ends.
  void OnStep(long n, const V* x0, const V* d0, const V* x1, const V* d1, V cos_end) {
    const bool sample_now = run_.until_sample == 1;
    V* samples = ReserveSamples(1);
    if (!Track(run_, n, x0[0], x0[1], x1, cos_end, samples)) FlushTurningPoints();
    CommitSamples(samples);
    // Strobes: each lane's next τ_k is due in step strobe_step_[l]; one integer compare per step
    // against the earliest of them.
    if (n >= next_due_) {
      const double t0 = static_cast<double>(n - 1) * h_;
      for (int l = 0; l < W; ++l) {
        while (strobe_step_[l] <= n) {
          const double ts = StrobeTime(l);
          if (n == n_keep_) {
            Strobe(l, 0.0, x1, d1, x1, d1);
          } else {
            Strobe(l, std::clamp((ts - t0) / h_, 0.0, 1.0), x0, d0, x1, d1);
          }
          ++next_k_[l];
          Schedule(l);
        }
      }
      next_due_ = strobe_step_[0];
      for (int l = 1; l < W; ++l) next_due_ = std::min(next_due_, strobe_step_[l]);
    }
    if (sample_now && keep_rows_) {
      rows_.push_back(x1[0]);
      rows_.push_back(x1[1]);
      if constexpr (D > 2) rows_.push_back(x1[2]), rows_.push_back(x1[3]);
      row_times_.push_back(static_cast<double>(n) * h_);
    }
  }

  double h() const { return h_; }
  void AddLogGrowth(V lg) {
    log_growth_ += lg;
    block_acc_ += lg;
  }
  // A growth batch ended at step n: its per-lane sum becomes one block.
  void EndGrowthBatch(long n) {
    for (int l = 0; l < W; ++l) {
      lanes_[l].block_logs.push_back(block_acc_[l]);
      lanes_[l].block_steps.push_back(n - block_start_);
    }
    block_acc_ = Splat<W>(0.0);
    block_start_ = n;
  }
  // The first step index in which some lane's next strobe falls (callers keep the step's start
  // state only for such steps).
  long next_due() const { return next_due_; }

  // Moves per-lane results out; quadratures and energies are set by the integrator.
  RawLane& Lane(int l) {
    FlushTurningPoints();
    RawLane& r = lanes_[l];
    r.y_samples.resize(n_samples_);
    for (size_t i = 0; i < n_samples_; ++i) r.y_samples[i] = y_samples_[i][l];
    r.rows.resize(row_times_.size());
    for (size_t i = 0; i < row_times_.size(); ++i) {
      const V* row = &rows_[i * D];
      r.rows[i] = {row_times_[i], row[0][l], row[1][l], 0.0, 0.0};
      if constexpr (D > 2) r.rows[i][3] = row[2][l], r.rows[i][4] = row[3][l];
    }
    lanes_[l].vabs_max = run_.vabs_max[l];
    lanes_[l].y_min = run_.y_min[l];
    lanes_[l].y_max = run_.y_max[l];
    lanes_[l].log_growth = log_growth_[l];
    return lanes_[l];
  }

 private:
  static V Load(const double* a) {
    V v;
    for (int l = 0; l < W; ++l) v[l] = a[l];
    return v;
  }
  // τ_k of lane l's next strobe.
  double StrobeTime(int l) const { return static_cast<double>(next_k_[l]) * strobe_period_[l] + strobe_offset_[l]; }
  // The step in which lane l's next strobe time falls: the smallest n with n·h ≥ τ_k.
  void Schedule(int l) {
    const double ts = StrobeTime(l);
    long n = static_cast<long>(std::ceil(ts / h_));
    if (static_cast<double>(n - 1) * h_ >= ts) --n;  // guard the division's rounding
    strobe_step_[l] = std::max(n, n_keep_);
  }

  // Cubic Hermite on [x0, x1] at θ ∈ [0, 1] for each state component (its derivative is d's).
  void Strobe(int l, double th, const V* x0, const V* d0, const V* x1, const V* d1) {
    const double t2 = th * th, t3 = t2 * th;
    const double h00 = 2 * t3 - 3 * t2 + 1, h10 = t3 - 2 * t2 + th, h01 = -2 * t3 + 3 * t2, h11 = t3 - t2;
    auto at = [&](int d) { return h00 * x0[d][l] + h10 * h_ * d0[d][l] + h01 * x1[d][l] + h11 * h_ * d1[d][l]; };
    lanes_[l].strobe_y.push_back(at(0));
    lanes_[l].strobe_v.push_back(at(1));
    if constexpr (D > 2) lanes_[l].strobe_yr.push_back(at(2)), lanes_[l].strobe_vr.push_back(at(3));
  }

  double h_;
  long n_keep_;
  int sample_every_;
  bool keep_samples_, keep_rows_;
  double alpha_omega_[W];
  double strobe_period_[W];
  double strobe_offset_[W];  // φ/Ω: τ_k = k·2π/Ω + φ/Ω
  long next_k_[W];
  long strobe_step_[W];
  long next_due_ = 0;
  Running run_;
  struct TpEntry {
    V y0, v0, y1, v1;  // (y_m, y_m') at both ends of a step in which some lane's y_m' changed sign
  };
  static constexpr int kTpBuffer = 32;
  TpEntry tp_buf_[kTpBuffer];
  int tp_count_ = 0;
  // [0, n_samples_) written. The storage is borrowed from a per-thread pool and handed back by the
  // destructor: sweeps run thousands of blocks per thread, and a fresh ~0.3 MB buffer each time
  // costs page faults (a nested recorder simply starts with an empty one).
  static std::vector<V>& Pool() {
    thread_local std::vector<V> pool;
    return pool;
  }
  std::vector<V> y_samples_ = std::move(Pool());
  size_t n_samples_ = 0;
  std::vector<V> rows_;  // D lane vectors per row
  std::vector<double> row_times_;
  V log_growth_ = Splat<W>(0.0);
  V block_acc_ = Splat<W>(0.0);
  long block_start_ = n_keep_;
  std::array<RawLane, W> lanes_;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_WINDOW_RECORDER_H_
