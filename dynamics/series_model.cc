#include "dynamics/series_model.h"

#include <cmath>
#include <string>

#include "base/validate.h"

namespace bistable {

SeriesModel::SeriesModel(std::vector<SeriesCell> cells, double alpha, double omega)
    : cells_(std::move(cells)), amp_(alpha * omega * omega), omega_(omega) {
  for (const SeriesCell& c : cells_) {
    main_.push_back(dim_);
    dim_ += 2;
    res_.push_back(c.has_resonator ? dim_ : -1);
    if (c.has_resonator) dim_ += 2;
  }
}

SeriesModel SeriesModel::Uniform(int n, const SeriesCell& cell, double alpha, double omega) {
  return SeriesModel(std::vector<SeriesCell>(n, cell), alpha, omega);
}

SeriesModel::State SeriesModel::WellState() const {
  State x = State::Zero(dim_);
  double y = 0;
  for (int i = 0; i < cells(); ++i) {
    y += cells_[i].bistable ? 1.0 / std::sqrt(cells_[i].eps) : 0.0;
    x[main_[i]] = y;
    if (res_[i] >= 0) x[res_[i]] = y;
  }
  return x;
}

void SeriesModel::operator()(double t, const State& x, State& dx) const {
  const double f = amp_ * std::sin(omega_ * t);
  const int n = cells();
  // Link forces L_i on cell i (i = 0..n−1 here), L_n = 0.
  double prev_y = 0, prev_v = 0;
  std::vector<double> link(n + 1, 0.0);
  for (int i = 0; i < n; ++i) {
    const SeriesCell& c = cells_[i];
    const double y = x[main_[i]], v = x[main_[i] + 1];
    const double d = y - prev_y, dd = v - prev_v;
    link[i] = -((c.bistable ? -1.0 : 1.0) * d + (c.bistable ? c.eps * d * d * d : 0.0) + c.eta * dd);
    prev_y = y, prev_v = v;
  }
  for (int i = 0; i < n; ++i) {
    const SeriesCell& c = cells_[i];
    const int m = main_[i];
    double acc = f + link[i] - link[i + 1];
    if (res_[i] >= 0) {
      const int r = res_[i];
      const double coupling = c.eta_r * (x[m + 1] - x[r + 1]) + c.lambda * c.lambda * (x[m] - x[r]);
      acc -= c.phi * coupling;
      dx[r] = x[r + 1];
      dx[r + 1] = f + coupling;
    }
    dx[m] = x[m + 1];
    dx[m + 1] = acc;
  }
}

void SeriesModel::Jac(double t, const State& x, Jacobian& J, State& dfdt) const {
  const int n = cells();
  J.setZero(dim_, dim_);
  dfdt.setZero(dim_);
  const double df = amp_ * omega_ * std::cos(omega_ * t);
  // Link i joins cell i−1 (or the table) and cell i: ∂L_i/∂y_i = −k_i(d), ∂L_i/∂y_{i−1} = +k_i(d).
  for (int i = 0; i < n; ++i) {
    const SeriesCell& c = cells_[i];
    const int m = main_[i];
    const int mp = i > 0 ? main_[i - 1] : -1;
    const double d = x[m] - (mp >= 0 ? x[mp] : 0.0);
    const double k = (c.bistable ? -1.0 : 1.0) + (c.bistable ? 3.0 * c.eps * d * d : 0.0);
    // +L_i acts on cell i.
    J(m + 1, m) -= k;
    J(m + 1, m + 1) -= c.eta;
    if (mp >= 0) {
      J(m + 1, mp) += k;
      J(m + 1, mp + 1) += c.eta;
      // −L_i acts on cell i−1.
      J(mp + 1, m) += k;
      J(mp + 1, m + 1) += c.eta;
      J(mp + 1, mp) -= k;
      J(mp + 1, mp + 1) -= c.eta;
    }
    J(m, m + 1) = 1;
    dfdt[m + 1] = df;
    if (res_[i] >= 0) {
      const int r = res_[i];
      const double l2 = c.lambda * c.lambda;
      J(m + 1, m) -= c.phi * l2;
      J(m + 1, r) += c.phi * l2;
      J(m + 1, m + 1) -= c.phi * c.eta_r;
      J(m + 1, r + 1) += c.phi * c.eta_r;
      J(r, r + 1) = 1;
      J(r + 1, m) += l2;
      J(r + 1, r) -= l2;
      J(r + 1, m + 1) += c.eta_r;
      J(r + 1, r + 1) -= c.eta_r;
      dfdt[r + 1] = df;
    }
  }
}

Status ValidateSeriesCells(const std::vector<SeriesCell>& cells) {
  if (cells.empty() || cells.size() > 10000)
    return Violates("cells", static_cast<double>(cells.size()), "in [1, 10000]");
  for (size_t i = 0; i < cells.size(); ++i) {
    const SeriesCell& c = cells[i];
    const std::string p = "cells[" + std::to_string(i) + "].";
    if (c.bistable) BISTABLE_RETURN_IF_ERROR(CheckPositive(p + "eps", c.eps));
    BISTABLE_RETURN_IF_ERROR(CheckNonNegative(p + "eta", c.eta));
    if (c.has_resonator) {
      BISTABLE_RETURN_IF_ERROR(CheckNonNegative(p + "eta_r", c.eta_r));
      BISTABLE_RETURN_IF_ERROR(CheckPositive(p + "phi", c.phi));
      BISTABLE_RETURN_IF_ERROR(CheckPositive(p + "lambda", c.lambda));
    }
  }
  return Status::Ok();
}

}  // namespace bistable
