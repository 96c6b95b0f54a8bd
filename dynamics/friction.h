// Stribeck friction (Specker et al.; the paper's Eqs. 18–19 with its typos removed, model.md §2):
//   F_f(v) = (F_s − F_c tanh(v_sp/v_t)) g(v) + F_c tanh(v/v_t),   g(v) = (v/v_sp) exp(1/2 − v²/(2 v_sp²))
// so that F_f(v_sp) = F_s (static peak) and F_f → F_c sign(v) (Coulomb) for |v| ≫ v_sp.
// Units: forces in N, velocities in m/s.
#ifndef BISTABLE_DYNAMICS_FRICTION_H_
#define BISTABLE_DYNAMICS_FRICTION_H_

#include <cmath>

namespace bistable {

struct Stribeck {
  double f_s = 0;      // static (peak) friction force, N, ≥ 0
  double f_c = 0;      // kinetic (Coulomb) friction force, N, ≥ 0
  double v_sp = 0.002; // Stribeck peak velocity, m/s, > 0
  double v_t = 0.001;  // transition velocity of the tanh, m/s, > 0

  double Force(double v) const {
    const double a = f_s - f_c * std::tanh(v_sp / v_t);
    const double u = v / v_sp;
    return a * u * std::exp(0.5 - 0.5 * u * u) + f_c * std::tanh(v / v_t);
  }
  // dF_f/dv.
  double Slope(double v) const {
    const double a = f_s - f_c * std::tanh(v_sp / v_t);
    const double u = v / v_sp;
    const double th = std::tanh(v / v_t);
    return a / v_sp * std::exp(0.5 - 0.5 * u * u) * (1.0 - u * u) + f_c * (1.0 - th * th) / v_t;
  }
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_FRICTION_H_
