#include "dynamics/term_model.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "base/validate.h"

namespace bistable {

int TermLaneCoefficients(TermKind kind) {
  switch (kind) {
    case TermKind::kStiffness2:
    case TermKind::kStiffness3:
    case TermKind::kStiffness5:
    case TermKind::kDamping2:
    case TermKind::kDampingV3:
    case TermKind::kDrag:
      return 2;
    case TermKind::kFriction:
      return 4;
    default:
      return 1;
  }
}

void TermLaneCoefficientValues(TermKind kind, const double* theta, const TermLaneFriction& fric, double* k) {
  switch (kind) {
    case TermKind::kStiffness2:
    case TermKind::kDamping2:
    case TermKind::kDrag:
      k[0] = theta[0], k[1] = 2.0 * theta[0];
      break;
    case TermKind::kStiffness3:
    case TermKind::kDampingV3:
      k[0] = theta[0], k[1] = 3.0 * theta[0];
      break;
    case TermKind::kStiffness5:
      k[0] = theta[0], k[1] = 5.0 * theta[0];
      break;
    case TermKind::kFriction: {
      const double a_vsp = (theta[0] - theta[1] * fric.tanh_sp) / fric.v_sp;
      k[0] = a_vsp, k[1] = 2.0 * a_vsp, k[2] = theta[1], k[3] = theta[1] / fric.v_t;
      break;
    }
    case TermKind::kLinear:
    case TermKind::kViscous:
    case TermKind::kBias:
      k[0] = theta[0];
      break;
    default:
      k[0] = 0.0;  // piezo and output terms: not forces here (refused by ValidateTermModel)
      break;
  }
}

bool TermModel::HasResonator() const {
  return std::any_of(terms.begin(), terms.end(), [](const TermDef* t) { return t->body == Body::kResonator; });
}

int TermModel::NumParams() const {
  int n = 0;
  for (const TermDef* t : terms) n += static_cast<int>(t->params.size());
  return n;
}

std::vector<std::string> TermModel::ParamNames() const {
  std::vector<std::string> out;
  for (const TermDef* t : terms)
    for (const TermParam& p : t->params) out.push_back(t->id + "." + p.name);
  return out;
}

std::vector<std::string> TermModel::ParamUnits() const {
  std::vector<std::string> out;
  for (const TermDef* t : terms)
    for (const TermParam& p : t->params) out.push_back(p.unit);
  return out;
}

int TermModel::IndexOf(const std::string& name) const {
  const std::vector<std::string> names = ParamNames();
  auto it = std::find(names.begin(), names.end(), name);
  return it == names.end() ? -1 : static_cast<int>(it - names.begin());
}

StatusOr<TermModel> TermModel::FromCell(ModelKind kind, const NondimParams& p) {
  if (!IsCellModel(kind))
    return Status::InvalidArgument("model", std::string(ModelName(kind)) +
                                                " is not a cell: a series chain has N bodies in a row (a term model "
                                                "has two), the dimensional rig is FromDimensional");
  TermModel m;
  m.m_main = 1.0;
  std::vector<std::pair<const char*, double>> terms = {{"main.linear", IsBistable(kind) ? -1.0 : 1.0}};
  if (IsBistable(kind)) terms.push_back({"main.stiffness_y3", p.eps});
  terms.push_back({"main.viscous", p.eta});
  if (::bistable::HasResonator(kind)) {
    m.m_res = p.phi;
    terms.push_back({"res.linear", p.phi * p.lambda * p.lambda});
    terms.push_back({"res.viscous", p.phi * p.eta_r});
  }
  for (const auto& [id, value] : terms) {
    auto t = FindTerm(id);
    if (!t.ok()) return t.status();
    m.terms.push_back(*t);
    m.theta.push_back(value);
  }
  return m;
}

StatusOr<TermModel> TermModel::FromDimensional(const DimensionalParams& p) {
  if (p.has_resonator && (p.fric_r.v_sp != p.fric_m.v_sp || p.fric_r.v_t != p.fric_m.v_t))
    return Status::InvalidArgument("friction",
                                   "the two bodies' friction laws have different v_sp or v_t; a term model has one "
                                   "pair (FrictionConstants)");
  TermModel m;
  m.m_main = p.m_m;
  m.m_res = p.has_resonator ? p.m_r : 0.0;
  m.fc.v_sp = p.fric_m.v_sp, m.fc.v_t = p.fric_m.v_t;
  auto add = [&m](const std::string& id, std::initializer_list<double> values) -> Status {
    auto t = FindTerm(id);
    if (!t.ok()) return t.status();
    m.terms.push_back(*t);
    m.theta.insert(m.theta.end(), values);
    return Status::Ok();
  };
  BISTABLE_RETURN_IF_ERROR(add("main.linear", {p.k_lin}));
  BISTABLE_RETURN_IF_ERROR(add("main.stiffness_y3", {p.k3}));
  BISTABLE_RETURN_IF_ERROR(add("main.viscous", {p.c0_m}));
  BISTABLE_RETURN_IF_ERROR(add("main.damping_y2", {p.c2_m}));
  BISTABLE_RETURN_IF_ERROR(add("main.friction", {p.fric_m.f_s, p.fric_m.f_c}));
  if (p.has_resonator) {
    BISTABLE_RETURN_IF_ERROR(add("res.linear", {p.k_r}));
    BISTABLE_RETURN_IF_ERROR(add("res.viscous", {p.c0_r}));
    BISTABLE_RETURN_IF_ERROR(add("res.damping_z2", {p.c2_r}));
    BISTABLE_RETURN_IF_ERROR(add("res.friction", {p.fric_r.f_s, p.fric_r.f_c}));
  }
  return m;
}

Status ValidateTermModel(const TermModel& m) {
  if (m.terms.empty()) return Status::InvalidArgument("terms", "a term model needs at least one term");
  for (const TermDef* t : m.terms)
    if (!t || !t->IsForce())
      return Status::InvalidArgument("terms", "term '" + (t ? t->id : std::string("null")) +
                                                  "' is not a force of the main body or the resonator; a swept "
                                                  "term model has forces only (no piezo, no output terms)");
  if (static_cast<int>(m.theta.size()) != m.NumParams())
    return Status::InvalidArgument("theta", "theta has " + std::to_string(m.theta.size()) + " values; the terms have " +
                                                std::to_string(m.NumParams()) + " parameters");
  const std::vector<std::string> names = m.ParamNames();
  for (size_t k = 0; k < m.theta.size(); ++k) BISTABLE_RETURN_IF_ERROR(CheckFinite(names[k], m.theta[k]));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("m_main", m.m_main));
  if (m.HasResonator()) BISTABLE_RETURN_IF_ERROR(CheckPositive("m_res", m.m_res));
  if (!(m.fc.v_sp > 0 && std::isfinite(m.fc.v_sp))) return Violates("friction.v_sp", m.fc.v_sp, "> 0 and finite");
  if (!(m.fc.v_t > 0 && std::isfinite(m.fc.v_t))) return Violates("friction.v_t", m.fc.v_t, "> 0 and finite");
  return Status::Ok();
}

