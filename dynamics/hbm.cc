#include "dynamics/hbm.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdio>
#include <tuple>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>

#include "base/limits.h"
#include "base/validate.h"
#include "dynamics/cancel.h"
#include "dynamics/dopri5.h"
#include "dynamics/nondim_system.h"
#include "dynamics/point.h"

namespace bistable {

double NextArclengthStep(int iterations, double ds, double ds_min, double ds_max) {
  if (iterations <= 3) return std::min(ds_max, ds * 1.5);
  if (iterations >= 8) return std::max(ds_min, ds * 0.7);
  return ds;
}

namespace {

double ParamOf(const HbmOptions& o, double omega, double alpha) {
  return o.param == ContinuationParam::kOmega ? omega : alpha;
}

// The options of a period-ν branch: harmonics of Ω/ν, H doubled (to at most 50) at every doubling.
HbmOptions ForPeriod(const HbmOptions& o, int nu) {
  HbmOptions ob = o;
  ob.subharmonic = nu;
  for (int d = 1; d < nu; d *= 2) ob.harmonics = std::min(limits::kMaxHbmHarmonics, 2 * ob.harmonics);
  return ob;
}

}  // namespace

Status ValidateHbmOptions(const HbmOptions& o) {
  if (!IsCellModel(o.model))
    return Status::InvalidArgument(
        "model", std::string("model = '") + ModelName(o.model) +
                     "' violates model in {standalone, coupled, linear, linear-coupled} (harmonic balance)");
  if (o.harmonics < 1 || o.harmonics > limits::kMaxHbmHarmonics)
    return Violates("harmonics", o.harmonics, "in [1, " + std::to_string(limits::kMaxHbmHarmonics) + "]");
  BISTABLE_RETURN_IF_ERROR(CheckPositive("alpha", o.alpha));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("omega", o.omega));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("from", o.from));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("to", o.to));
  if (o.from == o.to) return Violates("to", o.to, "!= from");
  BISTABLE_RETURN_IF_ERROR(CheckNonNegative("eta", o.params.eta));
  if (IsBistable(o.model)) BISTABLE_RETURN_IF_ERROR(CheckPositive("eps", o.params.eps));
  if (HasResonator(o.model)) {
    BISTABLE_RETURN_IF_ERROR(CheckNonNegative("eta_r", o.params.eta_r));
    BISTABLE_RETURN_IF_ERROR(CheckPositive("phi", o.params.phi));
    BISTABLE_RETURN_IF_ERROR(CheckPositive("lambda", o.params.lambda));
  }
  if (!(o.ds > 0 && o.ds_min > 0 && o.ds_max >= o.ds && o.ds >= o.ds_min))
    return Violates("ds", o.ds, "in [ds_min, ds_max]");
  if (o.max_points < 2) return Violates("max_points", o.max_points, ">= 2");
  if (o.switch_depth < 0 || o.switch_depth > 3) return Violates("switch_pd", o.switch_depth, "in [0, 3]");
  if (o.subharmonic != 1 && o.subharmonic != 2 && o.subharmonic != 4 && o.subharmonic != 8)
    return Violates("subharmonic", o.subharmonic, "in {1, 2, 4, 8}");
  if (o.subharmonic > o.harmonics)
    return Violates("harmonics", o.harmonics, ">= subharmonic (the forcing is harmonic subharmonic)");
  return Status::Ok();
}

HarmonicBalance::HarmonicBalance(const HbmOptions& o) : o_(o), h_(o.harmonics), nu_(std::max(1, o.subharmonic)) {
  dofs_ = HasResonator(o.model) ? 2 : 1;
  per_dof_ = 2 * h_ + 1;
  n_ = dofs_ * per_dof_;
  nt_ = std::max(64, 8 * h_);  // > 6H + 1: the cube of H harmonics is not aliased
  const bool bistable = IsBistable(o.model);
  k_lin_ = bistable ? -1.0 : 1.0;
  eps_ = bistable ? o.params.eps : 0.0;
  c_.setZero();
  k_.setZero();
  if (dofs_ == 1) {
    c_(0, 0) = o.params.eta;
    k_(0, 0) = k_lin_;
  } else {
    const double phi = o.params.phi, er = o.params.eta_r, l2 = o.params.lambda * o.params.lambda;
    c_ << o.params.eta + phi * er, -phi * er, -er, er;
    k_ << k_lin_ + phi * l2, -phi * l2, -l2, l2;
  }
}

