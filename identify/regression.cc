// The equation-error regression of the force terms on measured records (fit.h BuildRegression,
// SolveRegression): the fit's start values and the trace's force evidence.
#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "identify/fit.h"

namespace bistable {

Regression BuildRegression(const IdentModel& m, const std::vector<PreparedRecord>& recs, const Setup& setup,
                           const std::vector<const TermDef*>& extra, size_t max_rows) {
  const int p_model = m.NumParams();
  int p_extra = 0;
  for (const TermDef* t : extra) p_extra += static_cast<int>(t->params.size());
  size_t total = 0;
  for (const PreparedRecord& r : recs) total += r.n() * (r.z.empty() ? 1 : 2);
  const size_t stride = std::max<size_t>(1, (total + max_rows - 1) / max_rows);
  std::vector<std::vector<double>> rows;
  std::vector<double> rhs;
  Regression reg;
  const int mass_col = m.FitsMass() ? m.NumTermParams() : -1;
  auto add_body_columns = [&](std::vector<double>& row, Body body, double sign, double q, double v) {
    int k = 0;
    double phi[kMaxTermParams];
    for (const TermDef* t : m.terms) {
      if (t->body == body) {
        TermBasis(*t, q, v, m.fc, phi);
        for (size_t j = 0; j < t->params.size(); ++j) row[k + j] += sign * phi[j];
      }
      k += static_cast<int>(t->params.size());
    }
    k = p_model;
    for (const TermDef* t : extra) {
      if (t->body == body) {
        TermBasis(*t, q, v, m.fc, phi);
        for (size_t j = 0; j < t->params.size(); ++j) row[k + j] += sign * phi[j];
      }
      k += static_cast<int>(t->params.size());
    }
  };
  // The piezo (model or extra): its back-force column a is −w along the measured voltage; its circuit is
  // rows of its own, b w + c y' = −w' (model piezo only), scaled to the force rows' size (the two row sets
  // share no column, so the scale changes no estimate, only the pooled σ).
  int piezo_col = m.PiezoIndex();
  const bool model_piezo = piezo_col >= 0;
  if (!model_piezo) {
    int k = p_model;
    for (const TermDef* t : extra) {
      if (t->kind == TermKind::kPiezo) piezo_col = k;
      k += static_cast<int>(t->params.size());
    }
  }
  double circuit_scale = 1;
  if (model_piezo) {
    double f2 = 0, w2 = 0, nf = 0, nw = 0;
    for (const PreparedRecord& r : recs) {
      if (r.wd.empty()) continue;
      for (size_t i = 0; i < r.n(); ++i) {
        const double a = setup.input == InputKind::kBaseAcceleration ? r.pdd[i] + r.input[i] : r.pdd[i];
        f2 += a * a, w2 += r.wd[i] * r.wd[i], ++nf, ++nw;
      }
    }
    const double mm = m.FitsMass() ? 1.0 : m.m_main;
    if (w2 > 0 && f2 > 0) circuit_scale = mm * std::sqrt(f2 / nf) / std::sqrt(w2 / nw);
  }
  for (size_t ri = 0; ri < recs.size(); ++ri) {
    const PreparedRecord& r = recs[ri];
    const bool res = !r.z.empty();
    const bool volt = !r.w.empty();
    const size_t edge = std::min<size_t>(std::max<size_t>(12, r.n() / 50), r.n() / 4);  // derivative end effects
    for (size_t i = edge; i + edge < r.n(); i += stride) {
      // Main body: F(y, y') − G(z, z') [+ m p''] = target.
      std::vector<double> row(p_model + p_extra, 0.0);
      const double yi = r.y[i] + m.Offset(m.theta, r.index);  // offsets enter as fixed values here
      add_body_columns(row, Body::kMain, 1.0, yi, r.yd[i]);
      if (res) add_body_columns(row, Body::kResonator, -1.0, r.z[i], r.zd[i]);
      double target = 0;
      const double mm = m.FitsMass() ? 0.0 : m.m_main;
      switch (setup.input) {
        case InputKind::kBaseDisplacement:
          target = -mm * r.pdd[i];
          break;
        case InputKind::kBaseAcceleration:
          target = -mm * (r.pdd[i] + r.input[i]);
          break;
        case InputKind::kForce:
          target = r.input[i] - mm * r.pdd[i];
          break;
      }
      if (mass_col >= 0) row[mass_col] = setup.input == InputKind::kBaseAcceleration ? r.pdd[i] + r.input[i] : r.pdd[i];
      if (piezo_col >= 0 && volt) row[piezo_col] = -r.w[i];
      rows.push_back(std::move(row));
      rhs.push_back(target);
      reg.record_of_row.push_back(static_cast<int>(ri));
      reg.q.push_back(yi);
      reg.v.push_back(r.yd[i]);
      if (model_piezo && volt) {  // the circuit: b w + c y' = −w'
        std::vector<double> crow(p_model + p_extra, 0.0);
        crow[piezo_col + 1] = circuit_scale * r.w[i];
        crow[piezo_col + 2] = circuit_scale * r.yd[i];
        rows.push_back(std::move(crow));
        rhs.push_back(-circuit_scale * r.wd[i]);
        reg.record_of_row.push_back(static_cast<int>(ri));
        reg.q.push_back(NAN);
        reg.v.push_back(NAN);
      }
      if (res && m.m_res > 0) {  // resonator: G(z, z') = −m_r x_r''
        std::vector<double> rrow(p_model + p_extra, 0.0);
        add_body_columns(rrow, Body::kResonator, 1.0, r.z[i], r.zd[i]);
        const double xr_dd = setup.input == InputKind::kBaseDisplacement ? r.rdd[i] : r.pdd[i] + r.rdd[i];
        rows.push_back(std::move(rrow));
        rhs.push_back(-m.m_res * xr_dd);
        reg.record_of_row.push_back(static_cast<int>(ri));
        reg.q.push_back(NAN);
        reg.v.push_back(NAN);
      }
    }
  }
  reg.X.resize(static_cast<long>(rows.size()), p_model + p_extra);
  reg.b.resize(static_cast<long>(rows.size()));
  for (size_t i = 0; i < rows.size(); ++i) {
    for (int j = 0; j < p_model + p_extra; ++j) reg.X(static_cast<long>(i), j) = rows[i][j];
    reg.b[static_cast<long>(i)] = rhs[i];
  }
  return reg;
}

LinearFit SolveRegression(const Eigen::MatrixXd& X, const Eigen::VectorXd& b, const std::vector<Sign>& signs) {
  const long p = X.cols(), n = X.rows();
  std::vector<bool> free(p, true);
  LinearFit out;
  out.theta.assign(p, 0.0);
  out.sigma.assign(p, NAN);
  for (int pass = 0; pass <= p; ++pass) {
    std::vector<long> cols;
    for (long j = 0; j < p; ++j)
      if (free[j]) cols.push_back(j);
    Eigen::MatrixXd A(n, static_cast<long>(cols.size()));
    Eigen::VectorXd scale(static_cast<long>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c) {
      const double s = X.col(cols[c]).norm();
      scale[static_cast<long>(c)] = s > 0 ? s : 1.0;
      A.col(static_cast<long>(c)) = X.col(cols[c]) / scale[static_cast<long>(c)];
    }
    const Eigen::VectorXd x = cols.empty() ? Eigen::VectorXd() : Eigen::VectorXd(A.colPivHouseholderQr().solve(b));
    bool clipped = false;
    std::fill(out.theta.begin(), out.theta.end(), 0.0);
    for (size_t c = 0; c < cols.size(); ++c) {
      const double v = x[static_cast<long>(c)] / scale[static_cast<long>(c)];
      if (signs.size() == static_cast<size_t>(p) && signs[cols[c]] == Sign::kNonNegative && v < 0) {
        free[cols[c]] = false;
        clipped = true;
      }
      out.theta[cols[c]] = v;
    }
    if (clipped) continue;
    const Eigen::VectorXd r = cols.empty() ? b : Eigen::VectorXd(b - A * x);
    out.rss = r.squaredNorm();
    if (!cols.empty() && n > static_cast<long>(cols.size())) {
      const double s2 = out.rss / static_cast<double>(n - static_cast<long>(cols.size()));
      const Eigen::MatrixXd cov = (A.transpose() * A).ldlt().solve(Eigen::MatrixXd::Identity(A.cols(), A.cols())) * s2;
      for (size_t c = 0; c < cols.size(); ++c)
        out.sigma[cols[c]] =
            std::sqrt(std::max(cov(static_cast<long>(c), static_cast<long>(c)), 0.0)) / scale[static_cast<long>(c)];
    }
    for (long j = 0; j < p; ++j)
      if (!free[j]) out.theta[j] = 0.0, out.sigma[j] = 0.0;
    break;
  }
  return out;
}

}  // namespace bistable
