// Stribeck friction (Specker et al.; the paper's Eqs. 18–19 with its typos removed, model.md §2):
//   F_f(v) = (F_s − F_c tanh(v_sp/v_t)) g(v) + F_c tanh(v/v_t),   g(v) = (v/v_sp) exp(1/2 − v²/(2 v_sp²))
// so that F_f(v_sp) = F_s (static peak) and F_f → F_c sign(v) (Coulomb) for |v| ≫ v_sp.
// Units: forces in N, velocities in m/s. The one home of the law: the dimensional model (dynamics/)
// uses Force/Slope, identification (identify/effects.h) the same law as a basis linear in F_s, F_c.
#ifndef BISTABLE_DYNAMICS_FRICTION_H_
#define BISTABLE_DYNAMICS_FRICTION_H_

#include <cmath>

namespace bistable {

// scale · g(v), evaluated as (scale · v/v_sp) · exp(1/2 − v²/(2 v_sp²)) (scale = 1: g itself, exactly).
inline double StribeckHump(double scale, double v, double v_sp) {
  const double u = v / v_sp;
  return scale * u * std::exp(0.5 - 0.5 * u * u);
}

struct Stribeck {
  double f_s = 0;      // static (peak) friction force, N, ≥ 0
  double f_c = 0;      // kinetic (Coulomb) friction force, N, ≥ 0
  double v_sp = 0.002; // Stribeck peak velocity, m/s, > 0
  double v_t = 0.001;  // transition velocity of the tanh, m/s, > 0

  double Force(double v) const { return StribeckHump(f_s - f_c * std::tanh(v_sp / v_t), v, v_sp) + f_c * std::tanh(v / v_t); }
  // dF_f/dv.
  double Slope(double v) const {
    const double a = f_s - f_c * std::tanh(v_sp / v_t);
    const double u = v / v_sp;
    const double th = std::tanh(v / v_t);
    return a / v_sp * std::exp(0.5 - 0.5 * u * u) * (1.0 - u * u) + f_c * (1.0 - th * th) / v_t;
  }
  // The law is linear in the two forces: F_f(v) = F_s φ[0] + F_c φ[1] with φ[0] = g(v) and
  // φ[1] = tanh(v/v_t) − tanh(v_sp/v_t) g(v); φ depends on v_sp, v_t only (f_s, f_c unused).
  void Basis(double v, double* phi) const {
    const double g = StribeckHump(1.0, v, v_sp);
    phi[0] = g;
    phi[1] = std::tanh(v / v_t) - std::tanh(v_sp / v_t) * g;
  }
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_FRICTION_H_
