#include "dynamics/settle.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <vector>

#include "dynamics/point.h"

namespace bistable {
namespace {

// One point's chain: where it resumes, the window being assembled from chunks, the run's growth
// blocks and the summaries of its windows.
struct ChainLane {
  size_t item = 0;
  LaneInput input;
  int chunks = 1;     // kernel windows (chunks) per label window
  int in_window = 0;  // chunks merged into acc so far
  RawLane acc;
  long acc_start = 0;                          // step at which acc's window starts
  long cap_step = 0;                           // the lane's last window end: unresolved there
  std::vector<double> logs, log_tau, log_end;  // growth blocks: Σ log|w|, length τ, end τ − t_keep
  struct Window {
    int period = 0;
    int well = 0;          // 0 intrawell, 1 interwell
    bool chaotic = false;  // the window's own λ > threshold
    double spread = 0;     // rms distance of its strobes from their mean in (y_m, y_m')
  };
  std::vector<Window> windows;
  std::vector<double> strobes;     // y_m at every strobe since t_keep (the 0-1 test)
  std::vector<double> strobe_tau;  // their τ − t_keep
  bool done = false;
};

double Spread(const std::vector<double>& y, const std::vector<double>& v) {
  const size_t m = y.size();
  if (m == 0) return 0;
  double my = 0, mv = 0;
  for (size_t i = 0; i < m; ++i) my += y[i], mv += v[i];
  my /= m, mv /= m;
  double s = 0;
  for (size_t i = 0; i < m; ++i) s += (y[i] - my) * (y[i] - my) + (v[i] - mv) * (v[i] - mv);
  return std::sqrt(s / m);
}

// λ and its block-average standard error over the growth blocks ending after `from` (τ − t_keep): the
// blocks grouped into ≥ 10 groups of equal count (the rest joins the last); σ = ∞ with fewer than 10.
void LambdaSigma(const ChainLane& c, double from, double* lambda, double* sigma) {
  size_t first = 0;
  while (first < c.log_end.size() && c.log_end[first] <= from) ++first;
  const size_t nb = c.logs.size() - first;
  double sl = 0, st = 0;
  for (size_t i = first; i < c.logs.size(); ++i) sl += c.logs[i], st += c.log_tau[i];
  *lambda = st > 0 ? sl / st : 0.0;
  if (nb < 10) {
    *sigma = std::numeric_limits<double>::infinity();
    return;
  }
  const size_t per = nb / 10, groups = nb / per;
  std::vector<double> lam(groups, 0.0), tau(groups, 0.0);
  for (size_t i = 0; i < nb; ++i) {
    const size_t g = std::min(i / per, groups - 1);
    lam[g] += c.logs[first + i];
    tau[g] += c.log_tau[first + i];
  }
  double ss = 0;
  for (size_t g = 0; g < groups; ++g) {
    const double d = lam[g] / tau[g] - *lambda;
    ss += d * d;
  }
  *sigma = std::sqrt(ss / (static_cast<double>(groups) * static_cast<double>(groups - 1)));
}

// The strobe recurrence without the period metric's spectrum checks: 1, 0 when none, −1 for n ≥ 2 (its
// sub-harmonic checks need the window's spectrum, so the full metrics decide). Equal to the period metric
// whenever that is 0 or 1.
int RecurrencePeriod(const std::vector<double>& y, const std::vector<double>& v, int max_period, double tol) {
  const int n = StrobeRecurrence(y, v, max_period, tol);
  return n <= 1 ? n : -1;
}

}  // namespace

// The 0-1 test for chaos (Gottwald & Melbourne 2004; the correlation form with the oscillatory term
// removed, Gottwald & Melbourne 2009, SIAM J. Appl. Dyn. Syst. 8, 129): for the series φ_j (here the
// strobes y_m, one per forcing period), p_c(n) = Σ_{j≤n} φ_j cos jc, q_c(n) = Σ φ_j sin jc, the mean square
// displacement M_c(n) over n ≤ N/10, D_c(n) = M_c(n) − (Eφ)² (1 − cos nc)/(1 − cos c), and K_c the
// correlation of D_c(n) with n; K is the median of K_c over 16 fixed c in (π/5, 4π/5). K ≈ 1 for chaos
// (the (p, q) walk diffuses), ≈ 0 for regular motion (it stays bounded). NaN for fewer than 64 values.
double ZeroOneTestK(const double* phi, size_t n_all) {
  constexpr size_t kMin = 64, kMax = 400;
  constexpr int kC = 16;
  if (n_all < kMin) return std::numeric_limits<double>::quiet_NaN();
  const size_t N = std::min(n_all, kMax);
  phi += n_all - N;  // the latest
  double mean = 0;
  for (size_t j = 0; j < N; ++j) mean += phi[j];
  mean /= static_cast<double>(N);
  const size_t ncut = N / 10;
  std::vector<double> p(N + 1), q(N + 1), d(ncut + 1);
  std::array<double, kC> ks;
  for (int ci = 0; ci < kC; ++ci) {
    // Fixed, irrationally spaced c (golden-ratio offsets) avoid the resonances 2πk/n of periodic data.
    const double frac = std::fmod(0.5 + 0.6180339887498949 * ci, 1.0);
    const double c = M_PI / 5 + frac * (3 * M_PI / 5);
    p[0] = q[0] = 0;
    const double cc = std::cos(c), sc = std::sin(c);
    double cj = 1, sj = 0;  // cos jc, sin jc by rotation (re-anchored every 64 terms)
    for (size_t j = 1; j <= N; ++j) {
      if (j % 64 == 0) {
        cj = std::cos(static_cast<double>(j) * c), sj = std::sin(static_cast<double>(j) * c);
      } else {
        const double cn = cj * cc - sj * sc;
        sj = sj * cc + cj * sc, cj = cn;
      }
      p[j] = p[j - 1] + phi[j - 1] * cj;
      q[j] = q[j - 1] + phi[j - 1] * sj;
    }
    for (size_t k = 1; k <= ncut; ++k) {
      double msd = 0;
      for (size_t j = 0; j + k <= N; ++j) {
        const double dp = p[j + k] - p[j], dq = q[j + k] - q[j];
        msd += dp * dp + dq * dq;
      }
      msd /= static_cast<double>(N - k + 1);
      d[k] = msd - mean * mean * (1 - std::cos(static_cast<double>(k) * c)) / (1 - std::cos(c));
    }
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
    for (size_t k = 1; k <= ncut; ++k) {
      const double x = static_cast<double>(k), y = d[k];
      sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y;
    }
    const double m = static_cast<double>(ncut);
    const double vx = sxx - sx * sx / m, vy = syy - sy * sy / m, cxy = sxy - sx * sy / m;
    ks[ci] = vx > 0 && vy > 0 ? std::clamp(cxy / std::sqrt(vx * vy), -1.0, 1.0) : 0.0;
  }
  std::sort(ks.begin(), ks.end());
  return 0.5 * (ks[kC / 2 - 1] + ks[kC / 2]);
}

namespace {

// The 0-1 test on a lane's strobes: those of [T/2, T] since t_keep, or the latest 64 when that half holds
// fewer (low Ω), at most the latest 400.
double LaneK(const ChainLane& c, double half) {
  size_t first = 0;
  while (first < c.strobe_tau.size() && c.strobe_tau[first] < half) ++first;
  size_t n = c.strobes.size() - first;
  if (n < 64) n = std::min<size_t>(64, c.strobes.size());
  return ZeroOneTestK(c.strobes.data() + (c.strobes.size() - n), n);
}

// The next kernel window (chunk) appended to the label window being assembled.
void Append(RawLane* acc, RawLane&& r, bool drop_first_sample) {
  acc->vabs_max = std::max(acc->vabs_max, r.vabs_max);
  acc->y_min = std::min(acc->y_min, r.y_min);
  acc->y_max = std::max(acc->y_max, r.y_max);
  acc->log_growth += r.log_growth;
  auto cat = [](std::vector<double>* a, const std::vector<double>& b) { a->insert(a->end(), b.begin(), b.end()); };
  cat(&acc->strobe_y, r.strobe_y);
  cat(&acc->strobe_v, r.strobe_v);
  cat(&acc->strobe_yr, r.strobe_yr);
  cat(&acc->strobe_vr, r.strobe_vr);
  acc->y_samples.insert(acc->y_samples.end(), r.y_samples.begin() + (drop_first_sample && !r.y_samples.empty() ? 1 : 0),
                        r.y_samples.end());
  cat(&acc->turning_points, r.turning_points);
  acc->q_p += r.q_p, acc->q_in += r.q_in, acc->q_m += r.q_m, acc->q_r += r.q_r;
  acc->e_end = r.e_end;
  acc->final_state = r.final_state;
  acc->final_tangent = r.final_tangent;
  acc->final_sin = r.final_sin, acc->final_cos = r.final_cos;
  acc->steps = r.steps, acc->rhs_evals = r.rhs_evals;
  acc->diverged = acc->diverged || r.diverged;
}

template <int W>
class Sink {
 public:
  Sink(const PointSpec* specs, PointResult* out, ChainLane** lanes, long n_keep, double h, long window_steps)
      : specs_(specs), out_(out), lanes_(lanes), n_keep_(n_keep), h_(h), window_steps_(window_steps) {}

