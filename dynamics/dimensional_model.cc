#include "dynamics/dimensional_model.h"

#include <algorithm>
#include <string>

#include <Eigen/Eigenvalues>

#include "base/validate.h"

namespace bistable {

BaseMotion SineBase(double a0_m, double f0_hz) {
  const double w = 2.0 * M_PI * f0_hz;
  return [a0_m, w](double t) {
    const double s = std::sin(w * t), c = std::cos(w * t);
    return BaseKinematics{a0_m * s, a0_m * w * c, -a0_m * w * w * s, -a0_m * w * w * w * c};
  };
}

BaseMotion ChirpBase(double a0_m, double f_start_hz, double f_end_hz, double duration_s) {
  const double k = (f_end_hz - f_start_hz) / duration_s;  // Hz/s
  return [=](double t) {
    const double ph = 2.0 * M_PI * (f_start_hz * t + 0.5 * k * t * t);
    const double w = 2.0 * M_PI * (f_start_hz + k * t), dw = 2.0 * M_PI * k;
    const double s = std::sin(ph), c = std::cos(ph);
    // x = A sin φ, φ' = w, φ'' = dw.
    return BaseKinematics{a0_m * s, a0_m * w * c, a0_m * (dw * c - w * w * s),
                          a0_m * (-dw * w * s - 2.0 * w * dw * s - w * w * w * c)};
  };
}

DimensionalParams DimensionalParams::BistableTable2() { return DimensionalParams{}; }

DimensionalParams DimensionalParams::LinearTable2() {
  DimensionalParams p;
  p.k_lin = 484.9;
  p.k3 = 0;
  p.c0_m = 3.2;
  p.c2_m = 8.9e3;
  p.fric_m = Stribeck{1.2, 0.65};
  return p;
}

namespace {

// Mass, damping and friction of one body; fields are named with the body's suffix ("_m" main, "_r" resonator).
Status CheckBody(const std::string& sfx, double mass, double c0, double c2, const Stribeck& f) {
  BISTABLE_RETURN_IF_ERROR(CheckPositive("m" + sfx, mass));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("c0" + sfx, c0));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("c2" + sfx, c2));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("fs" + sfx, f.f_s));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("fc" + sfx, f.f_c));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("v_sp" + sfx, f.v_sp));
  return CheckPositive("v_t" + sfx, f.v_t);
}

}  // namespace

Status ValidateDimensionalParams(const DimensionalParams& p) {
  BISTABLE_RETURN_IF_ERROR(CheckBody("_m", p.m_m, p.c0_m, p.c2_m, p.fric_m));
  BISTABLE_RETURN_IF_ERROR(CheckFinite("k_lin", p.k_lin));
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("k3", p.k3));
  if (p.k_lin < 0 && p.k3 <= 0) return Violates("k3", p.k3, "> 0 when k_lin < 0 (bistable beam)");
  if (p.has_resonator) {
    BISTABLE_RETURN_IF_ERROR(CheckBody("_r", p.m_r, p.c0_r, p.c2_r, p.fric_r));
    BISTABLE_RETURN_IF_ERROR(CheckPositive("k_r", p.k_r));
  }
  return Status::Ok();
}

double DimensionalModel::ResonatorForce(const State& x) const {
  if (!p_.has_resonator) return 0.0;
  const double z = x[2], zd = x[3];
  return p_.k_r * z + (p_.c0_r + p_.c2_r * z * z) * zd + p_.fric_r.Force(zd);
}

double DimensionalModel::MainForce(const State& x) const {
  const double y = x[0], yd = x[1];
  return -(p_.k_lin * y + p_.k3 * y * y * y) - (p_.c0_m + p_.c2_m * y * y) * yd - p_.fric_m.Force(yd) +
         ResonatorForce(x);
}

void DimensionalModel::operator()(double t, const State& x, State& dx) const {
  const BaseKinematics b = base_(t);
  const double fm = MainForce(x) / p_.m_m;
  dx[0] = x[1];
  dx[1] = fm - b.a;
  if (p_.has_resonator) {
    dx[2] = x[3];
    dx[3] = -ResonatorForce(x) / p_.m_r - fm;
  } else {
    dx[2] = dx[3] = 0;
  }
}

void DimensionalModel::Jac(double t, const State& x, Jacobian& J, State& dfdt) const {
  const double y = x[0], yd = x[1], z = x[2], zd = x[3];
  const double dFdy = -(p_.k_lin + 3 * p_.k3 * y * y) - 2 * p_.c2_m * y * yd;
  const double dFdyd = -(p_.c0_m + p_.c2_m * y * y) - p_.fric_m.Slope(yd);
  double dGdz = 0, dGdzd = 0;
  if (p_.has_resonator) {
    dGdz = p_.k_r + 2 * p_.c2_r * z * zd;
    dGdzd = p_.c0_r + p_.c2_r * z * z + p_.fric_r.Slope(zd);
  }
  J.setZero();
  J(0, 1) = 1;
  J(1, 0) = dFdy / p_.m_m;
  J(1, 1) = dFdyd / p_.m_m;
  J(1, 2) = dGdz / p_.m_m;
  J(1, 3) = dGdzd / p_.m_m;
  if (p_.has_resonator) {
    J(2, 3) = 1;
    J(3, 0) = -J(1, 0);
    J(3, 1) = -J(1, 1);
    J(3, 2) = -dGdz / p_.m_r - J(1, 2);
    J(3, 3) = -dGdzd / p_.m_r - J(1, 3);
  }
  dfdt.setZero();
  dfdt[1] = -base_(t).j;
}

int Rk4Substeps(const DimensionalParams& p, double dt) {
  DimensionalModel m(p, SineBase(0.0, 0.0));
  DimensionalModel::State rest = DimensionalModel::State::Zero();
  if (p.k_lin < 0 && p.k3 > 0) rest[0] = std::sqrt(-p.k_lin / p.k3);  // in the positive well
  DimensionalModel::Jacobian J;
  DimensionalModel::State dfdt;
  m.Jac(0.0, rest, J, dfdt);
  const double rho = Eigen::EigenSolver<DimensionalModel::Jacobian>(J, false).eigenvalues().cwiseAbs().maxCoeff();
  const double h_max = 2.0 / rho;
  // Capped where an int still holds it: the spec refuses a rig past limits::kMaxRk4Substeps before this runs.
  return std::max(1, static_cast<int>(std::min(std::ceil(dt / h_max), 1e6)));
}

}  // namespace bistable
