// Fold curves of the harmonic balance in (α, Ω) — the boundary of the bistable region, continued from the folds
// of a branch (ContinueFoldCurve, ContinueFoldCurves) — and the paper's closed-form one-harmonic balance
// (Eq9Amplitudes). The branches themselves are dynamics/hbm.cc.
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

Status ValidateFoldCurveOptions(const FoldCurveOptions& f) {
  BISTABLE_RETURN_IF_ERROR(CheckPositive("alpha_range", f.alpha_lo));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("alpha_range", f.alpha_hi));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("omega_range", f.omega_lo));
  BISTABLE_RETURN_IF_ERROR(CheckPositive("omega_range", f.omega_hi));
  if (!(f.alpha_lo < f.alpha_hi))
    return Violates("alpha_range", f.alpha_hi, "> its low end " + FormatNumber(f.alpha_lo));
  if (!(f.omega_lo < f.omega_hi))
    return Violates("omega_range", f.omega_hi, "> its low end " + FormatNumber(f.omega_lo));
  if (!(f.ds > 0 && f.ds_min > 0 && f.ds_max >= f.ds && f.ds >= f.ds_min))
    return Violates("ds", f.ds, "in [ds_min, ds_max]");
  if (f.max_points < 2 || f.max_points > 100000) return Violates("max_points", f.max_points, "in [2, 100000]");
  return Status::Ok();
}

