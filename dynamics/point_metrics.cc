#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "dynamics/point.h"
#include "dynamics/rosenstein.h"
#include "dynamics/spectrum.h"

namespace bistable {
namespace {

// Power fraction at the sub-harmonics kΩ/n that a period-n (n > 1) claim must show.
constexpr double kMinSubharmonicFraction = 1e-4;

// Smallest n ≤ max_period such that stroboscopic samples repeat after n periods to within tol
// (in y_m and y_m'), checked over the later half of the samples with at least 4 comparisons.
// A period n > 1 must also show sub-harmonic power kΩ/n in the spectrum, and that power must not
// be dying out (its strongest line keeps ≥ kMinSubharmonicPersistence of its first-half amplitude in
// the second half): a slowly decaying transient whose frequency happens to sit near kΩ/n would
// otherwise pass as period-n motion.
constexpr double kMinSubharmonicPersistence = 0.5;

bool SubharmonicPersists(const std::vector<double>& ys, double dts, double omega, int n) {
  double best = 0, w_best = 0;
  for (int k = 1; k < n; ++k) {
    const double a = ToneAmplitude(ys.data(), ys.size(), dts, k * omega / n);
    if (a > best) best = a, w_best = k * omega / n;
  }
  const size_t half = ys.size() / 2;
  const double first = ToneAmplitude(ys.data(), half, dts, w_best);
  const double second = ToneAmplitude(ys.data() + half, ys.size() - half, dts, w_best);
  return second >= kMinSubharmonicPersistence * first;
}

int DetectPeriod(const std::vector<double>& y, const std::vector<double>& v, int max_period, double tol,
                 const Spectrum& sp, const std::vector<double>& ys, double dts, double omega) {
  const int n = StrobeRecurrence(y, v, max_period, tol);
  if (n <= 1) return n;
  const bool genuine =
      SubharmonicFraction(sp, omega, n) >= kMinSubharmonicFraction && SubharmonicPersists(ys, dts, omega, n);
  return genuine ? n : 0;
}

}  // namespace

int StrobeRecurrence(const std::vector<double>& y, const std::vector<double>& v, int max_period, double tol) {
  const int m = static_cast<int>(y.size());
  for (int n = 1; n <= max_period; ++n) {
    const int pairs = std::max(4, (m - n) / 2);
    if (m - n < pairs) break;
    bool repeats = true;
    for (int k = m - n - pairs; k < m - n && repeats; ++k)
      repeats = std::fabs(y[k] - y[k + n]) <= tol && std::fabs(v[k] - v[k + n]) <= tol;
    if (repeats) return n;
  }
  return 0;
}

double SampleStep(const PointSpec& spec) { return spec.integration.dt * spec.metrics.sample_every; }

namespace {

// Every metric of one lane given its response spectrum (unused when the lane diverged).
PointResult MetricsWithSpectrum(RawLane raw, const PointSpec& spec, const Spectrum& sp) {
  PointResult r;
  r.steps = raw.steps;
  r.rhs_evals = raw.rhs_evals;
  r.final_state = raw.final_state;
  r.turning_points = std::move(raw.turning_points);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (raw.diverged) {
    PointResult d = DivergedResult(r.final_state);
    d.steps = r.steps;
    d.rhs_evals = r.rhs_evals;
    d.turning_points = std::move(r.turning_points);
    return d;
  }
  const IntegrationSettings& in = spec.integration;
  const MetricSettings& ms = spec.metrics;
  const double window = in.t_end - in.t_keep;

  r.frf_db = 20.0 * std::log10(raw.vabs_max / (spec.alpha * spec.omega));
  r.lle = raw.log_growth / window;
  r.y_min = raw.y_min;
  r.y_max = raw.y_max;
  r.strobe_samples = static_cast<int>(raw.strobe_y.size());
  if (r.lle > ms.chaos_threshold) {
    r.motion = Motion::kChaotic;
  } else if (!IsBistable(spec.model) || raw.y_min > 0 || raw.y_max < 0) {
    r.motion = Motion::kIntrawell;  // a linear oscillator has a single well
  } else {
    r.motion = Motion::kInterwell;
  }

  // Spectrum of y_m over the window: harmonic diffusion.
  const double dts = SampleStep(spec);
  r.hd_peaks = SpectralPeaks(sp, ms.hd_level, ms.hd_top_k);
  r.hd_index = HarmonicDiffusionIndex(sp, spec.omega);
  r.period = DetectPeriod(raw.strobe_y, raw.strobe_v, ms.max_period, ms.period_tol, sp, raw.y_samples, dts, spec.omega);
  r.strobe_y = r.strobe_v = nan;
  if (const size_t m = raw.strobe_y.size(); m > 0) {
    size_t best = m - 1;
    for (size_t k = m - std::min<size_t>(m, std::max(r.period, 1)); k < m; ++k)
      if (raw.strobe_y[k] < raw.strobe_y[best] ||
          (raw.strobe_y[k] == raw.strobe_y[best] && raw.strobe_v[k] < raw.strobe_v[best]))
        best = k;
    r.strobe_y = raw.strobe_y[best];
    r.strobe_v = raw.strobe_v[best];
  }
  r.section_k0 = raw.strobe_k0;
  r.section_y = std::move(raw.strobe_y);
  r.section_v = std::move(raw.strobe_v);
  r.section_yr = std::move(raw.strobe_yr);
  r.section_vr = std::move(raw.strobe_vr);

  r.lle_rosenstein = nan;
  if (ms.rosenstein) {
    const RosensteinResult ro = RosensteinLle(raw.y_samples, dts);
    if (ro.ok) r.lle_rosenstein = ro.lle;
  }

  // Energy (model.md §3): gross-input ratios and the exact balance check.
  r.w_in = raw.q_in;
  r.w_net = raw.q_p;
  r.w_m = raw.q_m;
  r.w_r = raw.q_r;
  r.delta_e = raw.e_end - raw.e_start;
  const double denom = std::max(raw.q_in, 1e-300);
  r.edr_b = 100.0 * raw.q_m / denom;
  r.edr_r = 100.0 * raw.q_r / denom;
  r.edr_t = 100.0 * (raw.q_m + raw.q_r) / denom;
  r.energy_balance_residual = std::fabs(raw.q_p - raw.q_m - raw.q_r - r.delta_e) / denom;
  if (ms.keep_samples) r.samples = std::move(raw.rows);
  return r;
}

}  // namespace

PointResult ComputePointMetrics(RawLane raw, const PointSpec& spec) {
  PointResult r;
  ComputeBlockMetrics<1>(&raw, &spec, 1, &r);
  return r;
}

template <int W>
void ComputeBlockMetrics(RawLane* raw, const PointSpec* specs, int n, PointResult* out) {
  std::array<const std::vector<double>*, W> xs{};
  std::array<double, W> dts{};
  std::array<int, W> where{};
  int m = 0;
  for (int l = 0; l < n; ++l)
    if (!raw[l].diverged) xs[m] = &raw[l].y_samples, dts[m] = SampleStep(specs[l]), where[m++] = l;
  std::array<Spectrum, W> got;
  AmplitudeSpectra<W>(xs.data(), dts.data(), m, got.data());
  std::array<const Spectrum*, W> sp;
  const Spectrum none;
  for (int l = 0; l < n; ++l) sp[l] = &none;
  for (int i = 0; i < m; ++i) sp[where[i]] = &got[i];
  for (int l = 0; l < n; ++l) out[l] = MetricsWithSpectrum(std::move(raw[l]), specs[l], *sp[l]);
}

template void ComputeBlockMetrics<1>(RawLane*, const PointSpec*, int, PointResult*);
template void ComputeBlockMetrics<2>(RawLane*, const PointSpec*, int, PointResult*);
template void ComputeBlockMetrics<4>(RawLane*, const PointSpec*, int, PointResult*);
template void ComputeBlockMetrics<8>(RawLane*, const PointSpec*, int, PointResult*);
template void ComputeBlockMetrics<16>(RawLane*, const PointSpec*, int, PointResult*);

}  // namespace bistable
