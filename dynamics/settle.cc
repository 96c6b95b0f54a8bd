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
  int chunks = 1;          // kernel windows (chunks) per label window
  int in_window = 0;       // chunks merged into acc so far
  RawLane acc;
  long acc_start = 0;      // step at which acc's window starts
  long cap_step = 0;       // the lane's last window end: unresolved there
  std::vector<double> logs, log_tau, log_end;  // growth blocks: Σ log|w|, length τ, end τ − t_keep
  struct Window {
    int period = 0;
    int well = 0;          // 0 intrawell, 1 interwell
    bool chaotic = false;  // the window's own λ > threshold
    double spread = 0;     // rms distance of its strobes from their mean in (y_m, y_m')
  };
  std::vector<Window> windows;
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
        Append(&c.acc, std::move(r), specs_[c.item].metrics.sample_every > 0 &&
                                         window_steps_ % specs_[c.item].metrics.sample_every == 0);
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
    std::array<PointResult, W> got;
    if (m > 0) ComputeBlockMetrics<W>(eval_raw.data(), eval_spec.data(), m, got.data());
    for (int i = 0; i < m; ++i) {
      const int l = eval_lane[i];
      Decide(*lanes_[l], std::move(got[i]), step);
      done[l] = lanes_[l]->done;
    }
  }

 private:
  void Finish(ChainLane& c, PointResult&& r, Motion motion, int period, double lambda, double sigma, double t,
              double confidence, long step) {
    r.motion = motion;
    r.period = period;
    r.lle = lambda;
    r.lle_sigma = sigma;
    r.settle_time = t;
    r.label_confidence = confidence;
    r.steps = step;
    r.rhs_evals = 4 * step;
    out_[c.item] = std::move(r);
    c.done = true;
  }

  void Decide(ChainLane& c, PointResult&& cur, long step) {
    const PointSpec& spec = specs_[c.item];
    const double t = static_cast<double>(step) * h_;
    const double since = t - spec.integration.t_keep;
    if (cur.termination != Termination::kOk) {
      Finish(c, std::move(cur), Motion::kUndefined, 0, cur.lle, std::numeric_limits<double>::quiet_NaN(), t, 0, step);
      return;
    }
    const double thr = spec.metrics.chaos_threshold;
    ChainLane::Window w;
    w.period = cur.period;
    w.well = (!IsBistable(spec.model) || cur.y_min > 0 || cur.y_max < 0) ? 0 : 1;
    w.chaotic = cur.lle > thr;
    w.spread = Spread(cur.section_y, cur.section_v);
    c.windows.push_back(w);
    const Motion well = w.well == 0 ? Motion::kIntrawell : Motion::kInterwell;
    double lambda = cur.lle, sigma = std::numeric_limits<double>::infinity();
    if (c.windows.size() >= 2) {
      LambdaSigma(c, 0.5 * since, &lambda, &sigma);
      const ChainLane::Window& p = c.windows[c.windows.size() - 2];
      const double conf = 0.5 * std::erfc(-std::fabs(lambda - thr) / (sigma * std::sqrt(2.0)));
      const bool confirmed = since >= spec.integration.settle_confirm;
      // A period n ≥ 2 must keep its strobe cloud: a decaying flip transient (a Floquet multiplier
      // near −1) alternates from strobe to strobe and passes the recurrence test while it shrinks.
      const double ratio = p.spread > 0 ? w.spread / p.spread : 0.0;
      const bool cloud_kept = w.period == 1 || (ratio >= 0.97 && ratio <= 1.03);
      if (w.period >= 1 && p.period == w.period && p.well == w.well && cloud_kept && lambda + 2 * sigma < 0) {
        Finish(c, std::move(cur), well, w.period, lambda, sigma, t, conf, step);
        return;
      }
      if (confirmed && w.period == 0 && p.period == 0 && w.chaotic && p.chaotic && lambda - 2 * sigma > thr) {
        Finish(c, std::move(cur), Motion::kChaotic, 0, lambda, sigma, t, conf, step);
        return;
      }
      if (confirmed && w.period == 0 && p.period == 0 && p.well == w.well &&
          std::fabs(lambda) <= spec.metrics.quasi_lle && lambda + 2 * sigma < thr && ratio >= 0.8 && ratio <= 1.25) {
        Finish(c, std::move(cur), Motion::kQuasiPeriodic, 0, lambda, sigma, t, conf, step);
        return;
      }
    }
    if (step >= c.cap_step) {
      const int period = cur.period;
      Finish(c, std::move(cur), Motion::kUnresolved, period, lambda, sigma, t, 0.0, step);
    }
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
    c->chunks = std::max(1, static_cast<int>(std::ceil(specs[i].integration.settle_min_strobes * period / in.settle_window - 1e-9)));
    const long lw = win * c->chunks;
    const long cap = StepsFor(in.settle_cap, h);
    c->cap_step = n_keep + std::max<long>(2, (cap + lw - 1) / lw) * lw;
    max_cap = std::max(max_cap, c->cap_step);
    pending.push_back(c.get());
    all[i] = std::move(c);
  }
  // Rounds: fresh lanes from step 0 to the first tier, then the lanes not yet settled, side by side,
  // from each tier to the next (t_keep + 4 windows · 2^k), until none is left.
  long from = 0, tier = n_keep + 4 * win;
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
    tier = n_keep + 2 * (tier - n_keep);
  }
  return true;
}

template bool EvaluateSettled<1>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<2>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<4>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<8>(const PointSpec*, size_t, PointResult*);
template bool EvaluateSettled<16>(const PointSpec*, size_t, PointResult*);

}  // namespace bistable