namespace {

// The minimally augmented fold system in U = (z, Ω, α): F(U) = (R(z, Ω, α), g) with
// [J b; cᵀ 0] [v; g] = [0; 1]. b and c (unit vectors) are fixed during a Newton solve and moved to the
// left and right null vectors after every accepted point.
class FoldSystem {
 public:
  FoldSystem(const HarmonicBalance& hb, const HbmOptions& o) : hb_(hb), o_(o), n_(hb.size()) {}
  int n() const { return n_; }
  void InitBorders(const Eigen::VectorXd& u) {
    Eigen::VectorXd r;
    Eigen::MatrixXd j;
    hb_.Residual(u.head(n_), u[n_], u[n_ + 1], &r, &j);
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(j, Eigen::ComputeFullU | Eigen::ComputeFullV);
    b_ = svd.matrixU().col(n_ - 1);
    c_ = svd.matrixV().col(n_ - 1);
  }
  // g at u, and (when asked) v and w, the right and left null-vector estimates.
  double G(const Eigen::VectorXd& u, Eigen::VectorXd* v = nullptr, Eigen::VectorXd* w = nullptr) const {
    Eigen::VectorXd r;
    Eigen::MatrixXd j;
    hb_.Residual(u.head(n_), u[n_], u[n_ + 1], &r, &j);
    Eigen::MatrixXd m = Eigen::MatrixXd::Zero(n_ + 1, n_ + 1);
    m.topLeftCorner(n_, n_) = j;
    m.col(n_).head(n_) = b_;
    m.row(n_).head(n_) = c_.transpose();
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n_ + 1);
    rhs[n_] = 1.0;
    const Eigen::PartialPivLU<Eigen::MatrixXd> lu(m);
    const Eigen::VectorXd x = lu.solve(rhs);
    if (v) *v = x.head(n_);
    if (w) *w = m.transpose().partialPivLu().solve(rhs).head(n_);
    return x[n_];
  }
  // F(u) (n + 1) and its Jacobian (n + 1) × (n + 2): ∂R/∂z exact, the rest by central differences.
  void Full(const Eigen::VectorXd& u, Eigen::VectorXd* f, Eigen::MatrixXd* a) const {
    Eigen::VectorXd r;
    Eigen::MatrixXd j;
    hb_.Residual(u.head(n_), u[n_], u[n_ + 1], &r, &j);
    f->resize(n_ + 1);
    f->head(n_) = r;
    (*f)[n_] = G(u);
    if (!a) return;
    a->setZero(n_ + 1, n_ + 2);
    a->topLeftCorner(n_, n_) = j;
    for (int k = 0; k < n_ + 2; ++k) {
      const double h = 1e-6 * std::max(1.0, std::fabs(u[k]));
      Eigen::VectorXd up = u, um = u;
      up[k] += h, um[k] -= h;
      if (k >= n_) {
        Eigen::VectorXd rp, rm;
        hb_.Residual(up.head(n_), up[n_], up[n_ + 1], &rp, nullptr);
        hb_.Residual(um.head(n_), um[n_], um[n_ + 1], &rm, nullptr);
        a->col(k).head(n_) = (rp - rm) / (2 * h);
      }
      (*a)(n_, k) = (G(up) - G(um)) / (2 * h);
    }
  }
  // Newton on F(u) = 0 plus one more equation e·u = target (an arclength or a fixed α); iterations or −1.
  int Correct(Eigen::VectorXd* u, const Eigen::VectorXd& e, double target) const {
    for (int it = 0; it < o_.newton_max_iter; ++it) {
      Eigen::VectorXd f;
      Eigen::MatrixXd a;
      Full(*u, &f, &a);
      Eigen::VectorXd res(n_ + 2);
      res.head(n_ + 1) = f;
      res[n_ + 1] = e.dot(*u) - target;
      if (!res.allFinite()) return -1;
      if (f.head(n_).cwiseAbs().maxCoeff() < o_.newton_tol && std::fabs(f[n_]) < 1e-9 && std::fabs(res[n_ + 1]) < 1e-12)
        return it;
      Eigen::MatrixXd m(n_ + 2, n_ + 2);
      m.topRows(n_ + 1) = a;
      m.row(n_ + 1) = e.transpose();
      *u -= m.partialPivLu().solve(res);
    }
    return -1;
  }
  Eigen::VectorXd Tangent(const Eigen::VectorXd& u, const Eigen::VectorXd& prev) const {
    Eigen::VectorXd f;
    Eigen::MatrixXd a;
    Full(u, &f, &a);
    Eigen::MatrixXd aug(n_ + 2, n_ + 2);
    aug.topRows(n_ + 1) = a;
    aug.row(n_ + 1) = prev.transpose();
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n_ + 2);
    rhs[n_ + 1] = 1.0;
    Eigen::VectorXd t = aug.partialPivLu().solve(rhs);
    t.normalize();
    if (t.dot(prev) < 0) t = -t;
    return t;
  }
  // A direction of the curve without a previous one: the kernel of the (n + 1) × (n + 2) Jacobian.
  Eigen::VectorXd Kernel(const Eigen::VectorXd& u) const {
    Eigen::VectorXd f;
    Eigen::MatrixXd a;
    Full(u, &f, &a);
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
    return svd.matrixV().col(n_ + 1);
  }
  void MoveBorders(const Eigen::VectorXd& u) {
    Eigen::VectorXd v, w;
    G(u, &v, &w);
    if (v.allFinite() && v.norm() > 0) c_ = v.normalized();
    if (w.allFinite() && w.norm() > 0) b_ = w.normalized();
  }

 private:
  const HarmonicBalance& hb_;
  const HbmOptions& o_;
  int n_;
  Eigen::VectorXd b_, c_;
};

FoldCurvePoint FoldPointOf(const HarmonicBalance& hb, const Eigen::VectorXd& u) {
  const int n = hb.size();
  FoldCurvePoint p;
  p.z = u.head(n);
  p.omega = u[n];
  p.alpha = u[n + 1];
  const std::vector<double> y = hb.MainSamples(p.z, 256 * hb.subharmonic());
  p.y_min = *std::min_element(y.begin(), y.end());
  p.y_max = *std::max_element(y.begin(), y.end());
  p.amplitude = std::max(std::fabs(p.y_min), std::fabs(p.y_max));
  p.mean = p.z[0];
  return p;
}

