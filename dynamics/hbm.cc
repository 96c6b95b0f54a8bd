#include "dynamics/hbm.h"

#include <algorithm>
#include <cmath>
#include <complex>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "dynamics/cancel.h"
#include "dynamics/dopri5.h"
#include "dynamics/nondim_system.h"
#include "dynamics/point.h"
#include "base/validate.h"

namespace bistable {
namespace {

double ParamOf(const HbmOptions& o, double omega, double alpha) { return o.param == ContinuationParam::kOmega ? omega : alpha; }

}  // namespace

Status ValidateHbmOptions(const HbmOptions& o) {
  if (!IsCellModel(o.model))
    return Status::InvalidArgument("model", std::string("model = '") + ModelName(o.model) +
                                                "' violates model in {standalone, coupled, linear, linear-coupled} (harmonic balance)");
  if (o.harmonics < 1 || o.harmonics > 50) return Violates("harmonics", o.harmonics, "in [1, 50]");
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
  if (!(o.ds > 0 && o.ds_min > 0 && o.ds_max >= o.ds && o.ds >= o.ds_min)) return Violates("ds", o.ds, "in [ds_min, ds_max]");
  if (o.max_points < 2) return Violates("max_points", o.max_points, ">= 2");
  return Status::Ok();
}

HarmonicBalance::HarmonicBalance(const HbmOptions& o) : o_(o), h_(o.harmonics) {
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
  // Linear part, harmonic by harmonic.
  for (int i = 0; i < dofs_; ++i) {
    for (int j = 0; j < dofs_; ++j) {
      (*r)[Index(i, 0)] += k_(i, j) * z[Index(j, 0)];
      if (jac) (*jac)(Index(i, 0), Index(j, 0)) += k_(i, j);
      for (int k = 1; k <= h_; ++k) {
        const int ia = Index(i, 2 * k - 1), ib = Index(i, 2 * k), ja = Index(j, 2 * k - 1), jb = Index(j, 2 * k);
        const double kw = k * omega, stiff = k_(i, j) - (i == j ? kw * kw : 0.0), damp = c_(i, j) * kw;
        (*r)[ia] += stiff * z[ja] + damp * z[jb];
        (*r)[ib] += stiff * z[jb] - damp * z[ja];
        if (jac) {
          (*jac)(ia, ja) += stiff, (*jac)(ia, jb) += damp;
          (*jac)(ib, jb) += stiff, (*jac)(ib, ja) -= damp;
        }
      }
    }
    (*r)[Index(i, 2)] -= alpha * omega * omega;  // forcing αΩ² sin Ωτ on every mass
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
    for (int k = 1; k <= h_; ++k) v += z[Index(0, 2 * k - 1)] * std::cos(k * th) + z[Index(0, 2 * k)] * std::sin(k * th);
    y[s] = v;
  }
  return y;
}

double HarmonicBalance::MaxMultiplier(const Eigen::VectorXd& z, double omega, double alpha, int steps) const {
  // Monodromy of w' = J(x(τ)) w along the harmonic-balance orbit x(τ), RK4 over one period.
  const int d = 2 * dofs_;
  const double period = 2.0 * M_PI / omega, h = period / steps;
  auto y_main = [&](double t) {
    double v = z[Index(0, 0)];
    for (int k = 1; k <= h_; ++k) v += z[Index(0, 2 * k - 1)] * std::cos(k * omega * t) + z[Index(0, 2 * k)] * std::sin(k * omega * t);
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
  (void)alpha;
  Eigen::MatrixXd phi = Eigen::MatrixXd::Identity(d, d);
  for (int s = 0; s < steps; ++s) {
    const double t = s * h;
    const Eigen::MatrixXd j1 = jac(t), j2 = jac(t + 0.5 * h), j4 = jac(t + h);
    const Eigen::MatrixXd k1 = j1 * phi, k2 = j2 * (phi + 0.5 * h * k1), k3 = j2 * (phi + 0.5 * h * k2), k4 = j4 * (phi + h * k3);
    phi += (h / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
  }
  const Eigen::VectorXcd mu = Eigen::EigenSolver<Eigen::MatrixXd>(phi, false).eigenvalues();
  double best = 0;
  for (int i = 0; i < mu.size(); ++i) best = std::max(best, std::abs(mu[i]));
  return best;
}

HbmPoint HarmonicBalance::Describe(const Eigen::VectorXd& z, double omega, double alpha, int floquet_steps) const {
  HbmPoint p;
  p.omega = omega;
  p.alpha = alpha;
  const std::vector<double> y = MainSamples(z, 256);
  p.y_min = *std::min_element(y.begin(), y.end());
  p.y_max = *std::max_element(y.begin(), y.end());
  p.amplitude = std::max(std::fabs(p.y_min), std::fabs(p.y_max));
  p.mean = z[Index(0, 0)];
  p.harmonics.assign(z.data(), z.data() + per_dof_);
  p.z = z;
  p.max_multiplier = MaxMultiplier(z, omega, alpha, floquet_steps);
  p.stable = p.max_multiplier < 1.0;
  return p;
}

OrbitWell WellOf(const HbmPoint& p) {
  return p.y_min > 0 ? OrbitWell::kPlus : p.y_max < 0 ? OrbitWell::kMinus : OrbitWell::kInterwell;
}

const char* OrbitWellName(OrbitWell w) {
  switch (w) {
    case OrbitWell::kPlus: return "+well";
    case OrbitWell::kMinus: return "-well";
    case OrbitWell::kInterwell: return "interwell";
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

namespace {

// Pseudo-arclength continuation of one branch from a converged z at parameter p0, setting out
// toward increasing (direction +1) or decreasing (−1) parameter, until it leaves [from, to].
// Cancellation unwinds (CancelUnwind) at every point and corrector attempt.
HbmBranch Continue(const HarmonicBalance& hb, const HbmOptions& o, Eigen::VectorXd z, double p0, double direction) {
  HbmBranch branch;
  const int n = hb.size();
  const double lo = std::min(o.from, o.to), hi = std::max(o.from, o.to);
  auto om_al = [&](double p) {
    return o.param == ContinuationParam::kOmega ? std::pair<double, double>{p, o.alpha} : std::pair<double, double>{o.omega, p};
  };
  auto full = [&](const Eigen::VectorXd& zz, double p, Eigen::VectorXd* g, Eigen::MatrixXd* a) {
    auto [om, al] = om_al(p);
    Eigen::VectorXd r, rp, rm;
    Eigen::MatrixXd j;
    hb.Residual(zz, om, al, &r, &j);
    const double hp = 1e-7 * std::max(1.0, std::fabs(p));
    auto [om_p, al_p] = om_al(p + hp);
    auto [om_m, al_m] = om_al(p - hp);
    hb.Residual(zz, om_p, al_p, &rp, nullptr);
    hb.Residual(zz, om_m, al_m, &rm, nullptr);
    *g = r;
    a->setZero(n, n + 1);
    a->leftCols(n) = j;
    a->col(n) = (rp - rm) / (2 * hp);
  };
  Eigen::VectorXd u(n + 1), t(n + 1);
  u.head(n) = z;
  u[n] = p0;
  // Initial tangent: along increasing parameter when starting at the low end, else decreasing.
  Eigen::VectorXd t_prev = Eigen::VectorXd::Zero(n + 1);
  t_prev[n] = direction;
  double ds = o.ds;
  double prev_tp = 0, prev_det_sign = 0;
  for (int count = 0; count < o.max_points; ++count) {
    ThrowIfCancelled();
    Eigen::VectorXd g;
    Eigen::MatrixXd a;
    full(u.head(n), u[n], &g, &a);
    Eigen::MatrixXd aug(n + 1, n + 1);
    aug.topRows(n) = a;
    aug.row(n) = t_prev.transpose();
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(n + 1);
    rhs[n] = 1.0;
    Eigen::PartialPivLU<Eigen::MatrixXd> lu(aug);
    t = lu.solve(rhs);
    t.normalize();
    if (t.dot(t_prev) < 0) t = -t;
    if (u[n] < lo - 1e-12 || u[n] > hi + 1e-12) break;  // left the range: the branch ends here
    auto [om, al] = om_al(u[n]);
    HbmPoint pt = hb.Describe(u.head(n), om, al, o.floquet_steps);
    const double det_sign = lu.determinant() > 0 ? 1.0 : -1.0;
    if (count > 0) {
      pt.fold = (t[n] > 0) != (prev_tp > 0);
      pt.branch_point = !pt.fold && det_sign != prev_det_sign;
    }
    prev_tp = t[n];
    prev_det_sign = det_sign;
    branch.points.push_back(pt);
    // Predictor–corrector with step control.
    bool accepted = false;
    while (!accepted) {
      ThrowIfCancelled();
      const Eigen::VectorXd pred = u + ds * t;
      Eigen::VectorXd v = pred;
      int it = 0;
      bool ok = false;
      for (; it < o.newton_max_iter; ++it) {
        Eigen::VectorXd gv;
        Eigen::MatrixXd av;
        full(v.head(n), v[n], &gv, &av);
        Eigen::VectorXd res(n + 1);
        res.head(n) = gv;
        res[n] = t.dot(v - pred);
        if (!res.allFinite()) break;
        if (gv.cwiseAbs().maxCoeff() < o.newton_tol && std::fabs(res[n]) < 1e-12) {
          ok = true;
          break;
        }
        Eigen::MatrixXd m(n + 1, n + 1);
        m.topRows(n) = av;
        m.row(n) = t.transpose();
        v -= m.partialPivLu().solve(res);
      }
      // A corrector that lands far from its predictor has jumped to another part of the solution
      // set (a sharp turn): refuse it and retry with a shorter step.
      if (ok && (v - pred).norm() > 2.0 * ds) ok = false;
      if (ok) {
        u = v;
        t_prev = t;
        accepted = true;
        if (it <= 3) ds = std::min(o.ds_max, ds * 1.5);
        if (it >= 8) ds = std::max(o.ds_min, ds * 0.7);
      } else {
        ds *= 0.5;
        if (ds < o.ds_min) {
          HbmPoint failed = pt;
          failed.converged = false;
          failed.fold = failed.branch_point = false;
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

// Steady state of a time integration at (Ω, α) from x0, sampled over one period, as coefficients.
bool SeedFromTime(const HarmonicBalance& hb, const HbmOptions& o, double omega, double alpha, const std::array<double, 4>& x0,
                  Eigen::VectorXd* z) {
  PointSpec s;
  s.model = o.model;
  s.params = o.params;
  s.alpha = alpha;
  s.omega = omega;
  const LaneInput lane = LaneFor(s);
  const double period = 2.0 * M_PI / omega;
  const double t_settle = std::ceil(300.0 / period) * period;
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
    if (dp.Integrate(0.0, x, t_settle, [](const Dopri5<NondimSystem<Model>>&) { ThrowIfCancelled(); }) != OdeTermination::kOk)
      return false;
    for (int k = 0; k < m; ++k) {
      ThrowIfCancelled();
      Dopri5<NondimSystem<Model>> step(sys, ao);
      if (k > 0 && step.Integrate(t_settle + (k - 1) * period / m, x, t_settle + k * period / m) != OdeTermination::kOk) return false;
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
  const double p0 = o.from;
  const double omega0 = o.param == ContinuationParam::kOmega ? p0 : o.omega;
  const double alpha0 = o.param == ContinuationParam::kAlpha ? p0 : o.alpha;
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
      for (auto it = down.points.rbegin(); it != down.points.rend(); ++it) joined.points.push_back(*it);
      for (size_t i = 1; i < up.points.size(); ++i) joined.points.push_back(up.points[i]);
      // Joined in parameter order: fold flags of the reversed half mark the same turning points.
      result.branches.push_back(std::move(joined));
    }
  }
  // Truncation check: re-solve a few points with H + 2 harmonics and compare amplitudes.
  HbmOptions more = o;
  more.harmonics = o.harmonics + 2;
  HarmonicBalance hb2(more);
  for (const HbmBranch& b : result.branches) {
    for (size_t i = 0; i < b.points.size(); i += std::max<size_t>(1, b.points.size() / 8)) {
      ThrowIfCancelled();
      const HbmPoint& p = b.points[i];
      if (!p.converged) continue;
      Eigen::VectorXd z2 = hb.Resize(p.z, more.harmonics);
      if (hb2.Solve(&z2, p.omega, p.alpha) < 0) continue;
      double amp2 = 0;
      for (double v : hb2.MainSamples(z2, 256)) amp2 = std::max(amp2, std::fabs(v));
      result.truncation_change = std::max(result.truncation_change, std::fabs(amp2 - p.amplitude) / std::max(p.amplitude, 1e-12));
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

std::vector<double> Eq9Amplitudes(ModelKind model, const NondimParams& p, double alpha, double omega) {
  using C = std::complex<double>;
  const double k_lin = IsBistable(model) ? -1.0 : 1.0, eps = IsBistable(model) ? p.eps : 0.0;
  const C i(0.0, 1.0), f = -i * alpha * omega * omega;
  C b = k_lin - omega * omega + i * p.eta * omega, e = f;
  if (HasResonator(model)) {
    const C c = p.lambda * p.lambda + i * p.eta_r * omega, d = p.lambda * p.lambda - omega * omega + i * p.eta_r * omega;
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