  void OnWindow(RawLane* raw, int n, long step, bool* done) {
    std::array<RawLane, W> eval_raw;
    std::array<PointSpec, W> eval_spec;
    std::array<int, W> eval_lane;
    int m = 0;
    const double t0 = static_cast<double>(n_keep_) * h_;
    for (int l = 0; l < n; ++l) {
      ChainLane& c = *lanes_[l];
      if (c.done) {
        done[l] = true;
        continue;
      }
      RawLane& r = raw[l];
      c.input.x0 = r.final_state;
      c.input.resume_tangent = r.final_tangent;
      c.input.resume_sin = r.final_sin;
      c.input.resume_cos = r.final_cos;
      // Growth blocks in time order; the last one ends at this window's end.
      {
        long back = 0;
        for (size_t i = r.block_steps.size(); i-- > 0;) back += r.block_steps[i];
        long at = step - back;
        for (size_t i = 0; i < r.block_steps.size(); ++i) {
          at += r.block_steps[i];
          c.logs.push_back(r.block_logs[i]);
          c.log_tau.push_back(static_cast<double>(r.block_steps[i]) * h_);
          c.log_end.push_back(static_cast<double>(at) * h_ - t0);
        }
      }
      const bool diverged = r.diverged;
      if (c.in_window == 0) {
        c.acc = std::move(r);
        c.acc_start = step - window_steps_;
      } else {
        Append(&c.acc, std::move(r),
               specs_[c.item].metrics.sample_every > 0 && window_steps_ % specs_[c.item].metrics.sample_every == 0);
      }
      ++c.in_window;
      if (c.in_window == c.chunks || diverged) {
        c.in_window = 0;
        eval_raw[m] = std::move(c.acc);
        c.acc = RawLane{};
        PointSpec ps = specs_[c.item];
        ps.integration.t_keep = static_cast<double>(c.acc_start) * h_;
        ps.integration.t_end = static_cast<double>(step) * h_;
        eval_spec[m] = ps;
        eval_lane[m++] = l;
      }
    }
    if (m == 0) return;
    // Per window only what the label needs — λ, the well, the strobes' period and spread — from the raw
    // record; the window's spectrum only when the strobes recur with n ≥ 2 (the period's sub-harmonic
    // checks), and every other metric once, from the window the label settles in.
    std::array<Light, W> light;
    std::array<PointResult, W> got;
    std::array<bool, W> have_full{};
    std::array<int, W> need{};  // zeroed: GCC 12 cannot see that FullMetrics reads only need[0 .. nn)
    int nn = 0;
    for (int i = 0; i < m; ++i) {
      const RawLane& r = eval_raw[i];
      const PointSpec& ps = eval_spec[i];
      Light& g = light[i];
      g.diverged = r.diverged;
      g.lle = r.log_growth / (ps.integration.t_end - ps.integration.t_keep);
      g.y_min = r.y_min, g.y_max = r.y_max;
      g.spread = Spread(r.strobe_y, r.strobe_v);
      g.period =
          r.diverged ? 0 : RecurrencePeriod(r.strobe_y, r.strobe_v, ps.metrics.max_period, ps.metrics.period_tol);
      ChainLane& c = *lanes_[eval_lane[i]];
      const double om = ps.omega, phase = ps.metrics.poincare_phase;
      for (size_t k = 0; k < r.strobe_y.size(); ++k) {
        c.strobes.push_back(r.strobe_y[k]);
        c.strobe_tau.push_back((phase + 2 * M_PI * static_cast<double>(r.strobe_k0 + static_cast<long>(k))) / om - t0);
      }
      if (g.period < 0) need[nn++] = i;
    }
    FullMetrics(eval_raw.data(), eval_spec.data(), need.data(), nn, got.data(), have_full.data());
    for (int k = 0; k < nn; ++k) light[need[k]].period = got[need[k]].period;
    std::array<Label, W> labels;
    nn = 0;
    for (int i = 0; i < m; ++i) {
      labels[i] = Decide(*lanes_[eval_lane[i]], light[i], step);
      if (labels[i].done && !have_full[i]) need[nn++] = i;
    }
    FullMetrics(eval_raw.data(), eval_spec.data(), need.data(), nn, got.data(), have_full.data());
    for (int i = 0; i < m; ++i) {
      const int l = eval_lane[i];
      if (labels[i].done) Finish(*lanes_[l], std::move(got[i]), labels[i], step);
      done[l] = lanes_[l]->done;
    }
  }