void HarmonicBalance::Residual(const Eigen::VectorXd& z, double omega, double alpha, Eigen::VectorXd* r,
                               Eigen::MatrixXd* jac) const {
  r->setZero(n_);
  if (jac) jac->setZero(n_, n_);
  const double w = omega / nu_;  // base frequency: harmonic k is kΩ/ν
  // Linear part, harmonic by harmonic.
  for (int i = 0; i < dofs_; ++i) {
    for (int j = 0; j < dofs_; ++j) {
      (*r)[Index(i, 0)] += k_(i, j) * z[Index(j, 0)];
      if (jac) (*jac)(Index(i, 0), Index(j, 0)) += k_(i, j);
      for (int k = 1; k <= h_; ++k) {
        const int ia = Index(i, 2 * k - 1), ib = Index(i, 2 * k), ja = Index(j, 2 * k - 1), jb = Index(j, 2 * k);
        const double kw = k * w, stiff = k_(i, j) - (i == j ? kw * kw : 0.0), damp = c_(i, j) * kw;
        (*r)[ia] += stiff * z[ja] + damp * z[jb];
        (*r)[ib] += stiff * z[jb] - damp * z[ja];
        if (jac) {
          (*jac)(ia, ja) += stiff, (*jac)(ia, jb) += damp;
          (*jac)(ib, jb) += stiff, (*jac)(ib, ja) -= damp;
        }
      }
    }
    (*r)[Index(i, 2 * nu_)] -= alpha * omega * omega;  // forcing αΩ² sin Ωτ (harmonic ν) on every mass
  }
  // Cubic stiffness of the main DOF by alternating frequency–time.
  if (eps_ != 0.0) {
    Eigen::VectorXd g = Eigen::VectorXd::Zero(per_dof_);
    Eigen::MatrixXd dg = Eigen::MatrixXd::Zero(per_dof_, per_dof_);
    std::vector<double> basis(per_dof_);
    for (int s = 0; s < nt_; ++s) {
      const double th = 2.0 * M_PI * s / nt_;
      basis[0] = 1.0;
      for (int k = 1; k <= h_; ++k) basis[2 * k - 1] = std::cos(k * th), basis[2 * k] = std::sin(k * th);
      double y = 0;
      for (int m = 0; m < per_dof_; ++m) y += basis[m] * z[Index(0, m)];
      const double f = eps_ * y * y * y, df = 3.0 * eps_ * y * y;
      for (int l = 0; l < per_dof_; ++l) {
        const double proj = (l == 0 ? 1.0 : 2.0) / nt_ * basis[l];
        g[l] += proj * f;
        if (jac)
          for (int m = 0; m < per_dof_; ++m) dg(l, m) += proj * df * basis[m];
      }
    }
    for (int l = 0; l < per_dof_; ++l) {
      (*r)[Index(0, l)] += g[l];
      if (jac)
        for (int m = 0; m < per_dof_; ++m) (*jac)(Index(0, l), Index(0, m)) += dg(l, m);
    }
  }
  if (o_.zero_mean) {  // the constant terms are fixed at 0 (paper's Eq. 9 ansatz)
    for (int i = 0; i < dofs_; ++i) {
      (*r)[Index(i, 0)] = z[Index(i, 0)];
      if (jac) {
        jac->row(Index(i, 0)).setZero();
        (*jac)(Index(i, 0), Index(i, 0)) = 1.0;
      }
    }
  }
}

int HarmonicBalance::Solve(Eigen::VectorXd* z, double omega, double alpha) const {
  Eigen::VectorXd r;
  Eigen::MatrixXd j;
  for (int it = 0; it < o_.newton_max_iter; ++it) {
    Residual(*z, omega, alpha, &r, &j);
    if (!r.allFinite()) return -1;
    if (r.cwiseAbs().maxCoeff() < o_.newton_tol) return it;
    *z -= j.partialPivLu().solve(r);
  }
  Residual(*z, omega, alpha, &r, nullptr);
  return r.allFinite() && r.cwiseAbs().maxCoeff() < o_.newton_tol ? o_.newton_max_iter : -1;
}

Eigen::VectorXd HarmonicBalance::FromSamples(const std::vector<std::vector<double>>& samples) const {
  Eigen::VectorXd z = Eigen::VectorXd::Zero(n_);
  for (int i = 0; i < dofs_; ++i) {
    const auto& y = samples[i];
    const int m = static_cast<int>(y.size());
    for (int s = 0; s < m; ++s) {
      const double th = 2.0 * M_PI * s / m;
      z[Index(i, 0)] += y[s] / m;
      for (int k = 1; k <= h_; ++k) {
        z[Index(i, 2 * k - 1)] += 2.0 / m * y[s] * std::cos(k * th);
        z[Index(i, 2 * k)] += 2.0 / m * y[s] * std::sin(k * th);
      }
    }
  }
  return z;
}

std::vector<double> HarmonicBalance::MainSamples(const Eigen::VectorXd& z, int m) const {
  std::vector<double> y(m, 0.0);
  for (int s = 0; s < m; ++s) {
    const double th = 2.0 * M_PI * s / m;
    double v = z[Index(0, 0)];
    for (int k = 1; k <= h_; ++k)
      v += z[Index(0, 2 * k - 1)] * std::cos(k * th) + z[Index(0, 2 * k)] * std::sin(k * th);
    y[s] = v;
  }
  return y;
}

