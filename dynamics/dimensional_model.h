// The dimensional model for measured data (model.md §2; paper §5, Eqs. 13–19 corrected), SI units.
// State x = (y, y', z, z'): y = x_m − x0 main mass relative to the table [m], z = x_r − x_m
// resonator relative to the main mass [m], and their velocities [m/s].
//   m_m x_m'' = −F_k(y) − (c0_m + c2_m y²) y' − F_f(y'; main) + G_r
//   m_r x_r'' = −G_r,   G_r = k_r z + (c0_r + c2_r z²) z' + F_f(z'; res)
//   F_k(y) = k_lin y + k3 y³     (bistable: k_lin < 0 < k3; linear beam: k3 = 0)
// so y'' = F_m/m_m − a0(t) and z'' = −G_r/m_r − F_m/m_m. Without a resonator z, z' stay 0.
// Stiff at the paper's v_sp = 2 mm/s, v_t = 1 mm/s: use Rosenbrock23 (rosenbrock23.h).
#ifndef BISTABLE_DYNAMICS_DIMENSIONAL_MODEL_H_
#define BISTABLE_DYNAMICS_DIMENSIONAL_MODEL_H_

#include <cmath>
#include <functional>

#include <Eigen/Dense>

#include "dynamics/friction.h"
#include "base/status.h"

namespace bistable {

// Base (table) kinematics at time t [s]: displacement [m], velocity [m/s], acceleration [m/s²], jerk [m/s³].
struct BaseKinematics {
  double x = 0, v = 0, a = 0, j = 0;
};
using BaseMotion = std::function<BaseKinematics(double t)>;

// x0(t) = A0 sin(2π f0 t).
BaseMotion SineBase(double a0_m, double f0_hz);
// Linear chirp x0(t) = A0 sin(2π (f_start t + (f_end − f_start) t²/(2 T))), 0 ≤ t ≤ T.
BaseMotion ChirpBase(double a0_m, double f_start_hz, double f_end_hz, double duration_s);

struct DimensionalParams {
  // Main mass and beam.
  double m_m = 0.282;        // kg
  double k_lin = -1135.7;    // N/m (negative: pre-buckled, bistable)
  double k3 = 2.15e6;        // N/m³
  double c0_m = 1.5;         // N s/m
  double c2_m = 8.6e3;       // N s/m³
  Stribeck fric_m{1.2, 0.44};
  // Resonator.
  bool has_resonator = true;
  double m_r = 0.620;        // kg
  double k_r = 636.6;        // N/m
  double c0_r = 4.6;         // N s/m
  double c2_r = 38.7e3;      // N s/m³
  Stribeck fric_r{1.4, 0.59};

  // Paper Table 2 presets, with the paper's v_sp = 0.002 m/s, v_t = 0.001 m/s.
  static DimensionalParams BistableTable2();
  static DimensionalParams LinearTable2();
};

Status ValidateDimensionalParams(const DimensionalParams& p);

class DimensionalModel {
 public:
  using State = Eigen::Vector4d;
  using Jacobian = Eigen::Matrix4d;

  DimensionalModel(DimensionalParams p, BaseMotion base) : p_(p), base_(std::move(base)) {}
  int dim() const { return 4; }
  const DimensionalParams& params() const { return p_; }

  void operator()(double t, const State& x, State& dx) const;
  void Jac(double t, const State& x, Jacobian& J, State& dfdt) const;
  // Resonator force G_r [N] and main-mass net force F_m [N] (for residual analysis).
  double ResonatorForce(const State& x) const;
  double MainForce(const State& x) const;

 private:
  DimensionalParams p_;
  BaseMotion base_;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_DIMENSIONAL_MODEL_H_
