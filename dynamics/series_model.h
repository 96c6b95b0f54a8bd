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
#include "dynamics/lane_buf.h"
#include "dynamics/nondim_models.h"

namespace bistable {

struct SeriesCell {
  bool bistable = true;  // k_lin = −1 (bistable) or +1 (linear, ε ignored)
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
  int MainIndex(int i) const { return main_[i]; }      // index of y_i in the state
  int ResonatorIndex(int i) const { return res_[i]; }  // index of r_i, −1 when absent
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

// One lane of a series sweep for the lane kernel (ensemble_generic.h). The output cell is the last
// link: position d_N = y_N − y_{N−1}, velocity y_N' (model.md §3, "Series and dimensional sweeps").
struct SeriesLaneInput {
  double amp = 0, omega = 0, base_amp = 0;  // αΩ², Ω, α
  std::vector<SeriesCell> cells;            // all with a resonator or all without
  std::vector<double> x0;                   // SeriesModel's layout (WellState)
};

// The equations of SeriesModel for lane packs (the lane kernel's model concept): W chains side by
// side, each with its own cell coefficients. kCells > 0 fixes the chain length at compile time, 0
// takes it from the input; kRes: every cell carries a resonator (state per cell (y, y', r, r')), or none.
template <int kCells, bool kRes>
struct SeriesLaneModel {
  static constexpr int kStride = kRes ? 4 : 2;
  static constexpr int kDim = kCells * kStride;
  using Input = SeriesLaneInput;

  template <int W>
  class Lanes {
   public:
    using V = Vec<W>;
    // Link stiffness k_lin,i + 3 ε_i d_i² at the evaluated state.
    struct Jac {
      explicit Jac(const Lanes& m) : k(m.cells()) {}
      LaneBuf<V, kCells> k;
    };

    explicit Lanes(const Input& in) : n_(kCells > 0 ? kCells : static_cast<int>(in.cells.size())), c_(n_) {}
    int cells() const { return kCells > 0 ? kCells : n_; }
    int dim() const { return cells() * kStride; }

    void Load(int l, const Input& in) {
      for (int i = 0; i < cells(); ++i) {
        const SeriesCell& s = in.cells[i];
        c_[i].k_lin[l] = s.bistable ? -1.0 : 1.0;
        c_[i].eps[l] = s.bistable ? s.eps : 0.0;
        c_[i].eta[l] = s.eta;
        c_[i].eta_r[l] = kRes ? s.eta_r : 0.0;
        c_[i].phi[l] = kRes ? s.phi : 0.0;
        c_[i].lambda2[l] = kRes ? s.lambda * s.lambda : 0.0;
      }
    }

    // dx = F(x, f); the link stiffnesses into j.
    BISTABLE_INLINE void Eval(const V* x, V f, V* dx, Jac* j) const {
      const V zero = Splat<W>(0.0);
      V link = Link(0, x[0], x[1], zero, zero, j);
      for (int i = 0; i < cells(); ++i) {
        const int m = i * kStride;
        const V next = i + 1 < cells() ? Link(i + 1, x[m + kStride], x[m + kStride + 1], x[m], x[m + 1], j) : zero;
        Cell(i, x + m, f, link, next, dx + m);
        link = next;
      }
    }
    // dw = J w: the same equations, linearised (no forcing, link forces with the stiffness in j).
    BISTABLE_INLINE void Apply(const Jac& j, const V* w, V* dw) const {
      const V zero = Splat<W>(0.0);
      V link = LinearLink(0, j, w[0], w[1], zero, zero);
      for (int i = 0; i < cells(); ++i) {
        const int m = i * kStride;
        const V next =
            i + 1 < cells() ? LinearLink(i + 1, j, w[m + kStride], w[m + kStride + 1], w[m], w[m + 1]) : zero;
        Cell(i, w + m, zero, link, next, dw + m);
        link = next;
      }
    }
    // The last link's deflection and the last mass's velocity, with their time derivatives.
    BISTABLE_INLINE void Output(const V* x, const V* dx, V* out, V* dout) const {
      const int m = (cells() - 1) * kStride;
      out[0] = cells() > 1 ? x[m] - x[m - kStride] : x[m];
      out[1] = x[m + 1];
      dout[0] = cells() > 1 ? dx[m] - dx[m - kStride] : dx[m];
      dout[1] = dx[m + 1];
    }

   private:
    // L_i = −(k_lin d + ε d³ + η d') on cell i, d = y_i − y_{i−1}.
    BISTABLE_INLINE V Link(int i, V y, V v, V y_prev, V v_prev, Jac* j) const {
      const CellCoeffs<V>& c = c_[i];
      const V d = y - y_prev, dd = v - v_prev;
      j->k[i] = c.k_lin + 3.0 * c.eps * (d * d);
      return -(c.k_lin * d + c.eps * (d * d * d) + c.eta * dd);
    }
    BISTABLE_INLINE V LinearLink(int i, const Jac& j, V y, V v, V y_prev, V v_prev) const {
      return -(j.k[i] * (y - y_prev) + c_[i].eta * (v - v_prev));
    }
    // Cell i's rows: y'' = f + L_i − L_{i+1} − φ[η_r (y' − r') + λ²(y − r)], r'' = f + η_r (y' − r') + λ²(y − r).
    BISTABLE_INLINE void Cell(int i, const V* x, V f, V link, V next, V* dx) const {
      V acc = f + link - next;
      if constexpr (kRes) {
        const CellCoeffs<V>& c = c_[i];
        const V coupling = c.eta_r * (x[1] - x[3]) + c.lambda2 * (x[0] - x[2]);
        acc = acc - c.phi * coupling;
        dx[2] = x[3];
        dx[3] = f + coupling;
      }
      dx[0] = x[1];
      dx[1] = acc;
    }

    int n_;
    LaneBuf<CellCoeffs<V>, kCells> c_;
  };
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_SERIES_MODEL_H_
