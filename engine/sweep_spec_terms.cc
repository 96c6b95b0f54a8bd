// model = "terms" (issue 42): the [terms] table of a sweep spec, a term model's axes, canonical lines and
// covariance samples. The reader of the rest of a spec is sweep_spec_read.cc.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include <Eigen/Dense>

#include "base/limits.h"
#include "base/validate.h"
#include "engine/spec_toml.h"
#include "engine/sweep_spec_keys.h"

namespace bistable::spec_keys {
namespace {

const std::vector<std::string> kTermsKeys = {"list", "theta", "m_main",     "m_res",  "v_sp",
                                             "v_t",  "drive", "covariance", "origin", "report"};
// The most parameters a term model may have (every force term of both bodies has at most 2).
constexpr size_t kMaxTermParams = 64;

std::string G17(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

}  // namespace

// splitmix64: a counter-based generator, the same numbers on every machine.
uint64_t Mix(uint64_t z) {
  z += 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}
// A uniform number in (0, 1) for (seed, sample, coordinate).
double Uniform(uint64_t seed, uint64_t k, uint64_t d) {
  const uint64_t z = Mix(Mix(Mix(seed) ^ k) ^ (d + 0x51ED27ull));
  return (static_cast<double>(z >> 11) + 0.5) * 0x1.0p-53;
}

std::vector<std::string> TermAxisNames(const SweepSpec& spec) {
  std::vector<std::string> out = {spec.terms->DriveAxis(), "f0_hz"};
  for (const std::string& n : spec.terms->model.ParamNames()) out.push_back(n);
  return out;
}

std::vector<std::string> TermParamKeys(const SweepSpec& spec) { return {spec.terms->DriveAxis(), "f0_hz"}; }

Status ReadTerms(const toml::table& root, SweepSpec& spec) {
  const toml::node* n = root.get("terms");
  if (!spec.terms) {
    if (n) return Status::InvalidArgument("terms", "a [terms] table needs model = \"terms\"");
    return Status::Ok();
  }
  if (root.get("dimensional"))
    return Status::InvalidArgument("dimensional", "model = \"terms\" takes its model from [terms], not [dimensional]");
  const toml::table* t = n ? n->as_table() : nullptr;
  if (!t)
    return Status::InvalidArgument("terms",
                                   "model = \"terms\" needs a [terms] table: list, theta, m_main (and m_res, "
                                   "v_sp, v_t, drive, covariance), or report = \"DIR/report.json\"");
  BISTABLE_RETURN_IF_ERROR(CheckKeys(*t, "terms", kTermsKeys));
  if (t->get("report"))
    return Status::InvalidArgument(
        "terms.report",
        "terms.report names a file, which a coordinator or a worker must not read: `bistable run` and "
        "`bistable submit` read the report and send its model inline (terms.list, terms.theta, ...)");
  TermsConfig& c = *spec.terms;
  const toml::node* list = t->get("list");
  const toml::array* a = list ? list->as_array() : nullptr;
  if (!a || a->empty())
    return Status::InvalidArgument("terms.list",
                                   "terms.list must be a non-empty array of term ids, e.g. "
                                   "[\"main.linear\", \"main.stiffness_y3\", \"main.viscous\"]");
  for (size_t i = 0; i < a->size(); ++i) {
    auto id = String((*a)[i], "terms.list[" + std::to_string(i) + "]");
    if (!id.ok()) return id.status();
    auto term = FindTerm(*id);
    if (!term.ok()) return Status::InvalidArgument("terms.list[" + std::to_string(i) + "]", term.status().message());
    if (std::find(c.model.terms.begin(), c.model.terms.end(), *term) != c.model.terms.end())
      return Status::InvalidArgument("terms.list[" + std::to_string(i) + "]", "term " + *id + " is listed twice");
    c.model.terms.push_back(*term);
  }
  const size_t np = static_cast<size_t>(c.model.NumParams());
  if (np > kMaxTermParams) return Violates("terms.list", static_cast<double>(np), "parameters <= 64");
  const toml::node* th = t->get("theta");
  if (!th) return Status::InvalidArgument("terms.theta", "terms.theta is required: " + std::to_string(np) + " values");
  auto theta = NumberArray(*th, "terms.theta");
  if (!theta.ok()) return theta.status();
  if (theta->size() != np)
    return Status::InvalidArgument("terms.theta", "terms.theta has " + std::to_string(theta->size()) +
                                                      " values; the terms have " + std::to_string(np) + " parameters");
  for (size_t k = 0; k < np; ++k)
    if (!std::isfinite((*theta)[k]))
      return Violates("terms.theta[" + std::to_string(k) + "]", (*theta)[k],
                      "finite (" + c.model.ParamNames()[k] + ")");
  c.model.theta = *theta;
  BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "m_main", "terms.m_main", &c.model.m_main));
  BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "m_res", "terms.m_res", &c.model.m_res));
  BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "v_sp", "terms.v_sp", &c.model.fc.v_sp));
  BISTABLE_RETURN_IF_ERROR(ReadNumber(*t, "v_t", "terms.v_t", &c.model.fc.v_t));
  if (Status s = ValidateTermModel(c.model); !s.ok()) return Status::InvalidArgument("terms." + s.field(), s.message());
  if (const toml::node* d = t->get("drive")) {
    auto s = String(*d, "terms.drive");
    if (!s.ok()) return s.status();
    if (*s != "displacement" && *s != "acceleration" && *s != "force")
      return UnknownValue("terms.drive", *s, {"displacement", "acceleration", "force"});
    c.drive = *s == "acceleration" ? TermsConfig::Drive::kAcceleration
              : *s == "force"      ? TermsConfig::Drive::kForce
                                   : TermsConfig::Drive::kDisplacement;
  }
  if (const toml::node* o = t->get("origin")) {
    auto s = String(*o, "terms.origin");
    if (!s.ok()) return s.status();
    BISTABLE_RETURN_IF_ERROR(CheckPlainText("terms.origin", *s, limits::kMaxNameBytes));
    c.origin = *s;
  }
  if (const toml::node* cv = t->get("covariance")) {
    auto v = NumberArray(*cv, "terms.covariance");
    if (!v.ok()) return v.status();
    if (v->size() != np * np)
      return Status::InvalidArgument("terms.covariance", "terms.covariance has " + std::to_string(v->size()) +
                                                             " values; it is the " + std::to_string(np) + " x " +
                                                             std::to_string(np) + " matrix, row by row");
    for (size_t i = 0; i < np; ++i) {
      if (!((*v)[i * np + i] >= 0))
        return Violates("terms.covariance[" + std::to_string(i * np + i) + "]", (*v)[i * np + i],
                        ">= 0 (a variance on the diagonal)");
      for (size_t j = 0; j < np; ++j)
        if (!std::isfinite((*v)[i * np + j]) || (*v)[i * np + j] != (*v)[j * np + i])
          return Status::InvalidArgument("terms.covariance", "terms.covariance must be finite and symmetric (entry " +
                                                                 std::to_string(i) + ", " + std::to_string(j) + ")");
    }
    c.covariance = *v;
  }
  // The points: SI, the rig's metrics (a proxy cell classifies the motion), RK4 in lanes.
  spec.base.model = TermWell(c.model, c.model.theta.data()) > 0 ? ModelKind::kStandalone : ModelKind::kLinear;
  IntegrationSettings& in = spec.base.integration;
  in.integrator = IntegratorKind::kRk4;
  in.t_end = 20.0;
  in.t_keep = 10.0;
  in.dt = 0.001;
  spec.base.alpha = c.drive == TermsConfig::Drive::kAcceleration ? 0.1 : 1.0;  // 0.1 g, 1 mm or 1 N
  spec.base.omega = 5.0;
  spec.base.theta = c.model.theta;
  return Status::Ok();
}