void TermForce(const TermModel& m, Body body, const double* th, double q, double v, double* f, double* fq, double* fv) {
  const StribeckBasis fb = FrictionBasis(m.fc);
  double sum = 0, sq = 0, sv = 0;
  int offset = 0;
  for (const TermDef* t : m.terms) {
    if (t->body == body) {
      double phi[kMaxTermParams], pq[kMaxTermParams], pv[kMaxTermParams];
      TermBasisSlopes<double>(*t, q, v, fb, phi, pq, pv);
      for (size_t k = 0; k < t->params.size(); ++k) {
        sum += th[offset + k] * phi[k];
        sq += th[offset + k] * pq[k];
        sv += th[offset + k] * pv[k];
      }
    }
    offset += static_cast<int>(t->params.size());
  }
  *f = sum, *fq = sq, *fv = sv;
}

std::vector<double> TermRestStates(const TermModel& m, const double* th) {
  std::vector<double> rest = {0.0};
  for (double sign : {1.0, -1.0}) {
    double q0 = 0, f0 = 0, unused;
    for (double a = 1e-6; a <= 1e3; a *= 1.2) {  // 1 µm to 1 km: rigs in m, the cells in δ-units (wells ~1)
      double f;
      TermForce(m, Body::kMain, th, sign * a, 0.0, &f, &unused, &unused);
      if (q0 != 0 && (f > 0) != (f0 > 0)) {
        double lo = q0, hi = sign * a, flo = f0;  // bisection to a relative 1e-9
        for (int i = 0; i < 60 && std::fabs(hi - lo) > 1e-9 * std::fabs(hi); ++i) {
          const double mid = 0.5 * (lo + hi);
          double fm;
          TermForce(m, Body::kMain, th, mid, 0.0, &fm, &unused, &unused);
          if ((fm > 0) == (flo > 0))
            lo = mid, flo = fm;
          else
            hi = mid;
        }
        rest.push_back(0.5 * (lo + hi));
      }
      q0 = sign * a, f0 = f;
    }
  }
  std::sort(rest.begin(), rest.end());
  return rest;
}

double TermWell(const TermModel& m, const double* th) {
  for (double q : TermRestStates(m, th)) {
    if (!(q > 0)) continue;
    double f, fq, fv;
    TermForce(m, Body::kMain, th, q, 0.0, &f, &fq, &fv);
    if (fq > 0) return q;
  }
  return 0.0;
}

int TermRk4Substeps(const TermModel& m, const double* th, double dt) {
  const std::vector<double> rest = TermRestStates(m, th);
  const bool res = m.HasResonator();
  const double inv_m = 1.0 / m.m_main, inv_r = res ? 1.0 / m.m_res : 0.0;
  double rho = 0;
  for (double y : rest) {
    double f, fy, fyd, g = 0, gz = 0, gzd = 0;
    TermForce(m, Body::kMain, th, y, 0.0, &f, &fy, &fyd);
    if (res) TermForce(m, Body::kResonator, th, 0.0, 0.0, &g, &gz, &gzd);
    Eigen::Matrix4d J = Eigen::Matrix4d::Zero();
    J(0, 1) = 1;
    J.row(1) << -fy * inv_m, -fyd * inv_m, gz * inv_m, gzd * inv_m;
    if (res) {
      J(2, 3) = 1;
      J.row(3) << fy * inv_m, fyd * inv_m, -gz * (inv_r + inv_m), -gzd * (inv_r + inv_m);
    }
    rho = std::max(rho, Eigen::EigenSolver<Eigen::Matrix4d>(J, false).eigenvalues().cwiseAbs().maxCoeff());
  }
  if (!(rho > 0) || !std::isfinite(rho)) return 1;
  const double h_max = 2.0 / rho;
  return std::max(1, static_cast<int>(std::min(std::ceil(dt / h_max), 1e6)));
}

}  // namespace bistable