// One direction of the fold curve from the converged fold point u with tangent t0.
FoldCurve FoldHalf(const HarmonicBalance& hb, const FoldCurveOptions& f, FoldSystem sys, Eigen::VectorXd u,
                   Eigen::VectorXd t) {
  FoldCurve c;
  const int n = hb.size();
  const Eigen::VectorXd u0 = u;
  double ds = f.ds;
  auto inside = [&](const Eigen::VectorXd& x) {
    return x[n] >= f.omega_lo && x[n] <= f.omega_hi && x[n + 1] >= f.alpha_lo && x[n + 1] <= f.alpha_hi;
  };
  for (int count = 0; count < f.max_points; ++count) {
    ThrowIfCancelled();
    c.points.push_back(FoldPointOf(hb, u));
    if (!inside(u)) break;  // the point just outside closes the curve at the box's edge
    bool accepted = false;
    while (!accepted) {
      ThrowIfCancelled();
      const Eigen::VectorXd pred = u + ds * t;
      Eigen::VectorXd v = pred;
      const int it = sys.Correct(&v, t, t.dot(pred));
      if (it >= 0 && (v - pred).norm() <= 2.0 * ds) {
        u = v;
        sys.MoveBorders(u);
        t = sys.Tangent(u, t);
        accepted = true;
        ds = NextArclengthStep(it, ds, f.ds_min, f.ds_max);
      } else {
        ds *= 0.5;
        if (ds < f.ds_min) {
          c.converged = false;
          return c;
        }
      }
    }
    if (count > 10 && (u - u0).norm() < 0.5 * ds) {  // a closed curve: back at the start
      c.points.push_back(FoldPointOf(hb, u));
      break;
    }
  }
  return c;
}

}  // namespace

StatusOr<FoldCurve> ContinueFoldCurve(const HbmOptions& o, const FoldCurveOptions& f, const Eigen::VectorXd& z,
                                      double omega, double alpha) {
  BISTABLE_RETURN_IF_ERROR(ValidateHbmOptions(o));
  BISTABLE_RETURN_IF_ERROR(ValidateFoldCurveOptions(f));
  try {
    const HarmonicBalance hb(o);
    const int n = hb.size();
    if (z.size() != n) return Status::InvalidArgument("z", "the fold's coefficients do not match the balance's size");
    FoldSystem sys(hb, o);
    Eigen::VectorXd u(n + 2);
    u << z, omega, alpha;
    sys.InitBorders(u);
    // The fold at this α: Ω and z free.
    Eigen::VectorXd e_alpha = Eigen::VectorXd::Zero(n + 2);
    e_alpha[n + 1] = 1.0;
    bool ok = false;
    for (int round = 0; round < 3 && !ok; ++round) {
      ok = sys.Correct(&u, e_alpha, alpha) >= 0;
      sys.MoveBorders(u);
    }
    if (!ok)
      return Status::FailedPrecondition("no fold converged near Omega = " + FormatNumber(omega) +
                                        ", alpha = " + FormatNumber(alpha));
    ok = sys.Correct(&u, e_alpha, alpha) >= 0;  // once more with the borders at the fold
    if (!ok)
      return Status::FailedPrecondition("no fold converged near Omega = " + FormatNumber(omega) +
                                        ", alpha = " + FormatNumber(alpha));
    Eigen::VectorXd t = sys.Kernel(u);
    t.normalize();
    if (t[n + 1] < 0) t = -t;
    FoldCurve up = FoldHalf(hb, f, sys, u, t);
    FoldCurve down = FoldHalf(hb, f, sys, u, -t);
    FoldCurve out;
    out.converged = up.converged && down.converged;
    for (auto it = down.points.rbegin(); it != down.points.rend(); ++it) out.points.push_back(*it);
    for (size_t i = 1; i < up.points.size(); ++i) out.points.push_back(up.points[i]);
    // Cusps: the (α, Ω) chords on either side of a point point in opposite directions.
    for (size_t i = 1; i + 1 < out.points.size(); ++i) {
      const FoldCurvePoint &a = out.points[i - 1], &b = out.points[i], &c = out.points[i + 1];
      out.points[i].cusp = (b.alpha - a.alpha) * (c.alpha - b.alpha) + (b.omega - a.omega) * (c.omega - b.omega) < 0;
    }
    out.start = "fold at Omega = " + FormatNumber(omega) + ", alpha = " + FormatNumber(alpha);
    return out;
  } catch (const CancelUnwind&) {
    return CancelledStatus();
  }
}