Status CheckTerms(const SweepSpec& spec) {
  if (!spec.terms) return Status::Ok();
  if (spec.base.integration.integrator != IntegratorKind::kRk4)
    return Status::InvalidArgument("integration.integrator",
                                   "a term model integrates by RK4 in lanes (integrator = \"rk4\"): its friction "
                                   "basis has no curvature for the Rosenbrock tangent, and no adaptive path");
  if (spec.robustness.enabled() && !spec.robustness.covariance)
    return Status::InvalidArgument("robustness.covariance",
                                   "a term model's robustness map draws its parameters from the fit's covariance: set "
                                   "robustness.covariance = true (and give terms.covariance)");
  if (const int n = spec.TermSubsteps(); n > limits::kMaxRk4Substeps)
    return Status::InvalidArgument(
        "terms.theta", "the model needs " + std::to_string(n) +
                           " RK4 steps per dt = " + FormatNumber(spec.base.integration.dt) +
                           " s at its stiffest parameters (limit " + std::to_string(limits::kMaxRk4Substeps) +
                           "): a friction transition v_t or a stiffness that fast is outside what a sweep integrates");
  if (spec.robustness.covariance && spec.terms->covariance.empty())
    return Status::InvalidArgument("terms.covariance",
                                   "robustness.covariance = true needs terms.covariance (a report's covariance is "
                                   "copied there by bistable run)");
  return Status::Ok();
}