 private:
  struct Light {
    bool diverged = false;
    double lle = 0, y_min = 0, y_max = 0, spread = 0;
    int period = 0;
  };
  struct Label {
    bool done = false;
    Motion motion = Motion::kUndefined;
    int period = 0;
    double lambda = 0, sigma = 0, t = 0, confidence = 0, k01 = 0;
  };

  // The full metrics (ComputeBlockMetrics, spectrum included) of the windows which[0..n) of raw, into got.
  void FullMetrics(RawLane* raw, const PointSpec* spec, const int* which, int n, PointResult* got, bool* have) {
    if (n == 0) return;
    std::array<RawLane, W> r;
    std::array<PointSpec, W> sp;
    std::array<PointResult, W> out;
    for (int k = 0; k < n; ++k) r[k] = std::move(raw[which[k]]), sp[k] = spec[which[k]];
    ComputeBlockMetrics<W>(r.data(), sp.data(), n, out.data());
    for (int k = 0; k < n; ++k) got[which[k]] = std::move(out[k]), have[which[k]] = true;
  }

  void Finish(ChainLane& c, PointResult&& r, const Label& lb, long step) {
    r.motion = lb.motion;
    r.period = lb.period;
    r.lle = lb.lambda;
    r.lle_sigma = lb.sigma;
    r.settle_time = lb.t;
    r.label_confidence = lb.confidence;
    r.chaos_01 = lb.k01;
    r.steps = step;
    r.rhs_evals = 4 * step;
    out_[c.item] = std::move(r);
    c.done = true;
  }