StatusOr<std::vector<FoldCurve>> ContinueFoldCurves(const HbmOptions& o, const FoldCurveOptions& f,
                                                    const HbmResult& r) {
  BISTABLE_RETURN_IF_ERROR(ValidateHbmOptions(o));
  BISTABLE_RETURN_IF_ERROR(ValidateFoldCurveOptions(f));
  std::vector<FoldCurve> curves;
  // A fold on a computed curve (or its mirror image, with the same (α, Ω, max |y_m|)): within 5e-3 of
  // one of the curve's chords in (α, Ω, amplitude).
  auto known = [&](const HbmLocated& l) {
    const Eigen::Vector3d q(l.alpha, l.omega, l.amplitude);
    for (const FoldCurve& c : curves)
      for (size_t i = 0; i + 1 < c.points.size(); ++i) {
        const Eigen::Vector3d a(c.points[i].alpha, c.points[i].omega, c.points[i].amplitude);
        const Eigen::Vector3d b(c.points[i + 1].alpha, c.points[i + 1].omega, c.points[i + 1].amplitude);
        const double len2 = (b - a).squaredNorm();
        const double s = len2 > 0 ? std::clamp((q - a).dot(b - a) / len2, 0.0, 1.0) : 0.0;
        if ((a + s * (b - a) - q).norm() < 5e-3) return true;
      }
    return false;
  };
  for (const HbmBranch& b : r.branches) {
    if (b.period != 1) continue;
    for (const HbmPoint& p : b.points) {
      if (!p.fold || !p.fold_at.valid() || known(p.fold_at)) continue;
      if (static_cast<int>(curves.size()) >= limits::kMaxHbmFoldCurves) return curves;
      auto c = ContinueFoldCurve(o, f, p.fold_at.z, p.fold_at.omega, p.fold_at.alpha);
      if (!c.ok()) {
        if (c.status().message().find("cancelled") != std::string::npos) return c.status();
        continue;
      }
      FoldCurve fc = std::move(c).value();
      fc.start += " (" + b.start + ")";
      curves.push_back(std::move(fc));
    }
  }
  return curves;
}

std::vector<double> Eq9Amplitudes(ModelKind model, const NondimParams& p, double alpha, double omega) {
  using C = std::complex<double>;
  const double k_lin = IsBistable(model) ? -1.0 : 1.0, eps = IsBistable(model) ? p.eps : 0.0;
  const C i(0.0, 1.0), f = -i * alpha * omega * omega;
  C b = k_lin - omega * omega + i * p.eta * omega, e = f;
  if (HasResonator(model)) {
    const C c = p.lambda * p.lambda + i * p.eta_r * omega,
            d = p.lambda * p.lambda - omega * omega + i * p.eta_r * omega;
    b -= p.phi * c * omega * omega / d;
    e *= 1.0 + p.phi * c / d;
  }
  // S² u³ + 2 Re(B) S u² + |B|² u − |E|² = 0, u = q², S = ¾ε.
  const double sq = 0.75 * eps, br = b.real();
  std::vector<double> q;
  if (sq == 0.0) {  // linear: |B|² u = |E|²
    q.push_back(std::abs(e) / std::abs(b));
    return q;
  }
  const double c3 = sq * sq, c2 = 2 * br * sq, c1 = std::norm(b), c0 = -std::norm(e);
  Eigen::Matrix3d companion;
  companion << -c2 / c3, -c1 / c3, -c0 / c3, 1, 0, 0, 0, 1, 0;
  const Eigen::Vector3cd roots = Eigen::EigenSolver<Eigen::Matrix3d>(companion, false).eigenvalues();
  for (int k = 0; k < 3; ++k) {
    if (std::fabs(roots[k].imag()) > 1e-9 * std::max(1.0, std::abs(roots[k])) || roots[k].real() <= 0) continue;
    double u = roots[k].real();
    for (int it = 0; it < 5; ++it) {  // polish on the cubic
      const double fu = ((c3 * u + c2) * u + c1) * u + c0, dfu = (3 * c3 * u + 2 * c2) * u + c1;
      if (dfu != 0) u -= fu / dfu;
    }
    q.push_back(std::sqrt(u));
  }
  std::sort(q.begin(), q.end());
  return q;
}

}  // namespace bistable
