#include "dynamics/rosenstein.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <nanoflann.hpp>

#include "dynamics/spectrum.h"

namespace bistable {
namespace {

// Embedded vectors as a nanoflann dataset: point i, coordinate k = series[i + k·lag].
struct Embedding {
  const std::vector<double>& s;
  int lag, dim;
  size_t count;
  size_t kdtree_get_point_count() const { return count; }
  double kdtree_get_pt(size_t i, size_t k) const { return s[i + k * static_cast<size_t>(lag)]; }
  template <class Bbox>
  bool kdtree_get_bbox(Bbox&) const {
    return false;
  }
};

// Nearest neighbour of `self` outside the Theiler window |j − self| ≤ w and with j < limit.
class ExcludingNearest {
 public:
  ExcludingNearest(size_t self, size_t w, size_t limit) : self_(self), w_(w), limit_(limit) {}
  size_t size() const { return found_ ? 1 : 0; }
  bool full() const { return found_; }
  double worstDist() const { return found_ ? dist_ : std::numeric_limits<double>::max(); }
  bool addPoint(double dist, size_t index) {
    const size_t gap = index > self_ ? index - self_ : self_ - index;
    if (gap <= w_ || index >= limit_ || dist <= 0.0) return true;
    if (!found_ || dist < dist_) found_ = true, dist_ = dist, index_ = index;
    return true;
  }
  bool found() const { return found_; }
  size_t index() const { return index_; }

 private:
  size_t self_, w_, limit_;
  bool found_ = false;
  double dist_ = 0;
  size_t index_ = 0;
};

int AutocorrelationLag(const std::vector<double>& s) {
  const size_t n = s.size();
  const double mean = std::accumulate(s.begin(), s.end(), 0.0) / static_cast<double>(n);
  double c0 = 0;
  for (double v : s) c0 += (v - mean) * (v - mean);
  if (c0 <= 0) return 0;
  const double target = 1.0 - 1.0 / std::exp(1.0);
  for (size_t lag = 1; lag < n / 10; ++lag) {
    double c = 0;
    for (size_t i = 0; i + lag < n; ++i) c += (s[i] - mean) * (s[i + lag] - mean);
    if (c / c0 <= target) return static_cast<int>(lag);
  }
  return static_cast<int>(std::max<size_t>(1, n / 10));
}

}  // namespace

RosensteinResult RosensteinLle(const std::vector<double>& series, double dt, const RosensteinOptions& opt) {
  RosensteinResult r;
  const size_t n = series.size();
  if (n < 64 || opt.dim < 1 || !(dt > 0)) return r;
  r.dim = opt.dim;
  r.lag = opt.lag > 0 ? opt.lag : AutocorrelationLag(series);
  if (r.lag <= 0) return r;
  const size_t span = static_cast<size_t>(r.dim - 1) * r.lag;
  if (span + 32 >= n) return r;
  const size_t m = n - span;  // embedded points

  const double mean_freq = MeanFrequency(series, dt);  // cycles per unit time
  const double mean_period_samples = mean_freq > 0 ? 1.0 / (mean_freq * dt) : static_cast<double>(m) / 8;
  r.theiler = opt.theiler > 0 ? opt.theiler : static_cast<int>(std::ceil(mean_period_samples));
  int horizon = opt.horizon > 0 ? opt.horizon : static_cast<int>(std::ceil(6 * mean_period_samples));
  horizon = std::min<int>(horizon, static_cast<int>(m / 4));
  if (horizon < 4) return r;
  const size_t limit = m - static_cast<size_t>(horizon);

  Embedding data{series, r.lag, r.dim, limit};
  using StaticTree =
      nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Embedding>, Embedding, -1, size_t>;
  StaticTree tree(r.dim, data, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  tree.buildIndex();

  std::vector<double> sum(horizon + 1, 0.0);
  std::vector<long> cnt(horizon + 1, 0);
  std::vector<double> q(r.dim);
  for (size_t i = 0; i < limit; ++i) {
    for (int k = 0; k < r.dim; ++k) q[k] = series[i + static_cast<size_t>(k) * r.lag];
    ExcludingNearest nn(i, static_cast<size_t>(r.theiler), limit);
    tree.findNeighbors(nn, q.data(), nanoflann::SearchParams());
    if (!nn.found()) continue;
    const size_t j = nn.index();
    ++r.pairs;
    for (int s = 0; s <= horizon; ++s) {
      double d2 = 0;
      for (int k = 0; k < r.dim; ++k) {
        const double a =
            series[i + s + static_cast<size_t>(k) * r.lag] - series[j + s + static_cast<size_t>(k) * r.lag];
        d2 += a * a;
      }
      if (d2 > 0) sum[s] += 0.5 * std::log(d2), ++cnt[s];
    }
  }
  if (r.pairs < 16) return r;
  r.divergence.resize(horizon + 1);
  for (int s = 0; s <= horizon; ++s) r.divergence[s] = cnt[s] ? sum[s] / static_cast<double>(cnt[s]) : NAN;

  // Fit region.
  int b = opt.fit_begin, e = opt.fit_end;
  if (b < 0 || e <= b) {
    const double y0 = r.divergence[0];
    const double top = *std::max_element(r.divergence.begin(), r.divergence.end());
    const double lo = y0 + opt.fit_lo * (top - y0), hi = y0 + opt.fit_hi * (top - y0);
    b = -1, e = horizon;
    for (int s = 0; s <= horizon; ++s) {
      if (b < 0 && r.divergence[s] >= lo) b = s;
      if (r.divergence[s] >= hi) {
        e = s;
        break;
      }
    }
    b = std::max(b, 0);
    e = std::min(std::max(e, b + 3), horizon);
  }
  e = std::min(e, horizon);
  r.fit_begin = b;
  r.fit_end = e;
  // Least-squares slope of y(i) on t = i·dt over [b, e].
  double st = 0, sy = 0, stt = 0, sty = 0, k = 0;
  for (int s = b; s <= e; ++s) {
    const double t = s * dt, y = r.divergence[s];
    if (!std::isfinite(y)) continue;
    st += t, sy += y, stt += t * t, sty += t * y, k += 1;
  }
  const double den = k * stt - st * st;
  if (k < 3 || den <= 0) return r;
  r.lle = (k * sty - st * sy) / den;
  r.ok = true;
  return r;
}

}  // namespace bistable
