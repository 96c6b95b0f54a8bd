#include "identify/diagnostics.h"
#include "identify/predictability.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <map>
#include <set>

#include <boost/math/special_functions/gamma.hpp>

#include "dynamics/spectrum.h"

namespace bistable {

std::string FormatSignificant(double v, int digits) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, v);
  return b;
}

std::string WhitenessVerdict(const Whiteness& w) {
  const std::string alpha = FormatSignificant(w.alpha, 2);
  if (w.dof == 0)
    return w.diverged ? "residual not tested for whiteness: the final model diverges before any record's residual "
                        "could be tested"
                      : "residual not tested for whiteness: no record's band-limited residual holds 64 finite samples "
                        "for the Ljung\u2013Box test";
  const std::string test = "Ljung\u2013Box test of its autocorrelation on " + std::to_string(w.dof) +
                           " lags, p = " + FormatSignificant(w.p_value, 2);
  if (w.p_value >= w.alpha)
    return "residual indistinguishable from white noise: " + test +
           " (p: the chance that white noise correlates this much; p < " + alpha + " would say it is not white)";
  // p alone calls it structured; too little of it is predictable to count (diagnostics.h: "Size").
  const double bound = kPredictableShare + (std::isfinite(w.twin_predictable_share) ? w.twin_predictable_share : 0.0);
  const std::string share = std::isfinite(w.flatness) ? "only " + FormatSignificant(100 * (1 - w.flatness), 2) +
                                                            " % of it is predictable from its past"
                                                      : "its predictable share could not be measured";
  return "residual counted as white: " + test + " < " + alpha + " finds structure white noise would rarely show, but " +
         share + " (not white needs p < " + alpha + " and a predictable share >= " + FormatSignificant(100 * bound, 2) +
         " %)";
}

namespace {

std::string Num(double v, int digits = 3) { return FormatSignificant(v, digits); }

// The residual low-passed to [0, band_hz] by an FFT brick wall and resampled every d-th sample,
// d = ⌊1/(2 band dt)⌋: white noise stays white (the kept bins of a white series are independent).
std::vector<double> BandLimited(const std::vector<double>& e, double dt, double band_hz) {
  const size_t d = band_hz > 0 ? static_cast<size_t>(std::max(1.0, std::floor(0.5 / (band_hz * dt)))) : 1;
  const size_t m = FastFftLength(std::max<size_t>(1, e.size() / d)), len = m * d;
  std::vector<double> x(e.begin(), e.begin() + static_cast<long>(len));
  double mean = 0;
  for (double v : x) mean += v;
  mean /= static_cast<double>(len);
  for (double& v : x) v -= mean;
  if (d == 1) return x;
  std::vector<std::complex<double>> X, Y(m, 0.0);
  RealFftFull(x, &X);
  for (size_t k = 0; 2 * k < m; ++k) Y[k] = X[k] / static_cast<double>(d);
  for (size_t k = 1; 2 * k < m; ++k) Y[m - k] = X[len - k] / static_cast<double>(d);
  std::vector<double> y;
  InverseFftReal(Y, &y);
  return y;
}

// Ljung–Box Q of a zero-mean series over lags 1..h.
double LjungBox(const std::vector<double>& y, int h) {
  const double n = static_cast<double>(y.size());
  double c0 = 0;
  for (double v : y) c0 += v * v;
  if (!(c0 > 0)) return 0.0;
  double q = 0;
  for (int k = 1; k <= h; ++k) {
    double c = 0;
    for (size_t i = static_cast<size_t>(k); i < y.size(); ++i) c += y[i] * y[i - k];
    const double rho = c / c0;
    q += rho * rho / (n - k);
  }
  return n * (n + 2) * q;
}

// Spectral flatness of a series: geometric over arithmetic mean of its Welch periodogram (Hann
// segments of up to 256 samples and at least 15 of them, half overlapping), DC and Nyquist bins left
// out. 1 − flatness is the share of the variance a linear predictor could take from the series' past
// (Kolmogorov–Szegő: the one-step prediction error variance is the geometric mean of the spectrum).
double Flatness(const std::vector<double>& y) {
  const size_t L = std::min<size_t>(256, FastFftLength(std::max<size_t>(8, y.size() / 8)));  // ≥ 15 segments
  if (y.size() < L || L < 8) return NAN;
  std::vector<double> p(L / 2 + 1, 0.0), seg(L);
  int count = 0;
  for (size_t s = 0; s + L <= y.size(); s += L / 2, ++count) {
    for (size_t i = 0; i < L; ++i)
      seg[i] = y[s + i] * (0.5 - 0.5 * std::cos(2.0 * M_PI * static_cast<double>(i) / static_cast<double>(L)));
    std::vector<std::complex<double>> X;
    RealFftHalf(seg, &X);
    for (size_t k = 0; k < p.size() && k < X.size(); ++k) p[k] += std::norm(X[k]);
  }
  double lg = 0, ar = 0;
  int bins = 0;
  for (size_t k = 1; k + 1 < p.size(); ++k, ++bins) {
    if (!(p[k] > 0)) return 0.0;
    lg += std::log(p[k] / count), ar += p[k] / count;
  }
  return bins ? std::exp(lg / bins) / (ar / bins) : NAN;
}

// The term of a parameter name ("main.viscous.c0" → main.viscous), or nullptr (the mass, offsets).
const TermDef* TermOfParam(const IdentModel& m, const std::string& name) {
  for (const TermDef* t : m.terms)
    if (name.size() > t->id.size() && name.compare(0, t->id.size(), t->id) == 0 && name[t->id.size()] == '.') return t;
  return nullptr;
}

bool Dissipative(const TermDef* t) { return t && t->params[0].sign == Sign::kNonNegative; }

// |F| of a term with its own parameters at (q, v).
double TermForce(const TermDef& t, const double* th, double q, double v, const FrictionConstants& fc) {
  double phi[2] = {0, 0};
  TermBasis(t, q, v, fc, phi);
  double f = 0;
  for (size_t j = 0; j < t.params.size(); ++j) f += th[j] * phi[j];
  return std::abs(f);
}

// How a term's force grows with the amplitude at (q, v): total power (q and v doubled) and the power
// of the displacement alone (q doubled).
std::pair<double, double> AmplitudePowers(const TermDef& t, const double* th, double q, double v,
                                          const FrictionConstants& fc) {
  const double f = TermForce(t, th, q, v, fc);
  if (!(f > 0)) return {NAN, NAN};
  return {std::log2(TermForce(t, th, 2 * q, 2 * v, fc) / f), std::log2(TermForce(t, th, 2 * q, v, fc) / f)};
}

}  // namespace