void HarmonicBalance::Propagate(const Eigen::VectorXd& z, double omega, int steps, Eigen::MatrixXd* phi,
                                const std::function<void(int, const Eigen::MatrixXd&)>& each) const {
  // w' = J(x(τ)) w along the harmonic-balance orbit x(τ), RK4 over one period of the orbit (2πν/Ω).
  const int d = 2 * dofs_;
  const double w = omega / nu_;
  const int total = steps * nu_;
  const double period = 2.0 * M_PI * nu_ / omega, h = period / total;
  auto y_main = [&](double t) {
    double v = z[Index(0, 0)];
    for (int k = 1; k <= h_; ++k)
      v += z[Index(0, 2 * k - 1)] * std::cos(k * w * t) + z[Index(0, 2 * k)] * std::sin(k * w * t);
    return v;
  };
  auto jac = [&](double t) {
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(d, d);
    const double y = y_main(t);
    for (int i = 0; i < dofs_; ++i) {
      a(2 * i, 2 * i + 1) = 1.0;
      for (int j = 0; j < dofs_; ++j) {
        a(2 * i + 1, 2 * j) = -k_(i, j);
        a(2 * i + 1, 2 * j + 1) = -c_(i, j);
      }
    }
    a(1, 0) -= 3.0 * eps_ * y * y;
    return a;
  };
  Eigen::MatrixXd& p = *phi;
  for (int s = 0; s < total; ++s) {
    if (each) each(s, p);
    const double t = s * h;
    const Eigen::MatrixXd j1 = jac(t), j2 = jac(t + 0.5 * h), j4 = jac(t + h);
    const Eigen::MatrixXd k1 = j1 * p, k2 = j2 * (p + 0.5 * h * k1), k3 = j2 * (p + 0.5 * h * k2),
                          k4 = j4 * (p + h * k3);
    p += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
}

Eigen::MatrixXd HarmonicBalance::Monodromy(const Eigen::VectorXd& z, double omega, int steps) const {
  Eigen::MatrixXd phi = Eigen::MatrixXd::Identity(2 * dofs_, 2 * dofs_);
  Propagate(z, omega, steps, &phi, nullptr);
  return phi;
}

std::vector<std::complex<double>> HarmonicBalance::Multipliers(const Eigen::VectorXd& z, double omega,
                                                               int steps) const {
  const Eigen::VectorXcd mu = Eigen::EigenSolver<Eigen::MatrixXd>(Monodromy(z, omega, steps), false).eigenvalues();
  std::vector<std::complex<double>> out(mu.data(), mu.data() + mu.size());
  std::stable_sort(out.begin(), out.end(), [](auto a, auto b) { return std::abs(a) > std::abs(b); });
  return out;
}

double HarmonicBalance::MaxMultiplier(const Eigen::VectorXd& z, double omega, double alpha, int steps) const {
  (void)alpha;
  double best = 0;
  for (const auto& m : Multipliers(z, omega, steps)) best = std::max(best, std::abs(m));
  return best;
}

HbmPoint HarmonicBalance::Describe(const Eigen::VectorXd& z, double omega, double alpha, int floquet_steps) const {
  HbmPoint p;
  p.omega = omega;
  p.alpha = alpha;
  const std::vector<double> y = MainSamples(z, 256 * nu_);
  p.y_min = *std::min_element(y.begin(), y.end());
  p.y_max = *std::max_element(y.begin(), y.end());
  p.amplitude = std::max(std::fabs(p.y_min), std::fabs(p.y_max));
  p.mean = z[Index(0, 0)];
  p.harmonics.assign(z.data(), z.data() + per_dof_);
  p.z = z;
  p.period = nu_;
  p.multipliers = Multipliers(z, omega, floquet_steps);
  p.max_multiplier = p.multipliers.empty() ? 0.0 : std::abs(p.multipliers.front());
  p.stable = p.max_multiplier < 1.0;
  return p;
}

OrbitWell WellOf(const HbmPoint& p) {
  return p.y_min > 0 ? OrbitWell::kPlus : p.y_max < 0 ? OrbitWell::kMinus : OrbitWell::kInterwell;
}

const char* OrbitWellName(OrbitWell w) {
  switch (w) {
    case OrbitWell::kPlus:
      return "+well";
    case OrbitWell::kMinus:
      return "-well";
    case OrbitWell::kInterwell:
      return "interwell";
  }
  return "interwell";
}

Eigen::VectorXd HarmonicBalance::Resize(const Eigen::VectorXd& z, int h_new) const {
  const int per_new = 2 * h_new + 1;
  Eigen::VectorXd out = Eigen::VectorXd::Zero(dofs_ * per_new);
  for (int i = 0; i < dofs_; ++i)
    for (int m = 0; m < std::min(per_new, per_dof_); ++m) out[i * per_new + m] = z[Index(i, m)];
  return out;
}

Eigen::VectorXd HarmonicBalance::Doubled(const Eigen::VectorXd& z, int h_new) const {
  const int per_new = 2 * h_new + 1;
  Eigen::VectorXd out = Eigen::VectorXd::Zero(dofs_ * per_new);
  for (int i = 0; i < dofs_; ++i) {
    out[i * per_new] = z[Index(i, 0)];
    for (int k = 1; k <= h_ && 2 * k <= h_new; ++k) {
      out[i * per_new + 4 * k - 1] = z[Index(i, 2 * k - 1)];
      out[i * per_new + 4 * k] = z[Index(i, 2 * k)];
    }
  }
  return out;
}

Eigen::VectorXd HarmonicBalance::DoublingDirection(const Eigen::VectorXd& z, double omega, int steps, int h_new,
                                                   std::complex<double>* mu) const {
  const int d = 2 * dofs_;
  Eigen::EigenSolver<Eigen::MatrixXd> es(Monodromy(z, omega, steps), true);
  int best = -1;
  for (int i = 0; i < d; ++i)
    if (es.eigenvalues()[i].imag() == 0.0 && es.eigenvalues()[i].real() < 0 &&
        (best < 0 || std::abs(es.eigenvalues()[i] + 1.0) < std::abs(es.eigenvalues()[best] + 1.0)))
      best = i;
  if (best < 0) return {};
  if (mu) *mu = es.eigenvalues()[best];
  Eigen::MatrixXd w = es.eigenvectors().col(best).real();
  // w(τ) over one period, then −w(τ − T) over the next: the anti-periodic Floquet solution (μ ≈ −1).
  const int total = steps * nu_;
  std::vector<std::vector<double>> samples(dofs_, std::vector<double>(2 * total));
  Propagate(z, omega, steps, &w, [&](int s, const Eigen::MatrixXd& ws) {
    for (int i = 0; i < dofs_; ++i) samples[i][s] = ws(2 * i, 0), samples[i][s + total] = -ws(2 * i, 0);
  });
  HbmOptions o2 = o_;
  o2.harmonics = h_new;
  o2.subharmonic = 2 * nu_;
  Eigen::VectorXd c = HarmonicBalance(o2).FromSamples(samples);
  if (o_.zero_mean)
    for (int i = 0; i < dofs_; ++i) c[i * (2 * h_new + 1)] = 0.0;
  const double norm = c.norm();
  return norm > 0 && std::isfinite(norm) ? Eigen::VectorXd(c / norm) : Eigen::VectorXd();
}

namespace {

// The branch's equations in (coefficients, parameter): R(z, p) = 0 with ∂R/∂p by central differences,
// the tangent from the bordered Jacobian and the pseudo-arclength corrector.
class Arclength {
 public:
  Arclength(const HarmonicBalance& hb, const HbmOptions& o) : hb_(hb), o_(o), n_(hb.size()) {}
  std::pair<double, double> OmAl(double p) const {
    return o_.param == ContinuationParam::kOmega ? std::pair<double, double>{p, o_.alpha}
                                                 : std::pair<double, double>{o_.omega, p};
  }
  // R and [∂R/∂z, ∂R/∂p] at u = (z, p).
  void Full(const Eigen::VectorXd& zz, double p, Eigen::VectorXd* g, Eigen::MatrixXd* a) const {
    auto [om, al] = OmAl(p);
    Eigen::VectorXd r, rp, rm;
    Eigen::MatrixXd j;
    hb_.Residual(zz, om, al, &r, &j);
    const double hp = 1e-7 * std::max(1.0, std::fabs(p));
    auto [om_p, al_p] = OmAl(p + hp);
    auto [om_m, al_m] = OmAl(p - hp);
    hb_.Residual(zz, om_p, al_p, &rp, nullptr);
    hb_.Residual(zz, om_m, al_m, &rm, nullptr);
    *g = r;
    a->setZero(n_, n_ + 1);
    a->leftCols(n_) = j;
    a->col(n_) = (rp - rm) / (2 * hp);
  }
  // The unit tangent at u, oriented along `prev`; *det_sign: the sign of the bordered determinant.
  Eigen::VectorXd Tangent(const Eigen::VectorXd& u, const Eigen::VectorXd& prev, double* det_sign) const {
    Eigen::VectorXd g;
    Eigen::MatrixXd a;
    Full(u.head(n_), u[n_], &g, &a);
    Eigen::MatrixXd aug(n_ + 1, n_ + 1);
    aug.topRows(n_) = a;
    aug.row(n_) = prev.transpose();
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n_ + 1);
    rhs[n_] = 1.0;
    Eigen::PartialPivLU<Eigen::MatrixXd> lu(aug);
    Eigen::VectorXd t = lu.solve(rhs);
    t.normalize();
    if (t.dot(prev) < 0) t = -t;
    if (det_sign) *det_sign = lu.determinant() > 0 ? 1.0 : -1.0;
    return t;
  }
  // Newton on [R(v) = 0, t·(v − pred) = 0] from pred; the iterations it took, or −1.
  int Correct(const Eigen::VectorXd& pred, const Eigen::VectorXd& t, Eigen::VectorXd* out) const {
    Eigen::VectorXd v = pred;
    for (int it = 0; it < o_.newton_max_iter; ++it) {
      Eigen::VectorXd gv;
      Eigen::MatrixXd av;
      Full(v.head(n_), v[n_], &gv, &av);
      Eigen::VectorXd res(n_ + 1);
      res.head(n_) = gv;
      res[n_] = t.dot(v - pred);
      if (!res.allFinite()) return -1;
      if (gv.cwiseAbs().maxCoeff() < o_.newton_tol && std::fabs(res[n_]) < 1e-12) {
        *out = v;
        return it;
      }
      Eigen::MatrixXd m(n_ + 1, n_ + 1);
      m.topRows(n_) = av;
      m.row(n_) = t.transpose();
      v -= m.partialPivLu().solve(res);
    }
    return -1;
  }
  int n() const { return n_; }

 private:
  const HarmonicBalance& hb_;
  const HbmOptions& o_;
  int n_;
};

// An accepted arclength step: from u along the unit tangent t by ds.
struct ArcStep {
  Eigen::VectorXd u, t;
  double ds = 0;
};

// The Floquet test functions of a point: period doubling det(Φ + I) = Π(μ + 1); Neimark–Sacker the
// bialternate product Π_{i<j}(μ_i μ_j − 1) (zero when a complex pair crosses |μ| = 1, or at a neutral
// saddle μ_i μ_j = 1, which the count of complex multipliers outside the circle tells apart).
double PeriodDoublingTest(const std::vector<std::complex<double>>& mu) {
  std::complex<double> p = 1.0;
  for (const auto& m : mu) p *= m + 1.0;
  return p.real();
}
double NeimarkSackerTest(const std::vector<std::complex<double>>& mu) {
  std::complex<double> p = 1.0;
  for (size_t i = 0; i < mu.size(); ++i)
    for (size_t j = i + 1; j < mu.size(); ++j) p *= mu[i] * mu[j] - 1.0;
  return p.real();
}
int ComplexOutside(const std::vector<std::complex<double>>& mu) {
  int c = 0;
  for (const auto& m : mu) c += m.imag() != 0.0 && std::abs(m) > 1.0;
  return c;
}

// Bisection on the step: corrected points at σ ∈ (0, ds) along the step's predictor, keeping the
// sub-interval where `test` changes sign (test(σ = 0) has sign s0), until the parameter is bracketed
// to 1e-10 (or 60 halvings). `critical` picks the multiplier reported. Invalid when a corrector fails.
HbmLocated Locate(
    const HarmonicBalance& hb, const HbmOptions& o, const Arclength& al, const ArcStep& st, double s0,
    const std::function<double(const Eigen::VectorXd& v, const std::vector<std::complex<double>>& mu)>& test,
    const std::function<std::complex<double>(const std::vector<std::complex<double>>&)>& critical) {
  const int n = al.n();
  double lo = 0, hi = st.ds;
  Eigen::VectorXd v_lo = st.u, v_hi;
  if (al.Correct(st.u + st.ds * st.t, st.t, &v_hi) < 0) return {};
  for (int it = 0; it < 60 && std::fabs(v_hi[n] - v_lo[n]) > 1e-10 * std::max(1.0, std::fabs(v_hi[n])); ++it) {
    ThrowIfCancelled();
    const double mid = 0.5 * (lo + hi);
    Eigen::VectorXd v;
    if (al.Correct(st.u + mid * st.t, st.t, &v) < 0) return {};
    auto [om, alpha] = al.OmAl(v[n]);
    const double f = test(v, hb.Multipliers(v.head(n), om, o.floquet_steps));
    if ((f > 0) == (s0 > 0))
      lo = mid, v_lo = v;
    else
      hi = mid, v_hi = v;
  }
  const Eigen::VectorXd v = 0.5 * (v_lo + v_hi);
  HbmLocated out;
  Eigen::VectorXd zz = v.head(n);
  std::tie(out.omega, out.alpha) = al.OmAl(v[n]);
  hb.Solve(&zz, out.omega, out.alpha);  // onto the branch at the located parameter (a tiny correction)
  const HbmPoint p = hb.Describe(zz, out.omega, out.alpha, o.floquet_steps);
  out.amplitude = p.amplitude;
  out.multiplier = critical(p.multipliers);
  out.z = zz;
  return out;
}

std::complex<double> NearestTo(const std::vector<std::complex<double>>& mu, std::complex<double> target) {
  std::complex<double> best = NAN;
  for (const auto& m : mu)
    if (!(std::abs(best - target) <= std::abs(m - target))) best = m;
  return best;
}
std::complex<double> NearestToCircle(const std::vector<std::complex<double>>& mu) {
  std::complex<double> best = NAN;
  for (const auto& m : mu)
    if (m.imag() > 0 && !(std::fabs(std::abs(best) - 1.0) <= std::fabs(std::abs(m) - 1.0))) best = m;
  return best;
}

// Pseudo-arclength continuation of one branch from a converged z at parameter p0, setting out
// toward increasing (direction +1) or decreasing (−1) parameter, until it leaves [from, to].
// Folds, period doublings and Neimark–Sacker points are flagged at the point after the crossing and
// located on the step before it. Cancellation unwinds (CancelUnwind) at every point and corrector attempt.
HbmBranch Continue(const HarmonicBalance& hb, const HbmOptions& o, Eigen::VectorXd z, double p0, double direction) {
  HbmBranch branch;
  branch.period = hb.subharmonic();
  const Arclength al(hb, o);
  const int n = hb.size();
  const double lo = std::min(o.from, o.to), hi = std::max(o.from, o.to);
  Eigen::VectorXd u(n + 1), t(n + 1);
  u.head(n) = z;
  u[n] = p0;
  // Initial tangent: along increasing parameter when starting at the low end, else decreasing.
  Eigen::VectorXd t_prev = Eigen::VectorXd::Zero(n + 1);
  t_prev[n] = direction;
  double ds = o.ds;
  double prev_tp = 0, prev_det_sign = 0, prev_pd = 0, prev_ns = 0;
  int prev_ns_count = 0;
  ArcStep step;  // the accepted step that led to u
  for (int count = 0; count < o.max_points; ++count) {
    ThrowIfCancelled();
    double det_sign = 0;
    t = al.Tangent(u, t_prev, &det_sign);
    if (u[n] < lo - 1e-12 || u[n] > hi + 1e-12) break;  // left the range: the branch ends here
    auto [om, alpha] = al.OmAl(u[n]);
    HbmPoint pt = hb.Describe(u.head(n), om, alpha, o.floquet_steps);
    const double pd = PeriodDoublingTest(pt.multipliers), ns = NeimarkSackerTest(pt.multipliers);
    const int ns_count = ComplexOutside(pt.multipliers);
    if (count > 0) {
      pt.fold = (t[n] > 0) != (prev_tp > 0);
      pt.branch_point = !pt.fold && det_sign != prev_det_sign;
      if (pt.fold)
        pt.fold_at = Locate(
            hb, o, al, step, prev_tp,
            [&](const Eigen::VectorXd& v, const auto&) { return al.Tangent(v, step.t, nullptr)[n]; },
            [](const auto& mu) { return NearestTo(mu, 1.0); });
      if ((pd > 0) != (prev_pd > 0)) {
        pt.period_doubling = true;
        pt.period_doubling_at = Locate(
            hb, o, al, step, prev_pd, [](const auto&, const auto& mu) { return PeriodDoublingTest(mu); },
            [](const auto& mu) { return NearestTo(mu, -1.0); });
      }
      if (ns_count != prev_ns_count) {
        pt.neimark_sacker = true;
        if ((ns > 0) != (prev_ns > 0))
          pt.neimark_sacker_at = Locate(
              hb, o, al, step, prev_ns, [](const auto&, const auto& mu) { return NeimarkSackerTest(mu); },
              NearestToCircle);
      }
    }
    prev_tp = t[n];
    prev_det_sign = det_sign;
    prev_pd = pd, prev_ns = ns, prev_ns_count = ns_count;
    branch.points.push_back(pt);
    // Predictor–corrector with step control.
    bool accepted = false;
    while (!accepted) {
      ThrowIfCancelled();
      const Eigen::VectorXd pred = u + ds * t;
      Eigen::VectorXd v;
      const int it = al.Correct(pred, t, &v);
      bool ok = it >= 0;
      // A corrector that lands far from its predictor has jumped to another part of the solution
      // set (a sharp turn): refuse it and retry with a shorter step.
      if (ok && (v - pred).norm() > 2.0 * ds) ok = false;
      if (ok) {
        step = {u, t, ds};
        u = v;
        t_prev = t;
        accepted = true;
        ds = NextArclengthStep(it, ds, o.ds_min, o.ds_max);
      } else {
        ds *= 0.5;
        if (ds < o.ds_min) {
          HbmPoint failed = pt;
          failed.converged = false;
          failed.fold = failed.branch_point = failed.period_doubling = failed.neimark_sacker = false;
          failed.fold_at = failed.period_doubling_at = failed.neimark_sacker_at = HbmLocated{};
          branch.points.push_back(failed);
          return branch;
        }
      }
    }
    // A closed branch (isola) returns to its start: stop after one lap.
    if (count > 10 && (u - (Eigen::VectorXd(n + 1) << branch.points.front().z, p0).finished()).norm() < 0.5 * ds) break;
  }
  return branch;
}

// The period-2ν branch from a located period doubling of a period-ν branch of hb: the doubled orbit
// plus δ along the critical Floquet vector (DoublingDirection), solved with that component fixed and
// the parameter free (the branch leaves the period doubling as a pitchfork of the doubled balance),
// continued away from the period doubling. The located point itself leads the branch.
bool SwitchAtPeriodDoubling(const HarmonicBalance& hb, const HbmOptions& o, const HbmLocated& pd, HbmBranch* out) {
  HbmOptions o2 = o;  // o: the period-ν branch's options
  o2.subharmonic = 2 * hb.subharmonic();
  o2.harmonics = std::min(limits::kMaxHbmHarmonics, 2 * hb.harmonics());
  const HarmonicBalance hb2(o2);
  const Arclength al2(hb2, o2);
  const int n2 = hb2.size();
  const double p_pd = ParamOf(o, pd.omega, pd.alpha);
  std::complex<double> mu;
  const Eigen::VectorXd e = hb.DoublingDirection(pd.z, pd.omega, o.floquet_steps, o2.harmonics, &mu);
  if (e.size() != n2) return false;
  const Eigen::VectorXd z_pd = hb.Doubled(pd.z, o2.harmonics);
  for (double delta : {0.05, 0.02, 0.01}) {
    ThrowIfCancelled();
    Eigen::VectorXd v(n2 + 1);
    v.head(n2) = z_pd + delta * e;
    v[n2] = p_pd;
    bool ok = false;
    for (int it = 0; it < o.newton_max_iter && !ok; ++it) {
      Eigen::VectorXd g;
      Eigen::MatrixXd a;
      al2.Full(v.head(n2), v[n2], &g, &a);
      Eigen::VectorXd res(n2 + 1);
      res.head(n2) = g;
      res[n2] = e.dot(v.head(n2) - z_pd) - delta;
      if (!res.allFinite()) break;
      if (g.cwiseAbs().maxCoeff() < o.newton_tol && std::fabs(res[n2]) < 1e-12) {
        ok = true;
        break;
      }
      Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n2 + 1, n2 + 1);
      m.topRows(n2) = a;
      m.row(n2).head(n2) = e.transpose();
      v -= m.partialPivLu().solve(res);
    }
    const double p = v[n2];
    if (!ok || p < std::min(o.from, o.to) || p > std::max(o.from, o.to)) continue;
    HbmBranch b = Continue(hb2, o2, v.head(n2), p, p >= p_pd ? 1.0 : -1.0);
    out->period = o2.subharmonic;
    out->start = "period-doubling at " + std::string(o.param == ContinuationParam::kOmega ? "Omega = " : "alpha = ") +
                 FormatNumber(p_pd) + " (period " + std::to_string(hb.subharmonic()) + " -> " +
                 std::to_string(o2.subharmonic) + ")";
    out->points.clear();
    out->points.push_back(hb2.Describe(z_pd, pd.omega, pd.alpha, o.floquet_steps));
    for (HbmPoint& q : b.points) out->points.push_back(std::move(q));
    return true;
  }
  return false;
}

