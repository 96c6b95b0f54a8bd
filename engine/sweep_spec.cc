#include "engine/sweep_spec.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

#include "base/limits.h"
#include "base/names.h"
#include "base/validate.h"
#include "engine/content_hash.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_kind.h"
#include "engine/sweep_spec_keys.h"

namespace bistable {

using spec_keys::kParamKeys;
using spec_keys::kRefineCriteria;
using spec_keys::kToleranceKeys;
using spec_keys::ParamSlot;

namespace {

std::string G17(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

}  // namespace

std::string SweepSpec::ModelConfigText() const {
  const SweepSpec& spec = *this;
  std::ostringstream os;
  if (spec.model == ModelKind::kSeries) {
    os << "series.cells=" << spec.series.cells << "\nseries.resonators=" << spec.series.resonators
       << "\nseries.bistable=" << spec.series.bistable << "\n";
    for (size_t i = 0; i < spec.series.overrides.size(); ++i)
      for (const auto& [k, v] : spec.series.overrides[i])
        os << "series.cell[" << i << "]." << k << "=" << G17(v) << "\n";
  } else if (spec.terms) {
    os << spec_keys::TermsText(*spec.terms);
  } else if (spec.model == ModelKind::kDimensional) {
    const DimensionalParams& d = spec.dimensional.params;
    os << "dim.bistable=" << spec.dimensional.bistable << "\ndim.resonator=" << d.has_resonator;
    for (double v : {d.m_m, d.k_lin, d.k3, d.c0_m, d.c2_m, d.fric_m.f_s, d.fric_m.f_c, d.fric_m.v_sp, d.fric_m.v_t,
                     d.m_r, d.k_r, d.c0_r, d.c2_r, d.fric_r.f_s, d.fric_r.f_c, d.fric_r.v_sp, d.fric_r.v_t})
      os << "," << G17(v);
    os << "\n";
  }
  // RK4 chains and rig points changed numerics when they moved into lanes (issue 14: rotated forcing
  // phase, tangent from the lane model, the rig's stiffness-set substeps; the rig had ignored "rk4"):
  // results of the per-point path must not be found under their keys.
  if (spec.UsesGenericLanes() && spec.base.integration.integrator == IntegratorKind::kRk4) os << "rk4=lanes\n";
  return os.str();
}

const std::vector<std::string>& DimensionalAxisNames() {
  static const std::vector<std::string> kNames = {"a0_mm", "f0_hz"};
  return kNames;
}

const std::vector<std::string>& CanonicalAxisNames() {
  // Velocities before displacements: a map's first axis runs along the plot's vertical, so a basin
  // map over (ym0, vm0) is drawn in the usual phase plane (y_m(0) across, y_m'(0) up).
  static const std::vector<std::string> kNames = {"alpha", "omega", "eta", "eta_r", "lambda", "phi",
                                                  "eps",   "vm0",   "ym0", "vr0",   "yr0"};
  return kNames;
}

const std::vector<std::string>& InitialStateAxisNames() {
  static const std::vector<std::string> kNames = {"ym0", "vm0", "yr0", "vr0"};
  return kNames;
}

bool IsInitialStateAxis(const std::string& name) {
  const auto& n = InitialStateAxisNames();
  return std::find(n.begin(), n.end(), name) != n.end();
}

bool SweepSpec::HasInitialStateAxes() const {
  return std::any_of(axes.begin(), axes.end(), [](const Axis& a) { return IsInitialStateAxis(a.name); });
}

bool SweepSpec::IsBasinSweep() const {
  return !axes.empty() &&
         std::all_of(axes.begin(), axes.end(), [](const Axis& a) { return IsInitialStateAxis(a.name); });
}

std::string AxisUnit(const std::string& name) {
  static const std::map<std::string, std::string> kUnits = {{"alpha", "A0/delta_s"},
                                                            {"omega", "omega0/omega_n"},
                                                            {"eta", "c/(m_m omega_n)"},
                                                            {"eta_r", "c_r/(m_r omega_n)"},
                                                            {"lambda", "omega_r/omega_n"},
                                                            {"phi", "m_r/m_m"},
                                                            {"eps", "k3 delta_s^2/(m_m omega_n^2)"},
                                                            {"a0_mm", "mm"},
                                                            {"acc0_g", "g"},
                                                            {"force0_n", "N"},
                                                            {"f0_hz", "Hz"},
                                                            {"ym0", "delta_s"},
                                                            {"vm0", "delta_s/tau"},
                                                            {"yr0", "delta_s"},
                                                            {"vr0", "delta_s/tau"},
                                                            // The dimensional (Table 2) model's parameters.
                                                            {"m_m", "kg"},
                                                            {"k_lin", "N/m"},
                                                            {"k3", "N/m^3"},
                                                            {"c0_m", "N s/m"},
                                                            {"c2_m", "N s/m^3"},
                                                            {"fric_m_fs", "N"},
                                                            {"fric_m_fc", "N"},
                                                            {"fric_m_vsp", "m/s"},
                                                            {"fric_m_vt", "m/s"},
                                                            {"m_r", "kg"},
                                                            {"k_r", "N/m"},
                                                            {"c0_r", "N s/m"},
                                                            {"c2_r", "N s/m^3"},
                                                            {"fric_r_fs", "N"},
                                                            {"fric_r_fc", "N"},
                                                            {"fric_r_vsp", "m/s"},
                                                            {"fric_r_vt", "m/s"}};
  auto it = kUnits.find(name);
  return it == kUnits.end() ? "" : it->second;
}

std::string AxisLongName(const std::string& name) {
  static const std::map<std::string, std::string> kNames = {
      {"alpha", "base excitation amplitude alpha = A0/delta_s"},
      {"omega", "excitation frequency Omega = omega0/omega_n"},
      {"eta", "main damping coefficient eta = c/(m_m omega_n) (twice the damping ratio)"},
      {"eta_r", "resonator damping coefficient eta_r = c_r/(m_r omega_n) (twice its damping ratio)"},
      {"lambda", "resonator tuning lambda = omega_r/omega_n"},
      {"phi", "mass ratio phi = m_r/m_m"},
      {"eps", "cubic stiffness epsilon = k3 delta_s^2/(m_m omega_n^2)"},
      {"ym0", "initial displacement of the main mass relative to the base y_m(0)"},
      {"vm0", "initial velocity of the main mass relative to the base y_m'(0)"},
      {"yr0", "initial displacement of the resonator relative to the base y_r(0)"},
      {"vr0", "initial velocity of the resonator relative to the base y_r'(0)"},
      {"a0_mm", "base displacement amplitude A0"},
      {"acc0_g", "base acceleration amplitude (g = 9.80665 m/s^2)"},
      {"force0_n", "amplitude of the force on the main body (the base stands still)"},
      {"f0_hz", "excitation frequency f0"},
      {"m_m", "main mass"},
      {"k_lin", "linear stiffness of the main spring (negative: pre-buckled)"},
      {"k3", "cubic stiffness of the main spring"},
      {"c0_m", "linear damping of the main mass"},
      {"c2_m", "quadratic-in-displacement damping of the main mass (c2 y^2 y')"},
      {"fric_m_fs", "static (peak) Stribeck friction force on the main mass"},
      {"fric_m_fc", "kinetic (Coulomb) friction force on the main mass"},
      {"fric_m_vsp", "Stribeck peak velocity of the main mass's friction"},
      {"fric_m_vt", "transition velocity (tanh) of the main mass's friction"},
      {"fric_r_vsp", "Stribeck peak velocity of the resonator's friction"},
      {"fric_r_vt", "transition velocity (tanh) of the resonator's friction"},
      {"m_r", "resonator mass"},
      {"k_r", "resonator stiffness"},
      {"c0_r", "linear damping of the resonator"},
      {"c2_r", "quadratic-in-displacement damping of the resonator"},
      {"fric_r_fs", "static (peak) Stribeck friction force on the resonator"},
      {"fric_r_fc", "kinetic (Coulomb) friction force on the resonator"}};
  auto it = kNames.find(name);
  return it == kNames.end() ? name : it->second;
}

std::vector<FixedParameter> SweepSpec::FixedParameters() const {
  std::vector<FixedParameter> out;
  auto swept = [&](const std::string& n) {
    for (const Axis& a : axes)
      if (a.name == n) return true;
    return false;
  };
  auto add = [&](const std::string& n, double v) {
    if (!swept(n)) out.push_back({n, v, UnitOf(n), LongNameOf(n)});
  };
  if (terms) {  // the drive, then every parameter of the term model and the masses
    add(terms->DriveAxis(), base.alpha);
    add("f0_hz", base.omega);
    const std::vector<std::string> names = terms->model.ParamNames();
    for (size_t k = 0; k < names.size(); ++k) add(names[k], base.theta[k]);
    out.push_back({"m_main", terms->model.m_main, "kg", "mass of the main body"});
    if (terms->model.HasResonator()) out.push_back({"m_res", terms->model.m_res, "kg", "mass of the resonator"});
    const bool friction = std::any_of(terms->model.terms.begin(), terms->model.terms.end(),
                                      [](const TermDef* t) { return t->kind == TermKind::kFriction; });
    if (friction) {
      out.push_back({"v_sp", terms->model.fc.v_sp, "m/s", "Stribeck peak velocity of the friction terms"});
      out.push_back({"v_t", terms->model.fc.v_t, "m/s", "transition velocity (tanh) of the friction terms"});
    }
    return out;
  }
  if (model == ModelKind::kDimensional) {
    add("a0_mm", base.alpha);
    add("f0_hz", base.omega);
    const DimensionalParams& d = dimensional.params;
    add("m_m", d.m_m), add("k_lin", d.k_lin), add("k3", d.k3), add("c0_m", d.c0_m);
    add("c2_m", d.c2_m), add("fric_m_fs", d.fric_m.f_s), add("fric_m_fc", d.fric_m.f_c);
    add("fric_m_vsp", d.fric_m.v_sp), add("fric_m_vt", d.fric_m.v_t);
    if (d.has_resonator) {
      add("m_r", d.m_r), add("k_r", d.k_r), add("c0_r", d.c0_r), add("c2_r", d.c2_r);
      add("fric_r_fs", d.fric_r.f_s), add("fric_r_fc", d.fric_r.f_c);
      add("fric_r_vsp", d.fric_r.v_sp), add("fric_r_vt", d.fric_r.v_t);
    }
    return out;
  }
  const bool resonator = model == ModelKind::kSeries ? series.resonators : HasResonator(model);
  const bool bistable = model == ModelKind::kSeries ? series.bistable : IsBistable(model);
  auto overridden = [&](const std::string& n) {  // a series cell's own value: the base one is not the model's
    for (const auto& cell : series.overrides)
      for (const auto& [k, v] : cell)
        if (k == n) return true;
    return false;
  };
  for (const std::string n : {"alpha", "omega", "eta", "eta_r", "lambda", "phi", "eps"}) {
    if ((n == "eta_r" || n == "lambda" || n == "phi") && !resonator) continue;
    if (n == "eps" && !bistable) continue;
    if (model == ModelKind::kSeries && overridden(n)) continue;
    add(n, *ParamSlot(const_cast<PointSpec&>(base), n));
  }
  return out;
}

long SweepSpec::points() const {
  // Saturates instead of wrapping (parsing bounds the product far below; this guards hand-built specs).
  long n = 1;
  for (const Axis& a : axes)
    if (__builtin_mul_overflow(n, static_cast<long>(a.values.size()), &n)) return std::numeric_limits<long>::max();
  return n;
}

std::vector<int> SweepSpec::AxisIndices(long index) const {
  std::vector<int> idx(axes.size());
  for (int k = static_cast<int>(axes.size()) - 1; k >= 0; --k) {
    const long n = static_cast<long>(axes[k].values.size());
    idx[k] = static_cast<int>(index % n);
    index /= n;
  }
  return idx;
}

int SweepSpec::ic_count() const { return KindOf(*this).Slots(*this); }

PointSpec SweepSpec::PointAt(long index, int ic) const { return KindOf(*this).PointAt(*this, index, ic); }

namespace {

// Coordinate d of the k-th point (k ≥ 1) of the Halton sequence (radical inverse in the d-th prime
// base), shifted by a seed-derived offset modulo 1 (Cranley–Patterson rotation): a low-discrepancy,
// reproducible sample in [0, 1), the same bits on every machine.
double ShiftedHalton(uint64_t k, int d, uint64_t seed) {
  static const int kPrimes[] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31};
  const uint64_t base = static_cast<uint64_t>(kPrimes[d]);
  double f = 1.0, r = 0.0;
  for (uint64_t i = k; i > 0; i /= base) {
    f /= static_cast<double>(base);
    r += f * static_cast<double>(i % base);
  }
  uint64_t z = seed + 0x9E3779B97F4A7C15ull * static_cast<uint64_t>(d + 1);  // splitmix64
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  const double shift = static_cast<double>(z >> 11) * 0x1.0p-53;
  const double u = r + shift;
  return u >= 1.0 ? u - 1.0 : u;
}

}  // namespace

// Sample `k` of a robustness map: each toleranced parameter times 1 + tol (2u − 1), then the start moved
// to a point of the disc of radius ic_radius about it (uniform in area), one Halton coordinate each.
void ApplyRobustnessSample(const RobustnessConfig& r, int k, PointSpec* p) {
  int d = 0;
  for (const std::string& name : kToleranceKeys) {
    auto it = r.tolerance.find(name);
    if (it == r.tolerance.end()) continue;
    const double u = ShiftedHalton(static_cast<uint64_t>(k) + 1, d++, r.seed);
    *ParamSlot(*p, name) *= 1.0 + it->second * (2.0 * u - 1.0);
  }
  if (r.ic_radius > 0) {
    const double ua = ShiftedHalton(static_cast<uint64_t>(k) + 1, d++, r.seed);
    const double ub = ShiftedHalton(static_cast<uint64_t>(k) + 1, d++, r.seed);
    const auto start = InitialState(*p);
    const double rad = r.ic_radius * std::sqrt(ua), th = 2.0 * M_PI * ub;
    p->ic = start;
    p->ic[0] += rad * std::cos(th);
    p->ic[1] += rad * std::sin(th);
    p->ic_given = true;
  }
}

std::string SweepSpec::CanonicalText() const {
  std::ostringstream os;
  os << "numerics=" << kNumericsVersion << "\nmodel=" << ModelLabel() << "\n" << ModelConfigText();
  for (const std::string& name : kParamKeys)
    os << name << "=" << G17(*ParamSlot(const_cast<PointSpec&>(base), name)) << "\n";
  for (const Axis& a : axes) {
    os << "axis." << a.name << "=";
    for (double v : a.values) os << G17(v) << ",";
    os << "\n";
  }
  const IntegrationSettings& in = base.integration;
  os << "integrator=" << IntegratorName(in.integrator) << "\ndt=" << G17(in.dt) << "\nt_end=" << G17(in.t_end)
     << "\nt_keep=" << G17(in.t_keep) << "\nrtol=" << G17(in.rtol) << "\natol=" << G17(in.atol) << "\n";
  // Only when settled, so the ids of the paper's mode stay what they were.
  if (in.labels == LabelMode::kSettled)
    os << "labels=settled\nsettle_window=" << G17(in.settle_window) << "\nsettle_min_strobes=" << in.settle_min_strobes
       << "\nsettle_confirm=" << G17(in.settle_confirm) << "\nsettle_cap=" << G17(in.settle_cap)
       << "\nquasi_lle=" << G17(base.metrics.quasi_lle) << "\nchaos_01_min=" << G17(base.metrics.chaos_01_min) << "\n";
  const MetricSettings& m = base.metrics;
  os << "renorm_every=" << m.renorm_every << "\nchaos_threshold=" << G17(m.chaos_threshold)
     << "\nsample_every=" << m.sample_every << "\nperiod_tol=" << G17(m.period_tol) << "\nmax_period=" << m.max_period
     << "\nhd_level=" << G17(m.hd_level) << "\nhd_top_k=" << m.hd_top_k << "\nrosenstein=" << m.rosenstein << "\n";
  // Only when set, so the ids of sweeps without a section stay what they were.
  if (m.poincare_points > 0 || m.poincare_phase != 0)
    os << "poincare_points=" << m.poincare_points << "\npoincare_phase=" << G17(m.poincare_phase) << "\n";
  for (const auto& ic : initial_states)
    os << "ic=" << G17(ic[0]) << "," << G17(ic[1]) << "," << G17(ic[2]) << "," << G17(ic[3]) << "\n";
  os << KindOf(*this).CanonicalLine(*this);
  os << "metrics=";
  for (const auto& s : metrics) os << s << ",";
  os << "\n";
  return os.str();
}

const char* RefineCriterionName(RefineCriterion c) { return kRefineCriteria[static_cast<int>(c)].c_str(); }

std::string SweepSpec::ModelLabel() const { return terms ? "terms" : ModelName(model); }

double* SweepSpec::Slot(PointSpec& p, const std::string& name) const {
  if (terms) {
    const int k = terms->model.IndexOf(name);
    if (k >= 0) return static_cast<size_t>(k) < p.theta.size() ? &p.theta[k] : nullptr;
    if (name == "acc0_g" || name == "force0_n") return &p.alpha;
  }
  return ParamSlot(p, name);
}

std::string SweepSpec::UnitOf(const std::string& name) const {
  if (terms) {
    const int k = terms->model.IndexOf(name);
    if (k >= 0) return terms->model.ParamUnits()[k];
  }
  return AxisUnit(name);
}

std::string SweepSpec::LongNameOf(const std::string& name) const {
  if (terms) {
    const int k = terms->model.IndexOf(name);
    if (k >= 0) {
      const size_t dot = name.rfind('.');
      auto t = FindTerm(name.substr(0, dot));
      return "parameter " + name.substr(dot + 1) + " of " + name.substr(0, dot) +
             (t.ok() ? " (" + (*t)->meaning + ")" : "");
    }
  }
  return AxisLongName(name);
}

RigDrive SweepSpec::DriveAt(const PointSpec& p) const {
  const double omega = 2.0 * M_PI * p.omega;
  if (terms && terms->drive == TermsConfig::Drive::kAcceleration)
    return {p.alpha * kStandardGravity / (omega * omega), p.omega, omega};
  if (terms && terms->drive == TermsConfig::Drive::kForce)  // the free main mass's displacement under F0: the scale
    return {p.alpha / (terms->model.m_main * omega * omega), p.omega, omega, p.alpha};
  return {p.alpha * 1e-3, p.omega, omega};
}

std::string SweepSpec::ItemKey(long index, int ic) const { return KindOf(*this).ItemKey(*this, index, ic); }

// The cells of a series point: [params] and axis values for all, then each cell's overrides.
std::vector<SeriesCell> SweepSpec::SeriesCells(const PointSpec& p) const {
  SeriesCell base{series.bistable, p.params.eps, p.params.eta,   series.resonators,
                  p.params.eta_r,  p.params.phi, p.params.lambda};
  std::vector<SeriesCell> cells(series.cells, base);
  for (size_t i = 0; i < series.overrides.size() && i < cells.size(); ++i) {
    for (const auto& [k, v] : series.overrides[i]) {
      if (k == "eps") cells[i].eps = v;
      if (k == "eta") cells[i].eta = v;
      if (k == "eta_r") cells[i].eta_r = v;
      if (k == "phi") cells[i].phi = v;
      if (k == "lambda") cells[i].lambda = v;
    }
  }
  return cells;
}

std::string SweepSpec::Id() const {
  return (canonical_hash.empty() ? ContentHashHex(CanonicalText()) : canonical_hash).substr(0, 12);
}

}  // namespace bistable