Whiteness WhitenessTest(const std::vector<std::vector<double>>& residuals, const std::vector<double>& dt,
                        const std::vector<double>& band_hz, double alpha) {
  Whiteness w;
  w.alpha = alpha;
  double q = 0, flat = 0;
  int flat_n = 0;
  struct Line {
    double hz, amp;
  };
  std::vector<Line> lines;
  for (size_t i = 0; i < residuals.size(); ++i) {
    const std::vector<double>& e = residuals[i];
    if (e.size() < 64 || !std::all_of(e.begin(), e.end(), [](double v) { return std::isfinite(v); })) continue;
    const double band = band_hz[i] > 0 && band_hz[i] < 0.5 / dt[i] ? band_hz[i] : 0.0;
    const std::vector<double> y = BandLimited(e, dt[i], band);
    const int h = std::min<int>(20, static_cast<int>(y.size() / 5));
    if (h < 1) continue;
    q += LjungBox(y, h);
    w.dof += h;
    w.n_eff += static_cast<double>(y.size());
    const double f = Flatness(y);
    if (std::isfinite(f)) flat += f, ++flat_n;
    const Spectrum s = AmplitudeSpectrum(e, dt[i]);
    for (const HdPeak& p : SpectralPeaks(s, 0.05, 12)) {
      const double hz = p.freq / (2.0 * M_PI);
      if (band <= 0 || hz <= band) lines.push_back({hz, p.amp});
    }
  }
  if (w.dof == 0) return w;  // nothing testable: reported as white with no statistic
  w.statistic = q;
  w.p_value = boost::math::gamma_q(0.5 * w.dof, 0.5 * q);
  if (flat_n) w.flatness = flat / flat_n;
  w.white = w.p_value >= alpha || !(1.0 - w.flatness >= kPredictableShare);
  std::sort(lines.begin(), lines.end(), [](const Line& a, const Line& b) { return a.amp > b.amp; });
  for (const Line& l : lines) {
    if (w.dominant_hz.size() >= 3) break;
    bool near = false;
    for (double f : w.dominant_hz) near = near || std::abs(f - l.hz) < 0.02 * std::max(f, 1e-9);
    if (!near) w.dominant_hz.push_back(l.hz);
  }
  return w;
}

