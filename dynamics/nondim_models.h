// The paper's non-dimensional base-excited models (model.md §1), written once for any scalar type T
// (double, or a lane pack Vec<W> holding W grid points).
//
// Coordinates are relative to the table: x = (y_m, y_m', y_r, y_r'). The base acts on every mass
// through the inertial force f(τ) = α Ω² sin(Ωτ) per unit mass; callers pass f.
//
//   main:      y_m'' + η y_m' + k_lin y_m + ε y_m³ + φ η_r (y_m' − y_r') + φ λ² (y_m − y_r) = f
//   resonator: y_r'' + η_r (y_r' − y_m') + λ² (y_r − y_m)                                  = f
//
// Bistable beam: k_lin = −1, ε > 0 (equilibria at ±1/√ε). Linear oscillator: k_lin = +1, ε = 0.
// Without resonator the y_r rows are absent (kDim = 2).
//
// Each model provides, for stage evaluation in integrators:
//   Rhs(c, x, f, dx)          dx = F(x, f)
//   Tangent(c, x, v, dv)      dv = J(x) v (J = ∂F/∂x; f does not depend on x)
//   Power(c, x, f)            P  = f (y_m' + φ y_r'), power injected by the base in the relative frame
//   DissMain / DissRes(c, x)  η y_m'², φ η_r (y_m' − y_r')²
//   Energy(c, x)              E = ½y_m'² + ½φ y_r'² + ½k_lin y_m² + ¼ε y_m⁴ + ½φλ²(y_m − y_r)²
// so that dE/dτ = P − DissMain − DissRes exactly (model.md §3).
#ifndef BISTABLE_DYNAMICS_NONDIM_MODELS_H_
#define BISTABLE_DYNAMICS_NONDIM_MODELS_H_

namespace bistable {

// Per-lane coefficients. lambda2 = λ².
template <class T>
struct CellCoeffs {
  T k_lin, eps, eta, eta_r, phi, lambda2;
};

// Oscillator without resonator (paper Eq. 2; linear variant with k_lin = +1, ε = 0).
struct SingleModel {
  static constexpr int kDim = 2;
  static constexpr bool kHasResonator = false;

  template <class T>
  static void Rhs(const CellCoeffs<T>& c, const T* x, T f, T* dx) {
    const T y = x[0], v = x[1];
    dx[0] = v;
    dx[1] = f - c.eta * v - c.k_lin * y - c.eps * (y * y * y);
  }
  template <class T>
  static void Tangent(const CellCoeffs<T>& c, const T* x, const T* w, T* dw) {
    const T y = x[0];
    dw[0] = w[1];
    dw[1] = -c.eta * w[1] - (c.k_lin + 3.0 * c.eps * (y * y)) * w[0];
  }
  template <class T>
  static T Power(const CellCoeffs<T>&, const T* x, T f) { return f * x[1]; }
  template <class T>
  static T DissMain(const CellCoeffs<T>& c, const T* x) { return c.eta * (x[1] * x[1]); }
  template <class T>
  static T DissRes(const CellCoeffs<T>&, const T* x) { return 0.0 * x[0]; }
  template <class T>
  static T Energy(const CellCoeffs<T>& c, const T* x) {
    const T y = x[0], v = x[1], y2 = y * y;
    return 0.5 * (v * v) + 0.5 * c.k_lin * y2 + 0.25 * c.eps * (y2 * y2);
  }
};

// Oscillator coupled with a linear resonator (paper Eq. 3, corrected per model.md).
struct CoupledModel {
  static constexpr int kDim = 4;
  static constexpr bool kHasResonator = true;

  template <class T>
  static void Rhs(const CellCoeffs<T>& c, const T* x, T f, T* dx) {
    const T y = x[0], v = x[1], yr = x[2], vr = x[3];
    const T dv = v - vr, dy = y - yr;
    const T coupling = c.eta_r * dv + c.lambda2 * dy;  // per unit resonator mass
    dx[0] = v;
    dx[1] = f - c.eta * v - c.k_lin * y - c.eps * (y * y * y) - c.phi * coupling;
    dx[2] = vr;
    dx[3] = f + coupling;
  }
  template <class T>
  static void Tangent(const CellCoeffs<T>& c, const T* x, const T* w, T* dw) {
    const T y = x[0];
    const T coupling = c.eta_r * (w[1] - w[3]) + c.lambda2 * (w[0] - w[2]);
    dw[0] = w[1];
    dw[1] = -c.eta * w[1] - (c.k_lin + 3.0 * c.eps * (y * y)) * w[0] - c.phi * coupling;
    dw[2] = w[3];
    dw[3] = coupling;
  }
  template <class T>
  static T Power(const CellCoeffs<T>& c, const T* x, T f) { return f * (x[1] + c.phi * x[3]); }
  template <class T>
  static T DissMain(const CellCoeffs<T>& c, const T* x) { return c.eta * (x[1] * x[1]); }
  template <class T>
  static T DissRes(const CellCoeffs<T>& c, const T* x) {
    const T dv = x[1] - x[3];
    return c.phi * c.eta_r * (dv * dv);
  }
  template <class T>
  static T Energy(const CellCoeffs<T>& c, const T* x) {
    const T y = x[0], v = x[1], yr = x[2], vr = x[3], y2 = y * y, dy = y - yr;
    return 0.5 * (v * v) + 0.5 * c.phi * (vr * vr) + 0.5 * c.k_lin * y2 + 0.25 * c.eps * (y2 * y2) +
           0.5 * c.phi * c.lambda2 * (dy * dy);
  }
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_NONDIM_MODELS_H_
