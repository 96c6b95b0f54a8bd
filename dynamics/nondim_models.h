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
//   PowerRate, DissMainRate, DissResRate(c, x, dx[, f, f'])  their time derivatives along the flow
//                             (the window quadratures' end correction)
// so that dE/dτ = P − DissMain − DissRes exactly (model.md §3).
#ifndef BISTABLE_DYNAMICS_NONDIM_MODELS_H_
#define BISTABLE_DYNAMICS_NONDIM_MODELS_H_

#include "dynamics/lanes.h"  // BISTABLE_INLINE

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
  BISTABLE_INLINE static void Rhs(const CellCoeffs<T>& c, const T* x, T f, T* dx) {
    const T y = x[0], v = x[1];
    dx[0] = v;
    dx[1] = Fma(-c.eta, v, f) - y * Fma(c.eps, y * y, c.k_lin);  // f − η y' − (k_lin y + ε y³)
  }
  template <class T>
  BISTABLE_INLINE static void Tangent(const CellCoeffs<T>& c, const T* x, const T* w, T* dw) {
    const T y = x[0];
    const T j10 = Fma(c.eps * -3.0, y * y, -c.k_lin);  // ∂F₁/∂y = −k_lin − 3εy²
    dw[0] = w[1];
    dw[1] = Fma(j10, w[0], -c.eta * w[1]);
  }
  template <class T>
  BISTABLE_INLINE static T Power(const CellCoeffs<T>&, const T* x, T f) {
    return f * x[1];
  }
  template <class T>
  BISTABLE_INLINE static T DissMain(const CellCoeffs<T>& c, const T* x) {
    return c.eta * (x[1] * x[1]);
  }
  template <class T>
  BISTABLE_INLINE static T DissRes(const CellCoeffs<T>&, const T* x) {
    return 0.0 * x[0];
  }
  template <class T>
  static T PowerRate(const CellCoeffs<T>&, const T* x, const T* dx, T f, T fdot) {
    return fdot * x[1] + f * dx[1];
  }
  template <class T>
  static T DissMainRate(const CellCoeffs<T>& c, const T* x, const T* dx) {
    return 2.0 * c.eta * (x[1] * dx[1]);
  }
  template <class T>
  static T DissResRate(const CellCoeffs<T>&, const T* x, const T*) {
    return 0.0 * x[0];
  }
  template <class T>
  BISTABLE_INLINE static T Energy(const CellCoeffs<T>& c, const T* x) {
    const T y = x[0], v = x[1], y2 = y * y;
    return 0.5 * (v * v) + 0.5 * c.k_lin * y2 + 0.25 * c.eps * (y2 * y2);
  }
};

// Oscillator coupled with a linear resonator (paper Eq. 3, corrected per model.md).
struct CoupledModel {
  static constexpr int kDim = 4;
  static constexpr bool kHasResonator = true;

  template <class T>
  BISTABLE_INLINE static void Rhs(const CellCoeffs<T>& c, const T* x, T f, T* dx) {
    const T y = x[0], v = x[1], yr = x[2], vr = x[3];
    const T coupling = Fma(c.eta_r, v - vr, c.lambda2 * (y - yr));  // per unit resonator mass
    dx[0] = v;
    // f − η y' − (k_lin y + ε y³) − φ·coupling; y' is the stage's late input, so it enters last.
    dx[1] = Fma(-c.phi, coupling, Fma(-c.eta, v, f) - y * Fma(c.eps, y * y, c.k_lin));
    dx[2] = vr;
    dx[3] = f + coupling;
  }
  template <class T>
  BISTABLE_INLINE static void Tangent(const CellCoeffs<T>& c, const T* x, const T* w, T* dw) {
    const T y = x[0];
    const T j10 = Fma(c.eps * -3.0, y * y, -c.k_lin);  // ∂F₁/∂y = −k_lin − 3εy²
    const T coupling = Fma(c.eta_r, w[1] - w[3], c.lambda2 * (w[0] - w[2]));
    dw[0] = w[1];
    dw[1] = Fma(-c.phi, coupling, Fma(j10, w[0], -c.eta * w[1]));
    dw[2] = w[3];
    dw[3] = coupling;
  }
  template <class T>
  BISTABLE_INLINE static T Power(const CellCoeffs<T>& c, const T* x, T f) {
    return f * Fma(c.phi, x[3], x[1]);
  }
  template <class T>
  BISTABLE_INLINE static T DissMain(const CellCoeffs<T>& c, const T* x) {
    return c.eta * (x[1] * x[1]);
  }
  template <class T>
  BISTABLE_INLINE static T DissRes(const CellCoeffs<T>& c, const T* x) {
    const T dv = x[1] - x[3];
    return c.phi * c.eta_r * (dv * dv);
  }
  template <class T>
  static T PowerRate(const CellCoeffs<T>& c, const T* x, const T* dx, T f, T fdot) {
    return fdot * Fma(c.phi, x[3], x[1]) + f * Fma(c.phi, dx[3], dx[1]);
  }
  template <class T>
  static T DissMainRate(const CellCoeffs<T>& c, const T* x, const T* dx) {
    return 2.0 * c.eta * (x[1] * dx[1]);
  }
  template <class T>
  static T DissResRate(const CellCoeffs<T>& c, const T* x, const T* dx) {
    return 2.0 * c.phi * c.eta_r * ((x[1] - x[3]) * (dx[1] - dx[3]));
  }
  template <class T>
  BISTABLE_INLINE static T Energy(const CellCoeffs<T>& c, const T* x) {
    const T y = x[0], v = x[1], yr = x[2], vr = x[3], y2 = y * y, dy = y - yr;
    return 0.5 * (v * v) + 0.5 * c.phi * (vr * vr) + 0.5 * c.k_lin * y2 + 0.25 * c.eps * (y2 * y2) +
           0.5 * c.phi * c.lambda2 * (dy * dy);
  }
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_NONDIM_MODELS_H_