std::vector<ParamCorrelation> StrongCorrelations(const std::vector<std::string>& names, const Eigen::MatrixXd& cov,
                                                 double threshold) {
  std::vector<ParamCorrelation> out;
  const long p = std::min<long>(static_cast<long>(names.size()), cov.rows());
  if (cov.cols() != cov.rows()) return out;
  for (long i = 0; i < p; ++i)
    for (long j = i + 1; j < p; ++j) {
      const double den = std::sqrt(cov(i, i) * cov(j, j));
      if (!(den > 0)) continue;
      const double rho = cov(i, j) / den;
      if (std::abs(rho) > threshold) out.push_back({names[i], names[j], rho});
    }
  std::sort(out.begin(), out.end(),
            [](const ParamCorrelation& a, const ParamCorrelation& b) { return std::abs(a.rho) > std::abs(b.rho); });
  return out;
}

std::vector<ParamDrift> DriftOf(const IdentModel& before, const FitResult& fit_before, const IdentModel& after,
                                const FitResult& fit_after) {
  std::vector<ParamDrift> out;
  const auto nb = before.ParamNames(), na = after.ParamNames();
  for (size_t i = 0; i < nb.size() && i < fit_before.theta.size(); ++i) {
    const auto it = std::find(na.begin(), na.end(), nb[i]);
    if (it == na.end() || static_cast<size_t>(it - na.begin()) >= fit_after.theta.size()) continue;
    ParamDrift d;
    d.name = nb[i];
    d.before = fit_before.theta[i];
    d.after = fit_after.theta[static_cast<size_t>(it - na.begin())];
    const double delta = d.after - d.before;
    if (d.before != 0) d.relative = delta / std::abs(d.before);
    if (i < fit_before.sigma.size() && fit_before.sigma[i] > 0) d.in_sigma = delta / fit_before.sigma[i];
    out.push_back(d);
  }
  return out;
}