  Label Decide(ChainLane& c, const Light& cur, long step) {
    const PointSpec& spec = specs_[c.item];
    const double t = static_cast<double>(step) * h_;
    const double since = t - spec.integration.t_keep;
    const double nan = std::numeric_limits<double>::quiet_NaN();
    Label lb;
    lb.t = t;
    lb.k01 = nan;
    if (cur.diverged) {
      lb.done = true, lb.motion = Motion::kUndefined, lb.lambda = nan, lb.sigma = nan;
      return lb;
    }
    const double thr = spec.metrics.chaos_threshold;
    ChainLane::Window w;
    w.period = cur.period;
    w.well = (!IsBistable(spec.model) || cur.y_min > 0 || cur.y_max < 0) ? 0 : 1;
    w.chaotic = cur.lle > thr;
    w.spread = cur.spread;
    c.windows.push_back(w);
    const Motion well = w.well == 0 ? Motion::kIntrawell : Motion::kInterwell;
    double lambda = cur.lle, sigma = std::numeric_limits<double>::infinity();
    auto label = [&](Motion m, int period, double conf) {
      lb.done = true, lb.motion = m, lb.period = period, lb.lambda = lambda, lb.sigma = sigma, lb.confidence = conf;
      // The 0-1 test where the period does not already tell the motion (K of a periodic label: NaN).
      if (m == Motion::kChaotic || m == Motion::kQuasiPeriodic || m == Motion::kUnresolved)
        lb.k01 = LaneK(c, 0.5 * since);
      return lb;
    };
    if (c.windows.size() >= 2) {
      LambdaSigma(c, 0.5 * since, &lambda, &sigma);
      const ChainLane::Window& p = c.windows[c.windows.size() - 2];
      const double conf = 0.5 * std::erfc(-std::fabs(lambda - thr) / (sigma * std::sqrt(2.0)));
      const bool confirmed = since >= spec.integration.settle_confirm;
      // A period n ≥ 2 must keep its strobe cloud: a decaying flip transient (a Floquet multiplier
      // near −1) alternates from strobe to strobe and passes the recurrence test while it shrinks.
      const double ratio = p.spread > 0 ? w.spread / p.spread : 0.0;
      const bool cloud_kept = w.period == 1 || (ratio >= 0.97 && ratio <= 1.03);
      if (w.period >= 1 && p.period == w.period && p.well == w.well && cloud_kept && lambda + 2 * sigma < 0)
        return label(well, w.period, conf);
      if (confirmed && w.period == 0 && p.period == 0 && w.chaotic && p.chaotic && lambda - 2 * sigma > thr) {
        // The second, independent indicator: the 0-1 test on the strobes must agree (K > 1/2); where it
        // cannot run (fewer than 64 strobes since t_keep, Ω ≲ 0.2 at the defaults) λ − 2σ decides alone.
        const double k = LaneK(c, 0.5 * since);
        if (!(k <= spec.metrics.chaos_01_min)) {
          lb.done = true, lb.motion = Motion::kChaotic, lb.lambda = lambda, lb.sigma = sigma, lb.confidence = conf;
          lb.k01 = k;
          return lb;
        }
      }
      if (confirmed && w.period == 0 && p.period == 0 && p.well == w.well &&
          std::fabs(lambda) <= spec.metrics.quasi_lle && lambda + 2 * sigma < thr && ratio >= 0.8 && ratio <= 1.25)
        return label(Motion::kQuasiPeriodic, 0, conf);
    }
    if (step >= c.cap_step) return label(Motion::kUnresolved, cur.period, 0.0);
    return lb;
  }

