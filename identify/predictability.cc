#include "identify/predictability.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "dynamics/spectrum.h"
#include "identify/fit.h"

namespace bistable {

int CountWellChanges(const std::vector<double>& y, double well) {
  if (!(well > 0)) return -1;
  int side = 0, changes = 0;
  for (double v : y) {
    if (!std::isfinite(v)) continue;
    const int now = v > 0.5 * well ? 1 : v < -0.5 * well ? -1 : 0;
    if (now == 0) continue;
    if (side != 0 && now != side) ++changes;
    side = now;
  }
  return changes;
}

double DriveFrequency(const PreparedRecord& r) {
  if (r.input.size() < 16) return NAN;
  std::vector<double> x = r.input;
  double mean = 0;
  for (double v : x) mean += v;
  mean /= static_cast<double>(x.size());
  for (double& v : x) v -= mean;
  std::vector<std::complex<double>> X;
  RealFftHalf(x, &X);
  const double df = 1.0 / (r.dt * static_cast<double>(x.size()));
  double pw = 0, fpw = 0;
  for (size_t k = 1; k < X.size(); ++k) {
    const double p = std::norm(X[k]);
    pw += p, fpw += p * df * static_cast<double>(k);
  }
  return pw > 0 ? fpw / pw : NAN;
}

double HorizonError(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r, const Setup& setup,
                    double horizon_s) {
  std::vector<double> out;
  const int every = horizon_s > 0 ? std::max(2, static_cast<int>(std::round(horizon_s / r.dt))) : 0;
  PreparedRecord b = r;  // restarts from the band-limited states, whatever the record's own
  BandLimitedRestarts(&b);
  if (!Simulate(m, th, b, setup, &out, nullptr, 0, every) || out.size() != r.n()) return NAN;
  double ss = 0;
  for (size_t i = 0; i < r.n(); ++i) ss += (out[i] - r.meas[i]) * (out[i] - r.meas[i]);
  return 100.0 * std::sqrt(ss / static_cast<double>(r.n())) / r.meas_scale;
}

namespace {

// The main body's wells ±sqrt(−k_lin/k3) when the model has a negative linear and a positive cubic
// stiffness (the quintic, if any, ignored: a bound for the hysteresis, not a root), else 0.
double WellOf(const IdentModel& m, const std::vector<double>& th) {
  double k1 = 0, k3 = 0;
  for (const TermDef* t : m.terms) {
    if (t->body != Body::kMain) continue;
    const int off = m.Offset(t);
    if (t->kind == TermKind::kLinear) k1 = th[off];
    if (t->kind == TermKind::kStiffness3) k3 = th[off];
  }
  return k1 < 0 && k3 > 0 ? std::sqrt(-k1 / k3) : 0.0;
}

}  // namespace

namespace {

// RMS of the difference of two output series over [0, n), relative to the record's output scale, in %.
double RelativeRms(const std::vector<double>& a, const std::vector<double>& b, const PreparedRecord& r) {
  double ss = 0;
  for (size_t i = 0; i < r.n(); ++i) ss += (a[i] - b[i]) * (a[i] - b[i]);
  return 100.0 * std::sqrt(ss / static_cast<double>(r.n())) / r.meas_scale;
}

// The short horizon of a chaotic record: simulated in segments of `max_horizon_s` from the measured (band-limited)
// states and again from states moved by (sigma, sigma_v) (alternating sign from segment to segment) with the
// input's noise drawn again (`noisy_input`); the pooled RMS difference at each lag since the restart; the horizon
// is the longest lag (at least 4 samples, at most max_horizon_s) whose segments' RMS difference up to that lag
// stays below kShortDivergence % of the output's RMS. (TestPredictability moves the input only: multiple shooting
// fits the states.)
double ShortHorizon(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                    const PreparedRecord& noisy_input, const Setup& setup, double max_horizon_s, double sigma,
                    double sigma_v, int sub, double* divergence) {
  const int every = std::max(4, static_cast<int>(std::round(max_horizon_s / r.dt)));
  const size_t segs = NumSegments(r.n(), every);
  std::vector<double> states(segs * kStateDim), moved(segs * kStateDim);
  for (size_t k = 0; k < segs; ++k) {
    const std::array<double, kStateDim> x = MeasuredState(m, th, r, setup, k * static_cast<size_t>(every));
    const double sgn = (k % 2 == 0) ? 1.0 : -1.0;
    for (int c = 0; c < kStateDim; ++c)
      states[k * kStateDim + c] = moved[k * kStateDim + c] = x[static_cast<size_t>(c)];
    moved[k * kStateDim + 0] += sgn * sigma;
    moved[k * kStateDim + 1] += ((k / 2) % 2 == 0 ? 1.0 : -1.0) * sigma_v;
  }
  SegmentStates a, b;
  a.states = &states, b.states = &moved;
  SimOutputs oa, ob;
  if (!SimulateOutputs(m, th, {}, r, setup, sub, every, false, &oa, nullptr, &a) ||
      !SimulateOutputs(m, th, {}, noisy_input, setup, sub, every, false, &ob, nullptr, &b)) {
    *divergence = INFINITY;
    return 4 * r.dt;
  }
  std::vector<double> ss(static_cast<size_t>(every) + 1, 0.0);
  std::vector<size_t> count(ss.size(), 0);
  for (size_t i = 1; i < r.n(); ++i) {
    const size_t lag = (i - 1) % static_cast<size_t>(every) + 1;
    const double d = oa.out[0][i] - ob.out[0][i];
    if (!std::isfinite(d)) continue;
    ss[lag] += d * d, ++count[lag];
  }
  // Cumulative: the error a segment of `lag` samples would have.
  double cum = 0;
  size_t cum_n = 0;
  int best = 4;
  *divergence = 0;
  for (int lag = 1; lag <= every; ++lag) {
    cum += ss[static_cast<size_t>(lag)], cum_n += count[static_cast<size_t>(lag)];
    const double rel = cum_n ? 100.0 * std::sqrt(cum / static_cast<double>(cum_n)) / r.meas_scale : 0.0;
    if (rel < kShortDivergence)
      best = std::max(best, lag), *divergence = rel;
    else
      break;
  }
  return best * r.dt;
}

}  // namespace

Predictability TestPredictability(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                                  const Setup& setup, double max_horizon_s, bool require_followed) {
  Predictability p;
  p.record = r.name;
  p.duration_s = r.dt * static_cast<double>(r.n() > 0 ? r.n() - 1 : 0);
  p.well_changes = CountWellChanges(r.y, WellOf(m, th));
  std::vector<double> base;
  const int sub = SubstepsFor(m, th, r);
  // The output's noise as a state perturbation: in position for displacement-like outputs (and in velocity by
  // the derivative's noise gain 2π f_c / √3), in velocity for velocity outputs (and in position by its inverse).
  const double noise = std::isfinite(r.noise[0]) && r.noise[0] > 0 ? r.noise[0] : 1e-3 * r.meas_scale;
  const double gain = 2.0 * M_PI * std::max(r.f_cut, 1.0 / std::max(p.duration_s, r.dt)) / std::sqrt(3.0);
  const bool velocity = setup.output == OutputKind::kVelocity;
  const double sigma = velocity ? noise / gain : noise, sigma_v = velocity ? noise : noise * gain;
  const double sigma_in = NoiseLevel(r.input, r.dt);
  p.noise = sigma, p.input_noise = sigma_in;
  bool diverged = !Simulate(m, th, r, setup, &base, nullptr, sub);
  double floor = 0;
  size_t first_apart = r.n();
  // Twins of the long simulation: the start moved by the noise, and the input's own noise drawn again (the
  // record was driven by the true input; every simulation by the measured one).
  const size_t window = std::max<size_t>(2, static_cast<size_t>(std::round(0.25 / r.dt)));
  PreparedRecord twin = r;
  std::mt19937_64 rng(12345);
  std::normal_distribution<double> in_noise(0.0, std::isfinite(sigma_in) && sigma_in > 0 ? sigma_in : 1e-300);
  // Twins 0 and 1: the start moved by ±σ; 2 to 2 + kInputDraws − 1: the input's noise drawn again (the first
  // also with the start velocity moved). One draw is a sample of one: with the drive band-limited
  // (PreparedRecord::f_drive) only the in-band part of the input's noise reaches the model, and on a
  // chaotic coupled record a single draw left the truth's twins 3.2 % apart where the truth misses the
  // record by 200 % (and a margin of the band 1.5 instead of 1.25 gave 112 %): the floor is the largest
  // of several.
  constexpr int kInputDraws = 6;
  for (int k = 0; k < 2 + kInputDraws && !diverged; ++k) {
    twin.ic_p[0] = r.ic_p[0] + (k == 0 ? sigma : k == 1 ? -sigma : 0.0);
    twin.ic_pd[0] = r.ic_pd[0] + (k == 2 ? sigma_v : 0.0);
    if (k >= 2 && std::isfinite(sigma_in) && sigma_in > 0) {
      for (size_t i = 0; i < r.n(); ++i) twin.input[i] = r.input[i] + in_noise(rng);
      twin.in_spline = DriveSpline(r, twin.input);
      if (!twin.base_x.empty()) twin.base_x = twin.input;
    }
    std::vector<double> other;
    if (!Simulate(m, th, twin, setup, &other, nullptr, sub)) {
      diverged = true;
      break;
    }
    double run = 0;
    for (size_t i = 0; i < r.n(); ++i) {
      const double d = other[i] - base[i];
      run += d * d;
      if (i >= window) run -= (other[i - window] - base[i - window]) * (other[i - window] - base[i - window]);
      if (i + 1 >= window && i < first_apart &&
          std::sqrt(std::max(run, 0.0) / static_cast<double>(window)) > kDivergedShare * r.meas_scale)
        first_apart = i;
    }
    floor = std::max(floor, RelativeRms(other, base, r));
  }
  p.chaos_floor = diverged ? INFINITY : floor;
  p.horizon_s = diverged ? 0.0 : r.dt * static_cast<double>(first_apart >= r.n() ? r.n() - 1 : first_apart);
  p.long_error = diverged ? INFINITY : RelativeRms(base, r.meas, r);
  p.followed = !require_followed || p.long_error < kMeaningfulFloor;
  p.long_meaningful = !diverged && floor < kMeaningfulFloor && p.followed;
  char buf[560];
  if (p.long_meaningful) {
    p.fit_horizon_s = 0;
    std::snprintf(buf, sizeof buf,
                  "twins of the model (start moved by the noise, %.3g mm and %.3g mm/s; the input's noise, %.3g SI, "
                  "drawn again) stay "
                  "within %.3g %% of each other over the %.1f s record (< %.3g %%): the long simulation is meaningful "
                  "and is fitted",
                  1e3 * sigma, 1e3 * sigma_v, sigma_in, floor, p.duration_s, kMeaningfulFloor);
  } else {
    PreparedRecord banded = r, banded_twin = twin;  // the twin: the input's noise drawn again
    BandLimitedRestarts(&banded), BandLimitedRestarts(&banded_twin);
    // Under multiple shooting the segment states are fitted, so what limits a segment is the input's noise:
    // the restarted twins differ by the input drawn again, not by their states.
    p.fit_horizon_s =
        ShortHorizon(m, th, banded, banded_twin, setup, max_horizon_s, 0.0, 0.0, sub, &p.short_divergence);
    if (!diverged && floor < kMeaningfulFloor)  // predictable twins, but the model does not follow the record
      std::snprintf(
          buf, sizeof buf,
          "twins of the model stay within %.3g %% of each other (< %.3g %%), but its long simulation misses the record "
          "by "
          "%.3g %% (%d changes of well measured): it is outside the long simulation error's basin or understates the "
          "record's chaos. Fitted by multiple shooting on %.3g s segments, the longest over which twins restarted from "
          "the same state, their inputs a noise apart, stay within %.3g %% (%.3g %%)",
          floor, kMeaningfulFloor, p.long_error, p.well_changes, p.fit_horizon_s, kShortDivergence, p.short_divergence);
    else
      std::snprintf(
          buf, sizeof buf,
          "twins of the model (start moved by the noise, %.3g mm and %.3g mm/s; the input's noise, %.3g SI, drawn "
          "again) differ by %.3g %% over the "
          "record (>= %.3g %%; %.0f %% of the output's RMS apart after %.2f s; %d changes of well measured): its long "
          "simulation is chaos, not model error. Fitted by multiple shooting on %.3g s segments, the longest over "
          "which "
          "twins restarted from the same state, their inputs a noise apart, stay within %.3g %% (%.3g %%)",
          1e3 * sigma, 1e3 * sigma_v, sigma_in, floor, kMeaningfulFloor, 100 * kDivergedShare, p.horizon_s,
          p.well_changes, p.fit_horizon_s, kShortDivergence, p.short_divergence);
  }
  p.reason = buf;
  return p;
}

// A moving-block bootstrap of a residual series: blocks of 2τ samples (τ its correlation time, CorrelationTime;
// at least 1, at most a quarter of the series) from uniform starts, laid end to end, so that the resampled series
// keeps the residual's level and its correlation over short lags. Empty for an empty or non-finite series.
static std::vector<double> BlockResampled(const std::vector<double>& res, std::mt19937_64& rng) {
  const size_t n = res.size();
  if (n < 8 || !std::all_of(res.begin(), res.end(), [](double v) { return std::isfinite(v); })) return {};
  const double tau = CorrelationTime(res.data(), n, std::min<size_t>(2000, n / 2));
  const size_t len = std::clamp<size_t>(static_cast<size_t>(std::lround(2 * tau)), 1, n / 4);
  std::uniform_int_distribution<size_t> start(0, n - len);
  std::vector<double> out;
  out.reserve(n);
  while (out.size() < n) {
    const size_t b = start(rng);
    for (size_t j = 0; j < len && out.size() < n; ++j) out.push_back(res[b + j]);
  }
  return out;
}

std::vector<std::vector<PreparedRecord>> TwinRecords(const IdentModel& m, const std::vector<double>& th,
                                                     const std::vector<PreparedRecord>& recs, const Setup& setup,
                                                     int twins, double shooting_horizon_s, TwinNoise kind, int first) {
  std::vector<std::vector<PreparedRecord>> out;
  if (setup.input == InputKind::kForce ||
      (setup.output == OutputKind::kVelocity && setup.frame == OutputFrame::kRelative))
    return out;
  // The twins' true input: the measured one low-passed at its own band (AutoCutoff), so that, as for the record,
  // the truth is driven smoothly and only the recorded input carries noise. Driven by the noisy input itself,
  // a twin's truth jitters through friction's narrow transition (σ_v of the spline's slope ≫ v_t) and never
  // sticks, and its residual understated the record's (on a chaotic null record 27 % against 50 % predictable).
  std::vector<SimOutputs> sims(recs.size());
  std::vector<std::vector<double>> clean(recs.size());
  for (size_t i = 0; i < recs.size(); ++i) {
    PreparedRecord r = recs[i];
    clean[i] = SpectralDerivative(r.input, r.dt, 0, AutoCutoff(r.input, r.dt));
    r.input = clean[i];
    r.in_spline = DriveSpline(r, r.input);
    if (!r.base_x.empty()) r.base_x = r.input;
    if (!r.base_v.empty()) r.base_v = IntegrateFft(r.input, r.dt, 0.0);
    if (!SimulateOutputs(m, th, {}, r, setup, 2 * SubstepsFor(m, th, r), 0, false, &sims[i])) return out;
  }
  // Per record and output slot: the noise put on the twin's output (see the header).
  std::vector<std::array<double, kOutputSlots>> noise(recs.size());
  std::vector<std::array<std::vector<double>, kOutputSlots>> resid(recs.size());  // kind kResidualBlocks
  for (size_t i = 0; i < recs.size(); ++i) {
    const PreparedRecord& r = recs[i];
    SimOutputs shot;
    const bool shooting = shooting_horizon_s > 0 && (r.chaotic || r.horizon_s > 0);
    if (shooting) {
      PreparedRecord b = r;
      BandLimitedRestarts(&b);
      if (!SimulateShooting(m, th, b, setup, shooting_horizon_s, &shot)) shot = SimOutputs{};
    }
    const SimOutputs& model = shooting ? shot : sims[i];
    for (int k = 0; k < kOutputSlots; ++k) {
      const OutputSlot slot = static_cast<OutputSlot>(k);
      noise[i][static_cast<size_t>(k)] = r.Has(slot) ? r.noise[k] : 0.0;
      if (!r.Has(slot) || model.out[k].size() != r.n()) continue;
      const std::vector<double>& meas = r.Measured(slot);
      std::vector<double> res(r.n());
      for (size_t j = 0; j < r.n(); ++j) res[j] = meas[j] - model.out[k][j];
      if (kind == TwinNoise::kResidualBlocks) resid[i][static_cast<size_t>(k)] = res;
      const double s_res = NoiseLevel(res, r.dt);
      if (std::isfinite(s_res) && s_res > 0 && !(s_res >= noise[i][static_cast<size_t>(k)]))
        noise[i][static_cast<size_t>(k)] = s_res;
    }
  }
  for (int k = first; k < first + twins; ++k) {
    std::mt19937_64 rng(0x7e57 + 7919 * static_cast<unsigned>(k));
    std::normal_distribution<double> unit(0.0, 1.0);
    std::vector<PreparedRecord> set;
    for (size_t i = 0; i < recs.size(); ++i) {
      const PreparedRecord& r = recs[i];
      Record rec;
      rec.name = r.name + " (twin " + std::to_string(k + 1) + ")";
      rec.dt = r.dt;
      const double s_in = NoiseLevel(r.input, r.dt), s_out = noise[i][0], s_res = noise[i][1], s_v = noise[i][2];
      // kResidualBlocks: each output's error is the record's own residual, resampled in blocks (below).
      std::array<std::vector<double>, kOutputSlots> blocks;
      if (kind == TwinNoise::kResidualBlocks)
        for (int s = 0; s < kOutputSlots; ++s) blocks[s] = BlockResampled(resid[i][s], rng);
      auto err = [&](int slot, double sigma, size_t j) {
        if (!blocks[slot].empty()) return blocks[slot][j];
        return (std::isfinite(sigma) ? sigma : 0.0) * unit(rng);
      };
      for (size_t j = 0; j < r.n(); ++j) {
        rec.t.push_back(r.t0 + r.dt * static_cast<double>(j));
        rec.input.push_back(clean[i][j] + (std::isfinite(s_in) ? s_in : 0.0) * unit(rng));
        rec.output.push_back(sims[i].out[0][j] + err(0, s_out, j));
        if (r.Has(OutputSlot::kResonator)) rec.resonator.push_back(sims[i].out[1][j] + err(1, s_res, j));
        if (r.Has(OutputSlot::kVoltage)) rec.voltage.push_back(sims[i].out[2][j] + err(2, s_v, j));
      }
      auto p = PrepareRecord(rec, setup, 0, rec.t.size(), r.f_cut, rec.name);
      if (!p.ok()) return {};
      PreparedRecord t = std::move(p).value();
      t.index = r.index, t.horizon_s = r.horizon_s, t.chaotic = r.chaotic;
      std::copy(std::begin(r.weight), std::end(r.weight), t.weight);
      if (t.horizon_s > 0 || t.chaotic) BandLimitedRestarts(&t);
      set.push_back(std::move(t));
    }
    out.push_back(std::move(set));
  }
  return out;
}

}  // namespace bistable
