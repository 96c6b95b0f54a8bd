#include "identify/predict.h"

#include <algorithm>
#include <cmath>
#include <complex>

#include <Eigen/Eigenvalues>

#include "dynamics/spectrum.h"

namespace bistable {
namespace {

// Every root of Σ coef[k] y^k (degree ≥ 1 after trailing zeros are dropped), from the companion matrix of
// the monic polynomial in u = y/s, s = max_k |c_k/c_n|^{1/(n−k)} (the roots lie within 2s).
std::vector<std::complex<double>> PolynomialRoots(const std::vector<double>& coef) {
  int n = static_cast<int>(coef.size()) - 1;
  while (n > 0 && coef[static_cast<size_t>(n)] == 0.0) --n;
  if (n < 1) return {};
  const double cn = coef[static_cast<size_t>(n)];
  double s = 0;
  for (int k = 0; k < n; ++k) s = std::max(s, std::pow(std::abs(coef[static_cast<size_t>(k)] / cn), 1.0 / (n - k)));
  if (!(s > 0) || !std::isfinite(s)) return std::vector<std::complex<double>>(static_cast<size_t>(n), 0.0);  // c_n y^n
  Eigen::MatrixXd comp = Eigen::MatrixXd::Zero(n, n);
  for (int i = 1; i < n; ++i) comp(i, i - 1) = 1.0;
  for (int k = 0; k < n; ++k) comp(k, n - 1) = -(coef[static_cast<size_t>(k)] / cn) * std::pow(s, k - n);
  Eigen::EigenSolver<Eigen::MatrixXd> es(comp, false);
  std::vector<std::complex<double>> out;
  for (int i = 0; i < n; ++i) out.push_back(es.eigenvalues()(i) * s);
  return out;
}

double Poly(const std::vector<double>& c, double y) {
  double v = 0;
  for (size_t k = c.size(); k-- > 0;) v = v * y + c[k];
  return v;
}

double PolyDerivative(const std::vector<double>& c, double y) {
  double v = 0;
  for (size_t k = c.size(); k-- > 1;) v = v * y + static_cast<double>(k) * c[k];
  return v;
}

// V(y) = ∫₀^y Σ c_k s^k ds.
double PolyIntegral(const std::vector<double>& c, double y) {
  double v = 0;
  for (size_t k = 0; k < c.size(); ++k)
    v += c[k] * std::pow(y, static_cast<double>(k + 1)) / static_cast<double>(k + 1);
  return v;
}

Equilibrium At(const IdentModel& m, const std::vector<double>& th, const std::vector<double>& coef, double y) {
  Equilibrium e;
  e.y = y;
  e.stiffness = PolyDerivative(coef, y);
  e.stable = e.stiffness > 0;
  e.energy = PolyIntegral(coef, y);
  double c = 0;
  int k = 0;
  for (const TermDef* t : m.terms) {
    if (t->body == Body::kMain && t->IsForce()) {
      double dq = 0, dv = 0;
      TermSlopes(*t, th.data() + k, y, 0.0, m.fc, &dq, &dv);
      c += dv;
    }
    k += static_cast<int>(t->params.size());
  }
  e.damping = c;
  return e;
}

double Rms(const std::vector<double>& x, bool about_mean) {
  if (x.empty()) return NAN;
  double mean = 0;
  if (about_mean) {
    for (double v : x) mean += v;
    mean /= static_cast<double>(x.size());
  }
  double s = 0;
  for (double v : x) s += (v - mean) * (v - mean);
  return std::sqrt(s / static_cast<double>(x.size()));
}

double Mean(const std::vector<double>& x) {
  if (x.empty()) return NAN;
  double s = 0;
  for (double v : x) s += v;
  return s / static_cast<double>(x.size());
}

bool AllFinite(const std::vector<double>& x) {
  return std::all_of(x.begin(), x.end(), [](double v) { return std::isfinite(v); });
}

}  // namespace

std::vector<double> RealPolynomialRoots(const std::vector<double>& coef) {
  std::vector<double> out;
  for (const std::complex<double>& z : PolynomialRoots(coef)) {
    if (std::abs(z.imag()) > 1e-7 * std::abs(z)) continue;
    double y = z.real();
    for (int it = 0; it < 8; ++it) {  // Newton: the eigenvalues carry the companion's rounding
      const double d = PolyDerivative(coef, y);
      if (!(d != 0) || !std::isfinite(d)) break;
      const double step = Poly(coef, y) / d;
      if (!std::isfinite(step)) break;
      y -= step;
      if (std::abs(step) <= 1e-15 * std::max(std::abs(y), 1e-300)) break;
    }
    out.push_back(y);
  }
  std::sort(out.begin(), out.end());
  // A double root may come out as two nearly equal reals: keep one.
  std::vector<double> unique;
  for (double y : out)
    if (unique.empty() || std::abs(y - unique.back()) > 1e-9 * std::max({std::abs(y), std::abs(unique.back()), 1e-300}))
      unique.push_back(y);
  return unique;
}

LinearMode CoupledMode(double m, double C, double K, double a, double b, double c) {
  LinearMode mode;
  // m s³ + (C + m b) s² + (K + C b + a c) s + K b, ascending.
  const std::vector<double> coef = {K * b, K + C * b + a * c, C + m * b, m};
  double best = 0;
  for (const std::complex<double>& s : PolynomialRoots(coef)) {
    if (!(s.imag() > 1e-9 * std::abs(s)) || s.imag() <= best) continue;
    best = s.imag();
    mode.hz = std::abs(s) / (2.0 * M_PI);
    mode.damping_ratio = -s.real() / std::abs(s);
  }
  return mode;
}

StatusOr<ModelStatics> AnalyseStatics(const IdentModel& m, const std::vector<double>& th) {
  const auto names = m.ParamNames();
  if (th.size() != names.size())
    return Status::InvalidArgument("model.params", "the model has " + std::to_string(names.size()) + " parameters, " +
                                                       std::to_string(th.size()) + " given");
  for (size_t i = 0; i < th.size(); ++i)
    if (!std::isfinite(th[i]))
      return Status::InvalidArgument("model.params", "parameter " + names[i] + " is not finite");
  ModelStatics st;
  st.mass = m.Mass(th);
  if (!(st.mass > 0) || !std::isfinite(st.mass))
    return Status::InvalidArgument("model.m_main", "the main mass must be a finite number > 0");
  st.force_coef.assign(6, 0.0);
  int k = 0;
  for (const TermDef* t : m.terms) {
    if (t->body == Body::kMain) {
      switch (t->kind) {
        case TermKind::kLinear:
          st.force_coef[1] += th[k];
          break;
        case TermKind::kStiffness2:
          st.force_coef[2] += th[k];
          break;
        case TermKind::kStiffness3:
          st.force_coef[3] += th[k];
          break;
        case TermKind::kStiffness5:
          st.force_coef[5] += th[k];
          break;
        case TermKind::kBias:
          st.force_coef[0] += th[k];
          break;
        case TermKind::kPiezo:
          st.piezo = true, st.piezo_a = th[k], st.piezo_b = th[k + 1], st.piezo_c = th[k + 2];
          break;
        default:
          break;  // damping, drag, friction: zero at rest
      }
    }
    k += static_cast<int>(t->params.size());
  }
  const std::vector<double> roots = RealPolynomialRoots(st.force_coef);
  if (roots.empty() && st.force_coef[1] == 0 && st.force_coef[2] == 0 && st.force_coef[3] == 0 && st.force_coef[5] == 0)
    return Status::InvalidArgument("model.terms",
                                   "the model has no static restoring force (no linear, y2, y3 or y5 stiffness): "
                                   "it has no wells");
  for (double y : roots) st.equilibria.push_back(At(m, th, st.force_coef, y));
  auto make_well = [&](const Equilibrium& e, const std::string& side) {
    Well w;
    w.side = side;
    w.at = e;
    w.small_orbit_hz = std::sqrt(e.stiffness / st.mass) / (2.0 * M_PI);
    w.damping_ratio = e.damping / (2.0 * std::sqrt(e.stiffness * st.mass));
    if (st.piezo) {
      w.with_circuit = true;
      w.coupled = CoupledMode(st.mass, e.damping, e.stiffness, st.piezo_a, st.piezo_b, st.piezo_c);
      const double om = 2.0 * M_PI * w.small_orbit_hz, den = st.piezo_b * st.piezo_b + om * om;
      w.piezo_stiffness = st.piezo_a * st.piezo_c * om * om / den;
      w.piezo_damping = st.piezo_a * st.piezo_c * st.piezo_b / den;
    }
    return w;
  };
  // The barrier: an unstable equilibrium with a well on each side, the one nearest y = 0.
  int barrier = -1;
  for (size_t i = 1; i + 1 < st.equilibria.size(); ++i) {
    if (st.equilibria[i].stable || !st.equilibria[i - 1].stable || !st.equilibria[i + 1].stable) continue;
    if (barrier < 0 || std::abs(st.equilibria[i].y) < std::abs(st.equilibria[static_cast<size_t>(barrier)].y))
      barrier = static_cast<int>(i);
  }
  if (barrier >= 0) {
    const size_t b = static_cast<size_t>(barrier);
    st.bistable = true;
    st.barrier = st.equilibria[b];
    for (const auto& [e, side] : {std::pair{st.equilibria[b - 1], "left"}, std::pair{st.equilibria[b + 1], "right"}}) {
      Well w = make_well(e, side);
      w.depth = st.barrier.energy - e.energy;
      st.wells.push_back(w);
    }
    return st;
  }
  const Equilibrium* best = nullptr;
  for (const Equilibrium& e : st.equilibria)
    if (e.stable && (!best || std::abs(e.y) < std::abs(best->y))) best = &e;
  if (!best)
    return Status::InvalidArgument("model.params",
                                   "the model's static restoring force has no stable equilibrium (no well)");
  st.wells.push_back(make_well(*best, "only"));
  return st;
}

double AmplitudeAt(const std::vector<double>& x, double dt, double f_hz) {
  if (x.size() < 2 || !(dt > 0) || !std::isfinite(f_hz) || !(f_hz > 0) || !AllFinite(x)) return NAN;
  return ToneAmplitude(x.data(), x.size(), dt, 2.0 * M_PI * f_hz);
}

RecordPrediction PredictRecord(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                               const Setup& setup, const ModelStatics& statics, Objective objective) {
  RecordPrediction p;
  p.name = r.name;
  p.seconds = static_cast<double>(r.n()) * r.dt;
  p.forcing_hz = ForcingFrequency(r.input, r.dt);
  p.input_amplitude = AmplitudeAt(r.input, r.dt, p.forcing_hz);
  p.start_y = (r.ic_p.empty() ? 0.0 : r.ic_p[0]) + m.Offset(th, r.index);
  SimOutputs so;
  p.diverged = !SimulateOutputs(m, th, {}, r, setup, 0, 0, false, &so);
  const std::vector<PreparedRecord> one = {r};
  const Errors e = Evaluate(m, th, one, setup);
  size_t eo = 0;
  for (int k = 0; k < kOutputSlots; ++k) {
    const OutputSlot slot = static_cast<OutputSlot>(k);
    if (!r.Has(slot)) continue;
    OutputPrediction o;
    o.name = OutputName(setup, slot);
    if (eo < e.outputs.size()) o.nrmse = e.outputs[eo].nrmse, o.spectral = e.outputs[eo].fft;
    ++eo;
    const std::vector<double>& meas = r.Measured(slot);
    o.amplitude_measured = AmplitudeAt(meas, r.dt, p.forcing_hz);
    o.rms_measured = Rms(meas, true);
    if (!p.diverged) {
      o.amplitude_predicted = AmplitudeAt(so.out[k], r.dt, p.forcing_hz);
      o.rms_predicted = Rms(so.out[k], true);
    }
    p.outputs.push_back(o);
  }
  std::vector<double> ym, vm;
  MainBodyMotion(r.meas, r, setup, &ym, &vm);
  p.displacement_amplitude_measured = AmplitudeAt(ym, r.dt, p.forcing_hz);
  if (setup.output != OutputKind::kVelocity) p.mean_displacement_measured = Mean(ym);
  auto by_period = [&](const std::vector<double>& ys) {  // invariants.h's rule
    const WellSwitching w = WellsOf(ym, ys, r.dt, p.forcing_hz);
    if (!(w.seconds > 0) || !w.finite) return;
    p.switches.hysteresis = w.measured_split.band;
    p.switches.measured = w.measured.switches / w.seconds;
    if (!ys.empty()) p.switches.predicted = w.simulated.switches / w.seconds;
  };
  by_period({});
  if (statics.bistable) {
    p.switches.well_hysteresis =
        0.5 * std::min(statics.barrier.y - statics.wells[0].at.y, statics.wells[1].at.y - statics.barrier.y);
    p.switches.well_measured = CountSwitches(ym, 0.0, p.switches.well_hysteresis) / p.seconds;
  }
  const ChaosCheck check = CheckChaos(one, setup, objective);
  p.chaotic = check.chaotic;
  p.output_broadband = check.output_broadband.empty() ? NAN : check.output_broadband[0];
  if (p.diverged) return p;
  std::vector<double> ys, vs;
  MainBodyMotion(so.out[0], r, setup, &ys, &vs);
  p.displacement_amplitude_predicted = AmplitudeAt(ys, r.dt, p.forcing_hz);
  by_period(ys);
  if (statics.bistable) p.switches.well_predicted = CountSwitches(ys, 0.0, p.switches.well_hysteresis) / p.seconds;
  // The model's own displacement: a displacement output is it (MainBodyMotion: relative to the base
  // where the base moves); a velocity output's relative velocity integrated (trapezoids) from the state's
  // initial value — not zero-mean, so it says which well the model is in.
  std::vector<double> y_model = ys;
  if (setup.output == OutputKind::kVelocity) {
    y_model.assign(vs.size(), p.start_y);
    for (size_t i = 1; i < vs.size(); ++i) y_model[i] = y_model[i - 1] + 0.5 * r.dt * (vs[i - 1] + vs[i]);
  }
  p.mean_displacement_predicted = Mean(y_model);
  if (statics.bistable && !y_model.empty()) {
    p.switches.model = CountSwitches(y_model, statics.barrier.y, p.switches.well_hysteresis) / p.seconds;
    const double right = static_cast<double>(
        std::count_if(y_model.begin(), y_model.end(), [&](double y) { return y > statics.barrier.y; }));
    p.switches.model_right_fraction = right / static_cast<double>(y_model.size());
  }
  if (p.chaotic) p.invariants = ComputeInvariants(m, th, one, setup, check, e);
  return p;
}

}  // namespace bistable