  const PointSpec* specs_;
  PointResult* out_;
  ChainLane** lanes_;
  long n_keep_;
  double h_;
  long window_steps_;
};

template <int W, class S>
bool Chain(ModelKind model, const LaneInput* lanes, int n, const KernelSettings& ks, S& sink) {
  if (HasResonator(model)) return EnsembleRk4<CoupledModel, W>::RunChain(lanes, n, ks, sink);
  return EnsembleRk4<SingleModel, W>::RunChain(lanes, n, ks, sink);
}

}  // namespace

template <int W>
bool EvaluateSettled(const PointSpec* specs, size_t n, PointResult* out) {
  if (n == 0) return true;
  const PointSpec& first = specs[0];
  const IntegrationSettings& in = first.integration;
  const double h = in.dt;
  KernelSettings base = KernelSettingsFor(first);
  base.keep_rows = false;
  const long n_keep = StepsFor(in.t_keep, h);
  const long win = StepsFor(in.settle_window, h);
  base.window_steps = win;
  std::vector<std::unique_ptr<ChainLane>> all(n);
  std::vector<ChainLane*> pending;
  long max_cap = 0;
  for (size_t i = 0; i < n; ++i) {
    auto c = std::make_unique<ChainLane>();
    c->item = i;
    c->input = LaneFor(specs[i]);
    const double period = 2 * M_PI / specs[i].omega;
    c->chunks = std::max(
        1, static_cast<int>(std::ceil(specs[i].integration.settle_min_strobes * period / in.settle_window - 1e-9)));
    const long lw = win * c->chunks;
    const long cap = StepsFor(in.settle_cap, h);
    c->cap_step = n_keep + std::max<long>(2, (cap + lw - 1) / lw) * lw;
    max_cap = std::max(max_cap, c->cap_step);
    pending.push_back(c.get());
    all[i] = std::move(c);
  }
  // Rounds: fresh lanes from step 0 to the first tier — the earliest label, t_keep + 2 windows — then the
  // lanes not yet settled, packed side by side, one window at a time, until none is left. A lane that is
  // done keeps stepping unseen only to the end of its round, so every round's blocks are full but the last.
  long from = 0, tier = n_keep + 2 * win;
  while (!pending.empty()) {
    const long to = std::min(tier, max_cap);
    std::vector<ChainLane*> next;
    for (size_t s = 0; s < pending.size(); s += W) {
      const int m = static_cast<int>(std::min<size_t>(W, pending.size() - s));
      std::array<LaneInput, W> lanes;
      std::array<ChainLane*, W> block{};
      long block_cap = 0;
      for (int l = 0; l < m; ++l) {
        block[l] = pending[s + l];
        lanes[l] = block[l]->input;
        block_cap = std::max(block_cap, block[l]->cap_step);
      }
      KernelSettings ks = base;
      ks.step0 = from;
      ks.n_keep = from == 0 ? n_keep : from;
      ks.n_total = std::min(to, block_cap);
      Sink<W> sink(specs, out, block.data(), n_keep, h, win);
      if (!Chain<W>(first.model, lanes.data(), m, ks, sink)) return false;
      for (int l = 0; l < m; ++l)
        if (!block[l]->done) next.push_back(block[l]);
    }
    pending.swap(next);
    from = to;
    tier += win;
  }
  return true;
}

template bool EvaluateSettled<1>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<2>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<4>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<8>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<16>(const PointSpec*, size_t, PointResult*);

}  // namespace bistable