// Moves the bifurcation flags and located points of `from` (none when null) onto `to`.
void MoveFlags(HbmPoint* from, HbmPoint* to) {
  const HbmPoint none;
  const HbmPoint& f = from ? *from : none;
  to->fold = f.fold, to->branch_point = f.branch_point, to->period_doubling = f.period_doubling,
  to->neimark_sacker = f.neimark_sacker;
  to->fold_at = f.fold_at, to->period_doubling_at = f.period_doubling_at, to->neimark_sacker_at = f.neimark_sacker_at;
}

// Steady state of a time integration at (Ω, α) from x0, sampled over one period, as coefficients.
bool SeedFromTime(const HarmonicBalance& hb, const HbmOptions& o, double omega, double alpha,
                  const std::array<double, 4>& x0, Eigen::VectorXd* z) {
  PointSpec s;
  s.model = o.model;
  s.params = o.params;
  s.alpha = alpha;
  s.omega = omega;
  const LaneInput lane = LaneFor(s);
  const double period = 2.0 * M_PI / omega;
  const double t_settle = std::ceil(300.0 / period) * period;
  const double orbit = period * hb.subharmonic();  // sampled over the orbit's period
  AdaptiveOptions ao;
  ao.rtol = 1e-9;
  ao.atol = 1e-11;
  const int m = 256;
  std::vector<std::vector<double>> samples(hb.dofs(), std::vector<double>(m));
  auto run = [&](auto model_tag) {
    using Model = decltype(model_tag);
    NondimSystem<Model> sys(lane.coeffs, alpha, omega);
    typename NondimSystem<Model>::State x;
    for (int d = 0; d < Model::kDim; ++d) x[d] = x0[d];
    Dopri5<NondimSystem<Model>> dp(sys, ao);
    if (dp.Integrate(0.0, x, t_settle, [](const Dopri5<NondimSystem<Model>>&) { ThrowIfCancelled(); }) !=
        OdeTermination::kOk)
      return false;
    for (int k = 0; k < m; ++k) {
      ThrowIfCancelled();
      Dopri5<NondimSystem<Model>> step(sys, ao);
      if (k > 0 && step.Integrate(t_settle + (k - 1) * orbit / m, x, t_settle + k * orbit / m) != OdeTermination::kOk)
        return false;
      for (int i = 0; i < hb.dofs(); ++i) samples[i][k] = x[2 * i];
    }
    return true;
  };
  const bool ok = HasResonator(o.model) ? run(CoupledModel{}) : run(SingleModel{});
  if (!ok) return false;
  *z = hb.FromSamples(samples);
  return hb.Solve(z, omega, alpha) >= 0;
}

