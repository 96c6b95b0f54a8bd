#include "identify/invariants.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>

#include "dynamics/spectrum.h"

namespace bistable {

double ForcingFrequency(const std::vector<double>& input, double dt) {
  if (input.size() < 16 || !(dt > 0)) return NAN;
  const Spectrum s = AmplitudeSpectrum(input, dt);
  const std::vector<HdPeak> peaks = SpectralPeaks(s, 0.0, 1);
  if (peaks.empty()) return NAN;
  // Golden-section search for the maximum of the Hann-weighted projection within ±1 bin of the peak:
  // the bin's parabola leaves ~1 % of a bin, which over a record of N periods is a phase drift of
  // N/100 cycles in the stroboscopic section.
  auto amp = [&](double w) { return ToneAmplitude(input.data(), input.size(), dt, w); };
  double a = std::max(peaks[0].freq - s.d_omega, 0.5 * peaks[0].freq), b = peaks[0].freq + s.d_omega;
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double c = b - g * (b - a), d = a + g * (b - a), fc = amp(c), fd = amp(d);
  for (int it = 0; it < 60 && b - a > 1e-9 * peaks[0].freq; ++it) {
    if (fc > fd)
      b = d, d = c, fd = fc, c = b - g * (b - a), fc = amp(c);
    else
      a = c, c = d, fc = fd, d = a + g * (b - a), fd = amp(d);
  }
  return 0.25 * (a + b) / M_PI;  // midpoint, rad/s → Hz
}

void MainBodyMotion(const std::vector<double>& out, const PreparedRecord& r, const Setup& setup, std::vector<double>* y,
                    std::vector<double>* yd) {
  if (setup.output == OutputKind::kVelocity) {
    *yd = out;
    if (setup.input == InputKind::kBaseAcceleration && setup.frame == OutputFrame::kAbsolute)
      for (size_t i = 0; i < yd->size() && i < r.base_v.size(); ++i) (*yd)[i] -= r.base_v[i];
    *y = IntegrateFft(*yd, r.dt, 0.0);
    return;
  }
  *y = out;
  if (setup.input == InputKind::kBaseDisplacement && setup.frame == OutputFrame::kAbsolute)
    for (size_t i = 0; i < y->size() && i < r.input.size(); ++i) (*y)[i] -= r.input[i];
  *yd = SpectralDerivative(*y, r.dt, 1, r.f_cut > 0 ? r.f_cut : 0.45 / r.dt);
}

Eigen::MatrixXd StroboscopicSection(const std::vector<double>& y, const std::vector<double>& yd,
                                    const std::vector<double>& input, double dt, double f_hz) {
  const size_t n = std::min({y.size(), yd.size(), input.size()});
  if (n < 16 || !(f_hz > 0) || !std::isfinite(f_hz)) return Eigen::MatrixXd(0, 2);
  const double w = 2.0 * M_PI * f_hz;
  const double phi = std::arg(TonePhasor(input.data(), n, dt, w));
  const UniformSpline sy(0.0, dt, std::vector<double>(y.begin(), y.begin() + static_cast<long>(n)));
  const UniformSpline sv(0.0, dt, std::vector<double>(yd.begin(), yd.begin() + static_cast<long>(n)));
  const double t_end = static_cast<double>(n - 1) * dt;
  std::vector<double> rows;
  for (long k = static_cast<long>(std::ceil(phi / (2.0 * M_PI)));; ++k) {
    const double t = (2.0 * M_PI * static_cast<double>(k) - phi) / w;
    if (t > t_end) break;
    if (t < 0) continue;
    double q, dq, v, dv;
    sy.Eval(t, &q, &dq);
    sv.Eval(t, &v, &dv);
    rows.push_back(q), rows.push_back(v);
  }
  Eigen::MatrixXd out(static_cast<long>(rows.size() / 2), 2);
  for (long i = 0; i < out.rows(); ++i) out(i, 0) = rows[2 * i], out(i, 1) = rows[2 * i + 1];
  return out;
}

namespace {

constexpr long kMaxCloud = 2000;

Eigen::MatrixXd Thinned(const Eigen::MatrixXd& a) {
  if (a.rows() <= kMaxCloud) return a;
  Eigen::MatrixXd t(kMaxCloud, a.cols());
  for (long i = 0; i < kMaxCloud; ++i) t.row(i) = a.row(i * a.rows() / kMaxCloud);
  return t;
}

// Mean Euclidean distance between the rows of a and those of b (all pairs, a row with itself included).
double MeanDistance(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  double s = 0;
  for (long i = 0; i < a.rows(); ++i)
    for (long j = 0; j < b.rows(); ++j) s += (a.row(i) - b.row(j)).norm();
  return s / (static_cast<double>(a.rows()) * static_cast<double>(b.rows()));
}

bool Usable(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return a.rows() > 0 && b.rows() > 0 && a.cols() == b.cols() && a.allFinite() && b.allFinite();
}

}  // namespace

double EnergyDistanceSquared(const Eigen::MatrixXd& a_in, const Eigen::MatrixXd& b_in) {
  if (!Usable(a_in, b_in)) return NAN;
  const Eigen::MatrixXd a = Thinned(a_in), b = Thinned(b_in);
  return std::max(0.0, 2.0 * MeanDistance(a, b) - MeanDistance(a, a) - MeanDistance(b, b));
}

double EnergyCoefficient(const Eigen::MatrixXd& a_in, const Eigen::MatrixXd& b_in) {
  if (!Usable(a_in, b_in)) return NAN;
  Eigen::MatrixXd a = Thinned(a_in), b = Thinned(b_in);
  for (long j = 0; j < a.cols(); ++j) {
    const double va = (a.col(j).array() - a.col(j).mean()).square().mean();
    const double vb = (b.col(j).array() - b.col(j).mean()).square().mean();
    const double s = std::sqrt(0.5 * (va + vb));
    if (s > 0) a.col(j) /= s, b.col(j) /= s;
  }
  const double cross = MeanDistance(a, b);
  if (!(cross > 0)) return 0.0;  // every point of both clouds the same
  return std::clamp((2.0 * cross - MeanDistance(a, a) - MeanDistance(b, b)) / (2.0 * cross), 0.0, 1.0);
}

int CountSwitches(const std::vector<double>& y, double barrier, double h) {
  int side = 0, n = 0;
  for (double v : y) {
    const int s = v > barrier + h ? 1 : v < barrier - h ? -1 : 0;
    if (s == 0) continue;  // inside the hysteresis band (or NaN)
    if (side != 0 && s != side) ++n;
    side = s;
  }
  return n;
}

PeriodMotion PeriodsOf(const std::vector<double>& y, double dt, double f_hz) {
  PeriodMotion p;
  if (!(dt > 0) || !(f_hz > 0) || !std::isfinite(f_hz)) return p;
  const double samples_per_period = 1.0 / (f_hz * dt);
  if (!(samples_per_period >= 2) || !(samples_per_period <= static_cast<double>(y.size()))) return p;
  for (size_t k = 0;; ++k) {
    const size_t a = static_cast<size_t>(std::ceil(static_cast<double>(k) * samples_per_period));
    const size_t b = static_cast<size_t>(std::ceil(static_cast<double>(k + 1) * samples_per_period));
    if (b > y.size()) break;
    double s = 0, s2 = 0;
    for (size_t i = a; i < b; ++i) s += y[i];
    const double mean = s / static_cast<double>(b - a);
    for (size_t i = a; i < b; ++i) s2 += (y[i] - mean) * (y[i] - mean);
    p.mean.push_back(mean);
    p.spread.push_back(std::sqrt(s2 / static_cast<double>(b - a)));
  }
  return p;
}

WellSplit SplitWells(const PeriodMotion& p) {
  WellSplit w;
  const size_t n = p.mean.size();
  if (n < 4) return w;
  std::vector<double> x = p.mean;
  for (double v : x)
    if (!std::isfinite(v)) return w;
  std::sort(x.begin(), x.end());
  std::vector<double> prefix(n + 1, 0.0), prefix2(n + 1, 0.0);
  for (size_t i = 0; i < n; ++i) prefix[i + 1] = prefix[i] + x[i], prefix2[i + 1] = prefix2[i] + x[i] * x[i];
  auto ss = [&](size_t a, size_t b) {  // within sum of squares of x[a, b)
    const double s = prefix[b] - prefix[a], c = static_cast<double>(b - a);
    return prefix2[b] - prefix2[a] - s * s / c;
  };
  size_t best = 1;
  double best_ss = INFINITY;
  for (size_t k = 1; k < n; ++k) {
    const double v = ss(0, k) + ss(k, n);
    if (v < best_ss) best_ss = v, best = k;
  }
  w.centre_left = (prefix[best] - prefix[0]) / static_cast<double>(best);
  w.centre_right = (prefix[n] - prefix[best]) / static_cast<double>(n - best);
  w.split = 0.5 * (w.centre_left + w.centre_right);
  w.band = 0.25 * (w.centre_right - w.centre_left);
  std::vector<double> spread = p.spread;
  std::nth_element(spread.begin(), spread.begin() + static_cast<long>(spread.size() / 2), spread.end());
  w.two_wells = w.centre_right - w.centre_left > spread[spread.size() / 2];
  return w;
}

WellCount CountWells(const std::vector<double>& means, const WellSplit& s) {
  WellCount c;
  if (!s.two_wells) return c;
  int well = 0;
  for (double m : means) {
    const int now = m > s.split + s.band ? 1 : m < s.split - s.band ? -1 : 0;
    if (now == 0) continue;  // between the wells (or NaN): the last well
    if (well != 0 && now != well) ++c.switches;
    well = now;
    if (now > 0)
      ++c.right, c.sum_right += m;
    else
      ++c.left, c.sum_left += m;
  }
  return c;
}

WellSwitching WellsOf(const std::vector<double>& y_meas, const std::vector<double>& y_sim, double dt, double f_hz) {
  WellSwitching w;
  const PeriodMotion pm = PeriodsOf(y_meas, dt, f_hz), ps = PeriodsOf(y_sim, dt, f_hz);
  w.seconds = static_cast<double>(pm.mean.size()) / f_hz;
  for (const PeriodMotion* p : {&pm, &ps})
    for (double v : p->mean) w.finite = w.finite && std::isfinite(v);
  w.measured_split = SplitWells(pm);
  w.simulated_split = SplitWells(ps);
  w.measured = CountWells(pm.mean, w.measured_split);
  w.simulated = CountWells(ps.mean, w.simulated_split);
  return w;
}

double HistogramHellinger(const std::vector<double>& meas, const std::vector<double>& sim, int bins) {
  if (meas.empty() || sim.empty() || bins < 1) return NAN;
  const auto [mn, mx] = std::minmax_element(meas.begin(), meas.end());
  if (!std::isfinite(*mn) || !std::isfinite(*mx)) return NAN;
  const double span = std::max(*mx - *mn, 1e-300);
  const double lo = *mn - 0.05 * span, width = 1.1 * span / bins;
  auto histogram = [&](const std::vector<double>& x, std::vector<double>* p) {
    p->assign(static_cast<size_t>(bins) + 2, 0.0);
    for (double v : x) {
      if (!std::isfinite(v)) return false;
      const double k = std::floor((v - lo) / width);
      (*p)[k < 0       ? 0
           : k >= bins ? static_cast<size_t>(bins) + 1
                       : static_cast<size_t>(k) + 1] += 1.0 / static_cast<double>(x.size());
    }
    return true;
  };
  std::vector<double> p, q;
  if (!histogram(meas, &p) || !histogram(sim, &q)) return NAN;
  double bc = 0;  // Bhattacharyya coefficient
  for (size_t k = 0; k < p.size(); ++k) bc += std::sqrt(p[k] * q[k]);
  return std::sqrt(std::max(0.0, 1.0 - bc));
}

ChaosCheck CheckChaos(const std::vector<PreparedRecord>& recs, const Setup& setup, Objective objective) {
  ChaosCheck c;
  for (const PreparedRecord& r : recs) {
    const double f = ForcingFrequency(r.input, r.dt);
    double in_bb = NAN, out_bb = NAN;
    if (std::isfinite(f)) {
      std::vector<double> y, yd;
      MainBodyMotion(r.meas, r, setup, &y, &yd);
      in_bb = HarmonicDiffusionIndex(AmplitudeSpectrum(r.input, r.dt), 2.0 * M_PI * f);
      out_bb = HarmonicDiffusionIndex(AmplitudeSpectrum(yd, r.dt), 2.0 * M_PI * f);
    }
    const bool marked = objective != Objective::kTime || r.horizon_s > 0 || r.chaotic ||
                        (in_bb <= kPeriodicInput && out_bb >= kBroadbandChaotic);
    c.forcing_hz.push_back(f);
    c.input_broadband.push_back(in_bb);
    c.output_broadband.push_back(out_bb);
    c.record_chaotic.push_back(marked);
    c.chaotic = c.chaotic || marked;
  }
  char buf[400];
  std::snprintf(
      buf, sizeof buf,
      "%s a record is chaotic when its input is periodic (broadband share <= %.2g) and its output velocity is not "
      "(broadband share >= %.2g: power farther than 3 bins from every harmonic of the forcing), or when --objective "
      "auto "
      "fitted it on short horizons (its long simulation is chaos: objective_choice)",
      objective == Objective::kFft        ? "spectral objective: every record;"
      : objective == Objective::kShooting ? "shooting objective: every record;"
                                          : "time objective:",
      kPeriodicInput, kBroadbandChaotic);
  c.rule = buf;
  return c;
}

Invariants ComputeInvariants(const IdentModel& m, const std::vector<double>& th,
                             const std::vector<PreparedRecord>& recs, const Setup& setup, const ChaosCheck& check,
                             const Errors& errors) {
  Invariants inv;
  double h_sum = 0, floor_sum = 0, hist_sum = 0, fft_sum = 0, seconds = 0;
  int h_n = 0, floor_n = 0, hist_n = 0, fft_n = 0;
  WellCount wells_meas, wells_sim;  // summed over the records
  double out_hist[kOutputSlots] = {0, 0, 0};
  int out_hist_n[kOutputSlots] = {0, 0, 0};
  for (size_t i = 0; i < recs.size() && i < check.record_chaotic.size(); ++i) {
    if (!check.record_chaotic[i]) continue;
    const PreparedRecord& r = recs[i];
    std::vector<double> ym, vm, ys, vs;
    SimOutputs so;
    if (!SimulateOutputs(m, th, {}, r, setup, 0, 0, false, &so)) return Invariants{};  // diverged: nothing reproduced
    const std::vector<double>& out = so.out[0];
    for (int k = 0; k < kOutputSlots; ++k) {
      const OutputSlot slot = static_cast<OutputSlot>(k);
      if (!r.Has(slot) || so.out[k].size() != r.Measured(slot).size()) continue;
      const double hk = HistogramHellinger(r.Measured(slot), so.out[k]);
      if (std::isfinite(hk)) out_hist[k] += hk, ++out_hist_n[k];
    }
    MainBodyMotion(r.meas, r, setup, &ym, &vm);
    MainBodyMotion(out, r, setup, &ys, &vs);
    if (i < errors.record_fft.size() && std::isfinite(errors.record_fft[i])) fft_sum += errors.record_fft[i], ++fft_n;
    const double f = check.forcing_hz[i];
    if (std::isfinite(f)) {
      const Eigen::MatrixXd a = StroboscopicSection(ym, vm, r.input, r.dt, f),
                            b = StroboscopicSection(ys, vs, r.input, r.dt, f);
      const double h = EnergyCoefficient(a, b),
                   floor = EnergyCoefficient(a.topRows(a.rows() / 2), a.bottomRows(a.rows() - a.rows() / 2));
      inv.section_points += static_cast<int>(a.rows());
      if (std::isfinite(h)) h_sum += h, ++h_n;
      if (std::isfinite(floor)) floor_sum += floor, ++floor_n;
    }
    if (const WellSwitching w = std::isfinite(f) ? WellsOf(ym, ys, r.dt, f) : WellSwitching{};
        w.finite && w.seconds > 0) {
      // (a record with a non-finite period mean adds neither switches nor seconds)
      wells_meas.Add(w.measured);
      wells_sim.Add(w.simulated);
      seconds += w.seconds;
    }
    const double hh = HistogramHellinger(vm, vs);
    if (std::isfinite(hh)) hist_sum += hh, ++hist_n;
  }
  if (h_n) inv.poincare = h_sum / h_n;
  if (floor_n) inv.poincare_floor = floor_sum / floor_n;
  if (hist_n) inv.velocity_hellinger = hist_sum / hist_n;
  if (fft_n) inv.spectral_error = fft_sum / fft_n;
  for (int k = 0; k < kOutputSlots; ++k) {
    if (!out_hist_n[k]) continue;
    Invariants::Output o;
    o.name = OutputName(setup, static_cast<OutputSlot>(k));
    o.hellinger = out_hist[k] / out_hist_n[k];
    for (const OutputErrors& e : errors.outputs)
      if (e.name == o.name) o.spectral_error = e.fft;
    inv.by_output.push_back(o);
  }
  if (seconds > 0) {
    inv.switching_rate = wells_sim.switches / seconds;
    inv.switching_rate_measured = wells_meas.switches / seconds;
    if (wells_meas.switches > 0)
      inv.switching_error = std::abs(inv.switching_rate - inv.switching_rate_measured) / inv.switching_rate_measured;
    auto occupancy = [](const WellCount& c, double* fraction, double* centres) {
      if (c.left + c.right > 0) *fraction = static_cast<double>(c.right) / (c.left + c.right);
      if (c.left > 0) centres[0] = c.sum_left / c.left;
      if (c.right > 0) centres[1] = c.sum_right / c.right;
    };
    occupancy(wells_sim, &inv.right_well_fraction, inv.well_centres);
    occupancy(wells_meas, &inv.right_well_fraction_measured, inv.well_centres_measured);
  }
  return inv;
}

}  // namespace bistable