namespace {

// The final model's residual of one output per record: the simulation error, or for chaotic records
// the short-horizon one (restarted from the measured state every `horizon_s`). Records without that
// output are left out.
Whiteness FinalWhiteness(const FitSnapshot& f, const std::vector<PreparedRecord>& recs, const Setup& setup,
                         const ChaosCheck& chaos, double horizon_s, bool reestimated,
                         OutputSlot slot) {  // horizon_s by value: named in the report
  std::vector<std::vector<double>> res;
  std::vector<double> dts, bands;
  bool any_short = false, any_full = false;
  std::string diverged;
  for (size_t i = 0; i < recs.size(); ++i) {
    const PreparedRecord& r = recs[i];
    if (!r.Has(slot)) continue;
    // A record fitted on its own short horizons (--objective auto) is tested on those residuals: the ones the
    // fit and the trace saw.
    const bool own = r.horizon_s > 0 && !reestimated;
    const bool shortened = own || (i < chaos.record_chaotic.size() && chaos.record_chaotic[i]);
    const double h = own ? r.horizon_s : horizon_s;
    const int restart = shortened ? ShootingSegment(h, r.dt) : 0;
    SimOutputs so;
    if (shortened && reestimated)
      SimulateShooting(f.model, f.fit.theta, r, setup, h, &so);
    else
      SimulateOutputs(f.model, f.fit.theta, {}, r, setup, 0, restart, false, &so);
    const std::vector<double>& out = so.out[static_cast<int>(slot)];
    const std::vector<double>& meas = r.Measured(slot);
    std::vector<double> e;
    for (size_t j = 0; j < r.n() && j < out.size() && std::isfinite(out[j]); ++j) e.push_back(out[j] - meas[j]);
    if (e.size() < r.n())
      diverged +=
          (diverged.empty() ? "" : ", ") + r.name + " at t = " + Num(static_cast<double>(e.size()) * r.dt) + " s";
    res.push_back(std::move(e));
    dts.push_back(r.dt);
    bands.push_back(r.f_cut);
    any_short = any_short || shortened;
    any_full = any_full || !shortened;
    if (own) horizon_s = h;  // the report names the records' horizon
  }
  Whiteness w = WhitenessTest(res, dts, bands);
  w.residual = any_full ? "simulation error (sim - meas)" : "";
  if (any_short)
    w.residual += std::string(any_full ? "; " : "") + "short-horizon simulation error of the chaotic records (" +
                  (reestimated ? "segments of " + Num(horizon_s) + " s from re-estimated states"
                               : "state reset to the measured one every " + Num(horizon_s) + " s") +
                  ")";
  if (!diverged.empty()) {
    w.diverged = true;
    w.residual += "; the simulation diverged (" + diverged + "), tested up to there";
  }
  return w;
}

// Which records would separate two dissipative terms that these records cannot (diagnostics.h).
std::string PairHint(const TermDef& a, const double* tha, const TermDef& b, const double* thb,
                     const std::vector<PreparedRecord>& recs, const FrictionConstants& fc) {
  double q = 0, v = 0, fmin = INFINITY, fmax = 0;
  for (const PreparedRecord& r : recs) {
    q = std::max(q, r.p_range), v = std::max(v, r.v_range);
    const double f = ForcingFrequency(r.meas, r.dt);
    if (std::isfinite(f)) fmin = std::min(fmin, f), fmax = std::max(fmax, f);
  }
  const auto [pa, qa] = AmplitudePowers(a, tha, 0.5 * q, 0.5 * v, fc);
  const auto [pb, qb] = AmplitudePowers(b, thb, 0.5 * q, 0.5 * v, fc);
  const std::string here = "max |y| " + Num(q) + " m, max |y'| " + Num(v) + " m/s";
  if (!std::isfinite(pa) || !std::isfinite(pb))
    return "one of them is zero here; a record at another amplitude would show it";
  if (std::abs(pa - pb) >= 0.5) {
    const TermDef& hi = pa > pb ? a : b;
    const TermDef& lo = pa > pb ? b : a;
    return "their forces grow as amplitude^" + Num(std::max(pa, pb), 2) + " (" + hi.id + ") and amplitude^" +
           Num(std::min(pa, pb), 2) + " (" + lo.id +
           "): records at other amplitudes separate them — one at about twice the motion here (" + here + ") shows " +
           hi.id + ", one at about half shows " + lo.id;
  }
  if (std::abs(qa - qb) >= 0.5) {
    const TermDef& disp = qa > qb ? a : b;
    const TermDef& vel = qa > qb ? b : a;
    return "both grow as amplitude^" + Num(pa, 2) + ", but " + disp.id + " with displacement and " + vel.id +
           " with velocity: records at another frequency separate them (at the same velocity a lower frequency means a "
           "larger "
           "displacement); the response's strongest line here is " +
           (std::isfinite(fmin) ? Num(fmin) + (fmax > 1.01 * fmin ? "–" + Num(fmax) : "") : "?") + " Hz";
  }
  return "their forces have the same form at these amplitudes: no record separates them; declare only one";
}

// |ρ| between a parameter and a term's parameters (the largest) in a fit's covariance; NaN without one.
double LargestCorrelation(const FitSnapshot& f, const std::string& param, const TermDef& t) {
  const auto names = f.model.ParamNames();
  const long i = std::find(names.begin(), names.end(), param) - names.begin(), off = f.model.Offset(&t);
  const Eigen::MatrixXd& c = f.fit.covariance;
  if (off < 0 || i >= static_cast<long>(names.size()) || c.rows() != static_cast<long>(names.size())) return NAN;
  double best = 0;
  for (long j = off; j < off + static_cast<long>(t.params.size()); ++j)
    if (c(i, i) > 0 && c(j, j) > 0) best = std::max(best, std::abs(c(i, j)) / std::sqrt(c(i, i) * c(j, j)));
  return best;
}

// The separability hints and the notes on absorbed effects (diagnostics.h).
void Separability(const FitSnapshot& fin, const std::vector<FitSnapshot>& fits,
                  const std::vector<StepDiagnostics>& steps, const std::vector<ParamCorrelation>& corr,
                  const std::vector<PreparedRecord>& recs, LoopDiagnostics* d) {
  std::set<std::pair<const TermDef*, const TermDef*>> seen;
  auto hint = [&](const TermDef* a, const TermDef* b, const FitSnapshot& f, const std::string& why) {
    if (!a || !b || (!Dissipative(a) && !Dissipative(b)) || a == b) return;
    if (!seen.insert(a < b ? std::make_pair(a, b) : std::make_pair(b, a)).second) return;
    const double* tha = f.fit.theta.data() + f.model.Offset(a);
    const double* thb = f.fit.theta.data() + f.model.Offset(b);
    d->separability.push_back("these records cannot separate " + a->id + " and " + b->id + " (" + why +
                              "): " + PairHint(*a, tha, *b, thb, recs, f.model.fc) +
                              ". Fit such records together (repeat --data).");
  };
  for (const ParamCorrelation& c : corr)
    hint(TermOfParam(fin.model, c.a), TermOfParam(fin.model, c.b), fin,
         "correlated in the final fit, ρ = " + Num(c.rho, 3));
  for (size_t k = 0; k < steps.size() && k + 1 < fits.size(); ++k) {
    const FitSnapshot& f = fits[k + 1];
    if (f.refound) continue;  // a better optimum of the same model: its drift is no term's doing
    const TermDef* added = *FindTerm(steps[k].term);
    for (const ParamDrift& p : steps[k].drift) {
      const TermDef* moved = TermOfParam(f.model, p.name);
      if (!(std::abs(p.relative) > kLargeDrift) || !Dissipative(moved)) continue;
      const std::string what = p.name + " moved " + Num(100 * p.relative, 2) + " % when " + added->id + " was " +
                               (steps[k].kept ? "added" : "tried");
      // Kept, and the final fit tells the two apart: the declared value had absorbed the effect.
      const double rho = steps[k].kept ? LargestCorrelation(fin, p.name, *added) : NAN;
      if (rho < kStrongCorrelation)
        d->absorbed.push_back(what + ": before it, " + moved->id + " absorbed part of " + added->id +
                              "'s effect; the final fit separates them (|ρ| = " + Num(rho, 2) + ")");
      else
        hint(moved, added, f, what);
    }
  }
}

}  // namespace