std::string TermsText(const TermsConfig& c) {
  std::string s = "terms=";
  for (const TermDef* t : c.model.terms) s += t->id + ",";
  s += "\ntheta=";
  for (double v : c.model.theta) s += G17(v) + ",";
  s += "\nm_main=" + G17(c.model.m_main) + "\nm_res=" + G17(c.model.m_res) + "\nv_sp=" + G17(c.model.fc.v_sp) +
       "\nv_t=" + G17(c.model.fc.v_t) + "\ndrive=" + c.DriveAxis() + "\n";
  if (!c.covariance.empty()) {
    s += "covariance=";
    for (double v : c.covariance) s += G17(v) + ",";
    s += "\n";
  }
  return s;
}

}  // namespace bistable::spec_keys

namespace bistable {

// The stiffest parameter set the sweep holds — the nominal one, each swept parameter at its axis's ends, and with
// covariance samples each parameter at ±4σ — by the rig's rule (TermRk4Substeps).
int SweepSpec::TermSubsteps() const {
  if (!terms) return 1;
  const TermModel& m = terms->model;
  const double dt = base.integration.dt;
  int n = TermRk4Substeps(m, m.theta.data(), dt);
  auto with = [&](int k, double v) {
    std::vector<double> th = m.theta;
    th[k] = v;
    n = std::max(n, TermRk4Substeps(m, th.data(), dt));
  };
  for (const Axis& a : axes)
    if (const int k = m.IndexOf(a.name); k >= 0) with(k, a.values.front()), with(k, a.values.back());
  if (robustness.covariance && !terms->covariance.empty()) {
    const int np = m.NumParams();
    for (int k = 0; k < np; ++k) {
      const double sd = std::sqrt(std::max(0.0, terms->covariance[k * np + k]));
      with(k, m.theta[k] - 4 * sd), with(k, m.theta[k] + 4 * sd);
    }
  }
  return n;
}

void ApplyCovarianceSample(const TermsConfig& t, const RobustnessConfig& r, int k, PointSpec* p) {
  const int n = t.model.NumParams();
  if (static_cast<int>(t.covariance.size()) == n * n && static_cast<int>(p->theta.size()) == n) {
    const Eigen::MatrixXd cov = Eigen::Map<const Eigen::MatrixXd>(t.covariance.data(), n, n);  // symmetric
    Eigen::MatrixXd l;
    Eigen::LLT<Eigen::MatrixXd> llt(cov);
    if (llt.info() == Eigen::Success) {
      l = llt.matrixL();
    } else {  // semi-definite (a parameter the records did not determine): V √max(Λ, 0)
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(cov);
      l = es.eigenvectors() * es.eigenvalues().cwiseMax(0.0).cwiseSqrt().asDiagonal();
    }
    Eigen::VectorXd z(n);
    for (int d = 0; d < n; d += 2) {  // Box–Muller: two normals per pair of uniforms
      const double u1 = spec_keys::Uniform(r.seed, static_cast<uint64_t>(k), static_cast<uint64_t>(d));
      const double u2 = spec_keys::Uniform(r.seed, static_cast<uint64_t>(k), static_cast<uint64_t>(d + 1));
      const double rad = std::sqrt(-2.0 * std::log(u1)), a = 2.0 * M_PI * u2;
      z[d] = rad * std::cos(a);
      if (d + 1 < n) z[d + 1] = rad * std::sin(a);
    }
    const Eigen::VectorXd dx = l * z;
    for (int i = 0; i < n; ++i) p->theta[i] += dx[i];
  }
  if (r.ic_radius > 0) {  // the start disc, in (y, y') [m, m/s], as ApplyRobustnessSample's
    if (!p->ic_given) p->ic = {TermWell(t.model, p->theta.data()), 0, 0, 0};  // the lanes' default start
    const double ua = spec_keys::Uniform(r.seed, static_cast<uint64_t>(k), 1000);
    const double ub = spec_keys::Uniform(r.seed, static_cast<uint64_t>(k), 1001);
    const double rad = r.ic_radius * std::sqrt(ua), th = 2.0 * M_PI * ub;
    p->ic[0] += rad * std::cos(th);
    p->ic[1] += rad * std::sin(th);
    p->ic_given = true;
  }
}

}  // namespace bistable
