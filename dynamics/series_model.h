// N oscillators in series (paper §6.3, Fig. 25), non-dimensional, table frame. Cell i (1..N) is a
// unit main mass joined to cell i−1 (cell 0 = the table, y_0 ≡ 0) by a bistable or linear spring and
// damper; each cell may carry its own resonator. With d_i = y_i − y_{i−1} the link force on cell i is
//   L_i = −(k_lin,i d_i + ε_i d_i³ + η_i d_i')        (and −L_i on cell i−1)
//   y_i'' = f + L_i − L_{i+1} − φ_i [η_r,i (y_i' − r_i') + λ_i² (y_i − r_i)]
//   r_i'' = f + η_r,i (y_i' − r_i') + λ_i² (y_i − r_i)
// with f = αΩ² sin(Ωτ). N = 1 is the coupled model (or the stand-alone one without resonator).
// State layout: per cell (y_i, y_i'), followed by (r_i, r_i') when the cell has a resonator.
#ifndef BISTABLE_DYNAMICS_SERIES_MODEL_H_
#define BISTABLE_DYNAMICS_SERIES_MODEL_H_

#include <vector>

#include <Eigen/Dense>

#include "base/status.h"

namespace bistable {

struct SeriesCell {
  bool bistable = true;      // k_lin = −1 (bistable) or +1 (linear, ε ignored)
  double eps = 1.0;
  double eta = 0.1;
  bool has_resonator = true;
  double eta_r = 0.075, phi = 2.0, lambda = 0.8;
};

class SeriesModel {
 public:
  using State = Eigen::VectorXd;
  using Jacobian = Eigen::MatrixXd;

  SeriesModel(std::vector<SeriesCell> cells, double alpha, double omega);
  // Identical cells.
  static SeriesModel Uniform(int n, const SeriesCell& cell, double alpha, double omega);

  int dim() const { return dim_; }
  int cells() const { return static_cast<int>(cells_.size()); }
  int MainIndex(int i) const { return main_[i]; }       // index of y_i in the state
  int ResonatorIndex(int i) const { return res_[i]; }   // index of r_i, −1 when absent
  // Rest in the positive well of every bistable link (y_i = i/√ε cumulatively), resonators with their cell.
  State WellState() const;

  void operator()(double t, const State& x, State& dx) const;
  void Jac(double t, const State& x, Jacobian& J, State& dfdt) const;

 private:
  std::vector<SeriesCell> cells_;
  std::vector<int> main_, res_;
  int dim_ = 0;
  double amp_, omega_;
};

Status ValidateSeriesCells(const std::vector<SeriesCell>& cells);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_SERIES_MODEL_H_