std::string AttractorLoss(const Invariants& before, const Invariants& after) {
  // The measured side is the same for both models; `before` carries it (a diverged free run gives
  // Invariants{}, measured fields NaN too).
  const double measured_rate = before.switching_rate_measured, floor = before.poincare_floor;
  const bool diverged = std::isnan(after.switching_rate_measured);
  std::string lost;
  if (measured_rate > 0 && before.switching_rate > 0 && !(after.switching_rate > 0))
    lost = "no change of well over the record (" + Num(before.switching_rate, 3) + "/s before, measured " +
           Num(measured_rate, 3) + "/s" +
           (diverged                                ? ", the free run diverged"
            : std::isnan(after.right_well_fraction) ? ", one well"
                                                    : "") +
           ")";
  if (before.poincare <= floor && !(after.poincare <= floor))
    lost += (lost.empty() ? "" : "; ") + std::string("the Poincaré section beyond the measured floor (H ") +
            Num(before.poincare, 3) + " -> " + Num(after.poincare, 3) + ", floor " + Num(floor, 3) + ")";
  return lost;
}

LoopDiagnostics Diagnose(const std::vector<FitSnapshot>& fits, const std::vector<PreparedRecord>& recs,
                         const Setup& setup, const FitOptions& fo, const std::string& stop) {
  LoopDiagnostics d;
  d.chaos = CheckChaos(recs, setup, fo.objective);
  if (fits.empty()) return d;
  auto invariants = [&](const FitSnapshot& s) {
    return d.chaos.chaotic ? ComputeInvariants(s.model, s.fit.theta, recs, setup, d.chaos, s.fit.errors) : Invariants{};
  };
  d.declared = invariants(fits[0]);
  size_t base = 0;  // the fit each refit started from: the last one kept before it
  Invariants base_inv = d.declared;
  for (size_t k = 1; k < fits.size(); ++k) {
    StepDiagnostics s;
    s.term = fits[k].term;
    s.kept = fits[k].kept;
    s.refound = fits[k].refound;
    s.drift = DriftOf(fits[base].model, fits[base].fit, fits[k].model, fits[k].fit);
    s.before = base_inv;
    s.after = invariants(fits[k]);
    if (d.chaos.chaotic) s.attractor_loss = AttractorLoss(s.before, s.after);
    if (s.kept) base = k, base_inv = s.after;
    d.steps.push_back(std::move(s));
  }
  const FitSnapshot& fin = fits[base];
  d.final = base_inv;
  if (d.chaos.chaotic) d.attractor_loss = AttractorLoss(d.declared, d.final);
  // Every measured output's residual is tested; the verdict is the first output (main first) far from
  // white, so a structured residual on a second output (e.g. the voltage) is not hidden by a white one.
  const double horizon = fo.shooting_horizon_s > 0 ? fo.shooting_horizon_s : 0.5;
  // Records fitted on short horizons (--objective auto): their residual is far from white even for the true
  // model (noise in the restart states and the input acts through an unstable flow), so it is compared
  // with the same test on the final model's twins, where nothing is missing.
  const bool calibrate = std::any_of(recs.begin(), recs.end(),
                                     [](const PreparedRecord& r) { return r.chaotic || r.snaps || r.horizon_s > 0; });
  const std::vector<std::vector<PreparedRecord>> twins =
      calibrate ? TwinRecords(fin.model, fin.fit.theta, recs, setup, kTwins,
                              fo.objective == Objective::kShooting ? horizon : 0.0)
                : std::vector<std::vector<PreparedRecord>>{};
  for (int k = 0; k < kOutputSlots; ++k) {
    const OutputSlot slot = static_cast<OutputSlot>(k);
    if (!std::any_of(recs.begin(), recs.end(), [&](const PreparedRecord& r) { return r.Has(slot); })) continue;
    Whiteness w = FinalWhiteness(fin, recs, setup, d.chaos, horizon, fo.objective == Objective::kShooting, slot);
    for (const std::vector<PreparedRecord>& twin : twins) {
      const ChaosCheck tc = CheckChaos(twin, setup, fo.objective);
      const Whiteness tw = FinalWhiteness(fin, twin, setup, tc, horizon, fo.objective == Objective::kShooting, slot);
      if (std::isfinite(tw.flatness))
        w.twin_predictable_share = std::isfinite(w.twin_predictable_share)
                                       ? std::max(w.twin_predictable_share, 1 - tw.flatness)
                                       : 1 - tw.flatness;
    }
    if (!w.white && std::isfinite(w.twin_predictable_share) &&
        1 - w.flatness < w.twin_predictable_share + kPredictableShare)
      w.white = true;
    d.whiteness_by_output.emplace_back(OutputName(setup, slot), w);
  }
  std::string tested = d.whiteness_by_output.empty() ? "" : d.whiteness_by_output[0].first;
  if (!d.whiteness_by_output.empty()) d.whiteness = d.whiteness_by_output[0].second;
  for (const auto& [name, w] : d.whiteness_by_output)
    if (!w.white || (w.dof == 0 && w.diverged)) {
      d.whiteness = w, tested = name;
      break;
    }
  const std::string of = d.whiteness_by_output.size() > 1 ? " of the " + tested + " output" : "";
  if (d.whiteness.dof == 0 && d.whiteness.diverged) {
    d.unexplained = "the final model diverges when simulated from the measured state (" + d.whiteness.residual +
                    "), before its residual could be tested; the loop stopped: " + stop + ".";
  } else if (!d.whiteness.white) {
    std::string lines;
    for (double f : d.whiteness.dominant_hz) lines += (lines.empty() ? "" : ", ") + Num(f, 4);
    d.unexplained =
        "the final residual" + of + " is far from white (Ljung-Box Q = " + Num(d.whiteness.statistic, 4) + " on " +
        std::to_string(d.whiteness.dof) + " lags, p = " + Num(d.whiteness.p_value, 2) + " < " +
        Num(d.whiteness.alpha, 2) + "; spectral flatness " + Num(d.whiteness.flatness, 2) + ": " +
        Num(100 * (1 - d.whiteness.flatness), 2) + " % of it predictable from its past" +
        (lines.empty() ? "" : "; strongest lines " + lines + " Hz") + ") and the loop stopped: " + stop + ". " +
        (stop.rfind("it reached --max-added", 0) == 0 ? "More candidates may explain part of it (raise --max-added); "
                                                        "what they leave is a term not in the library or a "
                                                        "sensor effect."
                                                      : "The model lacks something the candidates do not hold (a term "
                                                        "not in the library, or a sensor effect); nothing "
                                                        "was added for it.");
  }
  d.correlations = StrongCorrelations(fin.model.ParamNames(), fin.fit.covariance);
  Separability(fin, fits, d.steps, d.correlations, recs, &d);
  return d;
}

}  // namespace bistable