StatusOr<HbmResult> ContinueBranchesOrUnwind(const HbmOptions& o) {
  HarmonicBalance hb(o);
  HbmResult result;
  const bool bistable = IsBistable(o.model);
  const double well = bistable ? 1.0 / std::sqrt(o.params.eps) : 0.0;
  struct Start {
    const char* name;
    std::array<double, 4> x0;
  };
  std::vector<Start> starts = {{"rest in the positive well", {well, 0, well, 0}}};
  if (bistable) {
    starts.push_back({"rest in the negative well", {-well, 0, -well, 0}});
    starts.push_back({"large-amplitude start (y_m' = 3)", {0, 3, 0, 3}});
  }
  // Seeds: steady states of time integrations from each start at five parameter values across the
  // range (interwell branches may exist only away from the range's start). A seed already lying on a
  // computed branch is skipped; a new one is continued both ways and the halves are joined.
  auto on_branch = [&](const Eigen::VectorXd& z, double p) {
    for (const HbmBranch& b : result.branches)
      for (const HbmPoint& q : b.points)
        if (std::fabs(ParamOf(o, q.omega, q.alpha) - p) <= o.ds_max && (q.z - z).norm() <= 0.05 * (1.0 + z.norm()))
          return true;
    return false;
  };
  for (int k = 0; k < 5; ++k) {
    const double p = o.from + (o.to - o.from) * k / 4.0;
    const double om = o.param == ContinuationParam::kOmega ? p : o.omega;
    const double al = o.param == ContinuationParam::kAlpha ? p : o.alpha;
    for (const Start& st : starts) {
      ThrowIfCancelled();
      Eigen::VectorXd z;
      if (!SeedFromTime(hb, o, om, al, st.x0, &z)) continue;
      if (o.zero_mean) {
        for (int i = 0; i < hb.dofs(); ++i) z[i * (2 * o.harmonics + 1)] = 0.0;
        if (hb.Solve(&z, om, al) < 0) continue;
      }
      if (on_branch(z, p)) continue;
      HbmBranch up = Continue(hb, o, z, p, +1.0);
      HbmBranch down = Continue(hb, o, z, p, -1.0);
      HbmBranch joined;
      joined.start = std::string(st.name) + " at " + (o.param == ContinuationParam::kOmega ? "Omega = " : "alpha = ") +
                     FormatNumber(p);
      // Joined in branch order (the down half reversed). A flag marks the point that ends the step of
      // the crossing: in the reversed half that is the point before the one it was found at.
      for (size_t k = 1; k < down.points.size(); ++k) MoveFlags(&down.points[k], &down.points[k - 1]);
      if (!down.points.empty()) MoveFlags(nullptr, &down.points.back());
      for (auto it = down.points.rbegin(); it != down.points.rend(); ++it) joined.points.push_back(*it);
      for (size_t i = 1; i < up.points.size(); ++i) joined.points.push_back(up.points[i]);
      joined.period = hb.subharmonic();
      result.branches.push_back(std::move(joined));
    }
  }
  // Branch switching at period doublings (breadth first: period 2 before 4), each located period
  // doubling once: one that lies on an already computed doubled branch (its other end) is skipped.
  int switched = 0;
  for (size_t bi = 0; bi < result.branches.size() && o.switch_depth > 0; ++bi) {
    const int nu = result.branches[bi].period;
    if (nu >= (1 << o.switch_depth)) continue;
    const HbmOptions ob = ForPeriod(o, nu);
    const HarmonicBalance hbb(ob);
    const int h2 = std::min(limits::kMaxHbmHarmonics, 2 * ob.harmonics);
    for (size_t pi = 0; pi < result.branches[bi].points.size(); ++pi) {
      const HbmPoint pt = result.branches[bi].points[pi];  // a copy: branches grows below
      if (!pt.period_doubling || !pt.period_doubling_at.valid()) continue;
      const Eigen::VectorXd zd = hbb.Doubled(pt.period_doubling_at.z, h2);
      const double p = ParamOf(o, pt.period_doubling_at.omega, pt.period_doubling_at.alpha);
      bool known = false;
      for (const HbmBranch& b : result.branches)
        if (b.period == 2 * nu)
          for (const HbmPoint& q : b.points)
            known |= std::fabs(ParamOf(o, q.omega, q.alpha) - p) <= o.ds_max &&
                     (q.z - zd).norm() <= 0.05 * (1.0 + zd.norm());
      if (known) continue;
      if (switched >= limits::kMaxHbmSwitchedBranches) break;
      HbmBranch doubled;
      if (!SwitchAtPeriodDoubling(hbb, ob, pt.period_doubling_at, &doubled)) {
        char note[200];
        std::snprintf(note, sizeof note,
                      "no period-%d branch could be seeded at the period doubling at %s = %.8g (branch %zu); "
                      "more harmonics (--harmonics) often help",
                      2 * nu, o.param == ContinuationParam::kOmega ? "Omega" : "alpha", p, bi);
        result.notes.push_back(note);
        continue;
      }
      doubled.start += ", from branch " + std::to_string(bi);
      result.branches.push_back(std::move(doubled));
      ++switched;
    }
  }
  // Truncation check: re-solve a few points with H + 2 harmonics and compare amplitudes.
  for (const HbmBranch& b : result.branches) {
    const HbmOptions ob = ForPeriod(o, b.period);
    HbmOptions more = ob;
    more.harmonics = ob.harmonics + 2;
    const HarmonicBalance hbk(ob), hb2(more);
    for (size_t i = 0; i < b.points.size(); i += std::max<size_t>(1, b.points.size() / 8)) {
      ThrowIfCancelled();
      const HbmPoint& p = b.points[i];
      if (!p.converged) continue;
      Eigen::VectorXd z2 = hbk.Resize(p.z, more.harmonics);
      if (hb2.Solve(&z2, p.omega, p.alpha) < 0) continue;
      double amp2 = 0;
      for (double v : hb2.MainSamples(z2, 256 * b.period)) amp2 = std::max(amp2, std::fabs(v));
      result.truncation_change =
          std::max(result.truncation_change, std::fabs(amp2 - p.amplitude) / std::max(p.amplitude, 1e-12));
    }
  }
  (void)ParamOf;
  return result;
}

}  // namespace

// Cancellation (dynamics/cancel.h) is polled at every seed, continuation point and corrector
// attempt, and after every accepted step of the seeding integrations: a cancelled run returns
// CancelledStatus() and no branches.
StatusOr<HbmResult> ContinueBranches(const HbmOptions& o) {
  BISTABLE_RETURN_IF_ERROR(ValidateHbmOptions(o));
  try {
    return ContinueBranchesOrUnwind(o);
  } catch (const CancelUnwind&) {
    return CancelledStatus();
  }
}

}  // namespace bistable
