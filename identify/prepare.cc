// Records prepared for a setup (model.h PrepareRecord): the derived signals, restart states, scales, noise
// levels and output weights.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "identify/model.h"

namespace bistable {

UniformSpline DriveSpline(const PreparedRecord& r, const std::vector<double>& input) {
  if (!(r.f_drive > 0)) return UniformSpline(r.t0, r.dt, input);
  return UniformSpline(r.t0, r.dt, SpectralDerivative(input, r.dt, 0, r.f_drive));
}

Status ValidateSetup(const Setup& s) {
  if (!(s.fc.v_sp > 0) || !std::isfinite(s.fc.v_sp)) return Status::InvalidArgument("v_sp", "v_sp must be > 0 m/s");
  if (!(s.fc.v_t > 0) || !std::isfinite(s.fc.v_t)) return Status::InvalidArgument("v_t", "v_t must be > 0 m/s");
  if (!(s.drift_cutoff_hz >= 0) ||
      !std::isfinite(s.drift_cutoff_hz)) {  // its upper bound is each record's: PrepareRecord
    char v[32];
    std::snprintf(v, sizeof v, "%g", s.drift_cutoff_hz);
    return Status::InvalidArgument("drift-cutoff",
                                   std::string("drift-cutoff = ") + v + " violates drift-cutoff >= 0 Hz, finite");
  }
  if (s.drift_cutoff_hz > 0 && s.output != OutputKind::kVelocity)
    return Status::InvalidArgument(
        "drift-cutoff",
        "drift-cutoff acts on a displacement integrated from a velocity output: it needs --output-kind velocity");
  const bool disp = s.output != OutputKind::kVelocity;
  if (s.input == InputKind::kBaseAcceleration && disp && s.frame == OutputFrame::kAbsolute)
    return Status::InvalidArgument("output",
                                   "an absolute displacement output needs the base displacement as input; with a "
                                   "base acceleration input use a velocity output or --output-frame relative");
  if (s.input == InputKind::kBaseDisplacement && !disp)
    return Status::InvalidArgument("output",
                                   "with a base displacement input the output must be a displacement "
                                   "(camera/laser position); velocity outputs go with a base acceleration input");
  return Status::Ok();
}

std::string OutputName(const Setup& s, OutputSlot slot) {
  switch (slot) {
    case OutputSlot::kMain:
      return s.output == OutputKind::kVelocity       ? "velocity"
             : s.output == OutputKind::kDisplacement ? "displacement"
                                                     : "analogue";
    case OutputSlot::kResonator:
      return "resonator";
    case OutputSlot::kVoltage:
      return "voltage";
  }
  return "";
}

int OutputSlotOf(const TermDef& t, const Setup& s) {
  if (t.body != Body::kOutput) return -1;
  for (int k = 0; k < kOutputSlots; ++k)
    if (t.output == OutputName(s, static_cast<OutputSlot>(k))) return k;
  return -1;
}

double PreparedRecord::Scale(OutputSlot s) const {
  return s == OutputSlot::kMain ? meas_scale
         : s == OutputSlot::kVoltage
             ? volt_scale
             : [&] {
                 double mean = 0, ss = 0;
                 for (double v : meas_res) mean += v;
                 mean /= static_cast<double>(std::max<size_t>(1, meas_res.size()));
                 for (double v : meas_res) ss += (v - mean) * (v - mean);
                 return std::sqrt(ss / static_cast<double>(std::max<size_t>(1, meas_res.size())));
               }();
}

std::array<double, kOutputSlots> RelativeNoise(const std::vector<PreparedRecord>& recs) {
  std::array<double, kOutputSlots> nu = {0, 0, 0};
  int count[kOutputSlots] = {0, 0, 0};
  for (const PreparedRecord& r : recs)
    for (int k = 0; k < kOutputSlots; ++k) {
      const OutputSlot s = static_cast<OutputSlot>(k);
      const double rel = r.noise[k] / r.Scale(s);
      if (r.Has(s) && std::isfinite(rel)) nu[k] += rel * rel, ++count[k];
    }
  for (int k = 0; k < kOutputSlots; ++k) nu[k] = count[k] ? std::sqrt(nu[k] / count[k]) : NAN;
  return nu;
}

void SetOutputWeightsFrom(const std::array<double, kOutputSlots>& level, std::vector<PreparedRecord>* recs) {
  for (PreparedRecord& r : *recs) {
    r.weight[0] = 1.0;
    for (int k = 1; k < kOutputSlots; ++k) {
      const double lam = (level[0] / level[k]) * (level[0] / level[k]);
      r.weight[k] = std::isfinite(lam) && lam > 0 ? std::clamp(lam, kMinOutputWeight, kMaxOutputWeight) : 1.0;
    }
  }
}

void SetOutputWeights(std::vector<PreparedRecord>* recs) { SetOutputWeightsFrom(RelativeNoise(*recs), recs); }

namespace {

// The main body's absolute position x from the output (base displacement input; a relative output
// plus the base).
std::vector<double> AbsolutePosition(const std::vector<double>& out, const PreparedRecord& r, const Setup& setup) {
  std::vector<double> x = out;
  if (setup.frame == OutputFrame::kRelative)
    for (size_t i = 0; i < x.size(); ++i) x[i] += r.input[i];
  return x;
}

// The velocity relative to the base from a velocity output (an absolute one minus the base velocity).
std::vector<double> RelativeVelocity(const std::vector<double>& out, const PreparedRecord& r, const Setup& setup) {
  std::vector<double> v_rel = out;
  if (setup.input == InputKind::kBaseAcceleration && setup.frame == OutputFrame::kAbsolute)
    for (size_t i = 0; i < v_rel.size(); ++i) v_rel[i] -= r.base_v[i];
  return v_rel;
}

// The resonator's coordinate r of the integrated state: x_r (displacement input: absolute) or
// z = x_r − y otherwise (force input: no base).
std::vector<double> ResonatorCoordinate(const std::vector<double>& xr, const std::vector<double>& out,
                                        const Setup& setup) {
  std::vector<double> q = xr;
  if (setup.input != InputKind::kBaseDisplacement)
    for (size_t i = 0; i < q.size(); ++i) q[i] -= out[i];
  return q;
}

// Band-limited derivative of one of the record's signals at its cutoff.
std::vector<double> Derivative(const PreparedRecord& r, const std::vector<double>& v, int order) {
  return SpectralDerivative(v, r.dt, order, r.f_cut);
}

// A coordinate's band-limited value, first and second derivative.
void CoordinateAndDerivatives(const PreparedRecord& r, const std::vector<double>& q, std::vector<double>* value,
                              std::vector<double>* first, std::vector<double>* second) {
  *value = Derivative(r, q, 0);
  *first = Derivative(r, q, 1);
  *second = Derivative(r, q, 2);
}

// The measured coordinate p of the integrated state and its derivatives, the relative y, y' and the
// compared output (and the base's displacement or velocity where the output needs it).
void MainBodySignals(PreparedRecord* r, const std::vector<double>& out, const Setup& setup) {
  const size_t n = out.size();
  r->meas = out;
  if (setup.input == InputKind::kBaseDisplacement) {
    r->base_x = r->input;
    const std::vector<double> x0d = Derivative(*r, r->input, 1);
    const std::vector<double> x = AbsolutePosition(out, *r, setup);
    CoordinateAndDerivatives(*r, x, &r->p, &r->pd, &r->pdd);
    r->y.resize(n), r->yd.resize(n);
    for (size_t i = 0; i < n; ++i) r->y[i] = r->p[i] - r->input[i], r->yd[i] = r->pd[i] - x0d[i];
    return;
  }
  if (setup.input == InputKind::kBaseAcceleration) r->base_v = IntegrateFft(r->input, r->dt, 0.0);
  if (setup.output != OutputKind::kVelocity) {
    CoordinateAndDerivatives(*r, out, &r->p, &r->pd, &r->pdd);
  } else {
    const std::vector<double> v_rel = RelativeVelocity(out, *r, setup);
    r->pd = Derivative(*r, v_rel, 0);
    r->pdd = Derivative(*r, v_rel, 1);
    // Zero-mean: an offset (the well) is not observable from velocity; drift below --drift-cutoff removed.
    r->p = IntegrateFft(v_rel, r->dt, setup.drift_cutoff_hz);
  }
  r->y = r->p;
  r->yd = r->pd;
}

// The resonator's measured coordinate and its derivatives, and z, z'.
void ResonatorSignals(PreparedRecord* r, const std::vector<double>& xr, const std::vector<double>& out,
                      const Setup& setup) {
  const size_t n = out.size();
  r->meas_res = xr;
  const std::vector<double> q = ResonatorCoordinate(xr, out, setup);
  CoordinateAndDerivatives(*r, q, &r->r, &r->rd, &r->rdd);
  r->z.resize(n), r->zd.resize(n);
  for (size_t i = 0; i < n; ++i) {
    r->z[i] = setup.input == InputKind::kBaseDisplacement ? r->r[i] - r->p[i] : r->r[i];
    r->zd[i] = setup.input == InputKind::kBaseDisplacement ? r->rd[i] - r->pd[i] : r->rd[i];
  }
}

// Initial and restart states: local cubic fits (the band-limited derivative of a mirrored record is
// distorted at its ends, and its wider band lets more noise into single-sample states).
void RestartStates(PreparedRecord* r, const std::vector<double>& out, const Setup& setup) {
  const double dt = r->dt;
  if (setup.input == InputKind::kBaseDisplacement) {
    const std::vector<double> x = AbsolutePosition(out, *r, setup);
    r->ic_p = SavitzkyGolay(x, dt, 4, 0);
    r->ic_pd = SavitzkyGolay(x, dt, 4, 1);
  } else if (setup.output != OutputKind::kVelocity) {
    r->ic_p = SavitzkyGolay(out, dt, 4, 0);
    r->ic_pd = SavitzkyGolay(out, dt, 4, 1);
  } else {
    r->ic_p = r->p;
    r->ic_pd = SavitzkyGolay(RelativeVelocity(out, *r, setup), dt, 4, 0);
  }
  if (!r->r.empty()) {
    const std::vector<double> q = ResonatorCoordinate(r->meas_res, out, setup);
    r->ic_r = SavitzkyGolay(q, dt, 4, 0);
    r->ic_rd = SavitzkyGolay(q, dt, 4, 1);
  }
}

// The NRMSE denominator and the ranges of y, y' (for substep bounds and divergence); an error when
// the output is constant.
Status SetScales(PreparedRecord* r) {
  const size_t n = r->n();
  double mean = 0;
  for (double v : r->meas) mean += v;
  mean /= static_cast<double>(n);
  double ss = 0;
  for (double v : r->meas) ss += (v - mean) * (v - mean);
  r->meas_scale = std::sqrt(ss / static_cast<double>(n));
  if (!(r->meas_scale > 0))
    return Status::InvalidArgument("data", "record '" + r->name + "': the output is constant over the range used");
  r->p_range = 0;
  r->v_range = 0;
  for (size_t i = 0; i < n; ++i) r->p_range = std::max(r->p_range, std::abs(r->y[i]));
  for (size_t i = 0; i < n; ++i) r->v_range = std::max(r->v_range, std::abs(r->yd[i]));
  if (!(r->p_range > 0)) r->p_range = r->meas_scale;
  if (!(r->v_range > 0)) r->v_range = r->meas_scale / r->dt;
  return Status::Ok();
}

}  // namespace

void BandLimitedRestarts(PreparedRecord* r) {
  const size_t n = r->ic_p.size(), edge = std::min<size_t>(16, n / 4);
  auto take = [&](std::vector<double>* ic, const std::vector<double>& from) {
    if (ic->size() != n || from.size() != n) return;
    for (size_t i = edge; i + edge < n; ++i) (*ic)[i] = from[i];
  };
  take(&r->ic_p, r->p), take(&r->ic_pd, r->pd);
  if (!r->ic_r.empty()) take(&r->ic_r, r->r), take(&r->ic_rd, r->rd);
}

StatusOr<PreparedRecord> PrepareRecord(const Record& rec, const Setup& setup, size_t begin, size_t end, double f_cut_hz,
                                       const std::string& name) {
  BISTABLE_RETURN_IF_ERROR(ValidateSetup(setup));
  end = std::min(end, rec.t.size());
  constexpr size_t kMinSamples = 64;
  if (end <= begin || end - begin < kMinSamples)
    return Status::InvalidArgument(
        "data", "record '" + name + "' has " + std::to_string(end > begin ? end - begin : 0) +
                    " samples in the range used; at least " + std::to_string(kMinSamples) + " are needed");
  PreparedRecord r;
  r.name = name;
  r.dt = rec.dt;
  r.t0 = rec.t[begin];
  auto slice = [&](const std::vector<double>& v) { return std::vector<double>(v.begin() + begin, v.begin() + end); };
  r.input = slice(rec.input);
  const std::vector<double> out = slice(rec.output);
  r.f_drive = DriveCutoff(r.input, r.dt);
  r.in_spline = DriveSpline(r, r.input);
  if (!(f_cut_hz >= 0)) return Status::InvalidArgument("deriv-cutoff", "the derivative cutoff must be >= 0 Hz");
  r.f_cut = f_cut_hz > 0 ? std::min(f_cut_hz, 0.5 / r.dt) : AutoCutoff(out, r.dt);
  if (setup.drift_cutoff_hz > 0 && !(setup.drift_cutoff_hz < r.f_cut)) {  // it would remove the whole signal
    char v[96];
    std::snprintf(v, sizeof v, "drift-cutoff = %g violates drift-cutoff < %g Hz", setup.drift_cutoff_hz, r.f_cut);
    return Status::InvalidArgument("drift-cutoff",
                                   std::string(v) + ", the derivative cutoff of record '" + name +
                                       "' (a high-pass of the displacement must keep the band the model sees)");
  }
  MainBodySignals(&r, out, setup);
  if (!rec.resonator.empty()) {
    if (setup.input == InputKind::kBaseAcceleration)
      return Status::InvalidArgument("resonator",
                                     "a measured resonator needs a base displacement or force input (its "
                                     "absolute position cannot be related to an acceleration-driven base)");
    ResonatorSignals(&r, slice(rec.resonator), out, setup);
  }
  RestartStates(&r, out, setup);
  BISTABLE_RETURN_IF_ERROR(SetScales(&r));
  r.noise[0] = NoiseLevel(r.meas, r.dt);
  if (!r.meas_res.empty()) r.noise[1] = NoiseLevel(r.meas_res, r.dt);
  if (!rec.voltage.empty()) {
    r.volt = slice(rec.voltage);
    r.w = Derivative(r, r.volt, 0);
    r.wd = Derivative(r, r.volt, 1);
    r.ic_w = SavitzkyGolay(r.volt, r.dt, 4, 0);
    double mean = 0, ss = 0;
    for (double v : r.volt) mean += v;
    mean /= static_cast<double>(r.n());
    for (double v : r.volt) ss += (v - mean) * (v - mean);
    r.volt_scale = std::sqrt(ss / static_cast<double>(r.n()));
    if (!(r.volt_scale > 0))
      return Status::InvalidArgument("data",
                                     "record '" + r.name + "': the voltage output is constant over the range used");
    r.noise[2] = NoiseLevel(r.volt, r.dt);
  }
  return r;
}

}  // namespace bistable
