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

#include <array>
#include <cmath>
#include <functional>

#include <Eigen/Dense>

#include "base/status.h"
#include "dynamics/friction.h"
#include "dynamics/lanes.h"

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
  double m_m = 0.282;      // kg
  double k_lin = -1135.7;  // N/m (negative: pre-buckled, bistable)
  double k3 = 2.15e6;      // N/m³
  double c0_m = 1.5;       // N s/m
  double c2_m = 8.6e3;     // N s/m³
  Stribeck fric_m{1.2, 0.44};
  // Resonator.
  bool has_resonator = true;
  double m_r = 0.620;    // kg
  double k_r = 636.6;    // N/m
  double c0_r = 4.6;     // N s/m
  double c2_r = 38.7e3;  // N s/m³
  Stribeck fric_r{1.4, 0.59};

  // The state components the Benettin tangent starts on (ode.h, TangentDims): (y, y', z, z'), or (y, y') alone
  // without a resonator — the one rule of the rig's RK4, Rosenbrock and adaptive paths.
  int TangentDims() const { return has_resonator ? 4 : 2; }

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
  int tangent_dims() const { return p_.TangentDims(); }
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

// Fixed-step RK4 on the rig: the stiffness sets the step. Where the model is stiffest — at rest, both
// bodies stuck, where the friction law's slope peaks (≈ 10³ N s/m at the paper's v_sp, v_t) — the
// largest |eigenvalue| ρ of the Jacobian bounds the step: h ≤ 2/ρ, 72 % of RK4's real-axis limit
// 2.785/ρ (the margin covers the c2 dampers' growth with the deflection). Steps per output step dt:
int Rk4Substeps(const DimensionalParams& p, double dt);

// One lane of a dimensional sweep for the lane kernel (ensemble_generic.h): a sine base
// x0 = A0 sin(ω t), output cell y, y'.
struct DimensionalLaneInput {
  double amp = 0, omega = 0, base_amp = 0;  // A0 ω² [m/s²], ω [rad/s], A0 [m]
  DimensionalParams params;                 // the rig: the same in every lane of a run (lane 0's are used)
  std::array<double, 4> x0 = {0, 0, 0, 0};
};

// The Jacobian entries a two-body lane model leaves behind at an evaluated state (its Lanes' `Jac`): j.fy = −∂F/∂y,
// j.fyd = −∂F/∂y', j.gz = ∂G/∂z, j.gzd = ∂G/∂z' of the main body's force F and the resonator's G.
template <int W, class Lanes>
struct TwoBodyJac {
  explicit TwoBodyJac(const Lanes&) {}
  Vec<W> fy, fyd, gz, gzd;
};

// dw = J w of a main body (y, y') under a base with a resonator (z, z') on it, from the force slopes
// j.fy = −∂F/∂y, j.fyd = −∂F/∂y', j.gz = ∂G/∂z, j.gzd = ∂G/∂z' (the lane models of the rig and of term models).
template <int W, class Jac>
BISTABLE_INLINE void TwoBodyApply(const Jac& j, const Vec<W>* w, Vec<W>* dw, double inv_m_m, double inv_m_r,
                                  bool resonator) {
  const Vec<W> gw = Fma(j.gz, w[2], j.gzd * w[3]);
  const Vec<W> a = Fma(j.fy, w[0], Fma(j.fyd, w[1], gw)) * inv_m_m;
  dw[0] = w[1];
  dw[1] = a;
  if (resonator) {
    dw[2] = w[3];
    dw[3] = Fma(-gw, Splat<W>(inv_m_r), -a);
  } else {
    dw[2] = dw[3] = Splat<W>(0.0);
  }
}

// DimensionalModel's equations for lane packs (the lane kernel's model concept): the Stribeck terms
// through Stribeck::Lanes (the project's lane exp and tanh), fused multiply-adds, and products with
// reciprocals of the masses, so a lane's bits are those of the same point at W = 1 (and within ulps
// per evaluation of DimensionalModel's). All lanes share the rig's parameters (lane 0's).
struct DimensionalLaneModel {
  static constexpr int kDim = 4;
  using Input = DimensionalLaneInput;

  template <int W>
  class Lanes {
   public:
    using V = Vec<W>;
    using Jac = TwoBodyJac<W, Lanes>;

    // d²F_f/dv² of both bodies at the evaluated state (EvalCurvature).
    struct Curv {
      V m, r;
    };

    explicit Lanes(const Input& in)
        : p_(in.params), fric_m_(p_.fric_m), fric_r_(p_.fric_r), inv_m_m_(1.0 / p_.m_m), inv_m_r_(1.0 / p_.m_r) {}
    int dim() const { return kDim; }
    int tangent_dims() const { return p_.TangentDims(); }
    void Load(int, const Input&) {}

    BISTABLE_INLINE void Eval(const V* x, V f, V* dx, Jac* j) const { EvalWith<false>(x, f, dx, j, nullptr); }
    // Eval, and the friction laws' curvatures (the same bits of dx and j as Eval).
    BISTABLE_INLINE void EvalCurvature(const V* x, V f, V* dx, Jac* j, Curv* c) const {
      EvalWith<true>(x, f, dx, j, c);
    }
    // The derivative of the Jacobian entries along k at the state x (c: EvalCurvature's there): with
    // Apply(dj, w, ·) it is ∂(J(x) w)/∂x · k, the tangent's coupling block of the augmented Jacobian.
    BISTABLE_INLINE void JacDirection(const V* x, const Curv& c, const V* k, Jac* dj) const {
      const V y = x[0], yd = x[1];
      const V two_c2y = (2.0 * p_.c2_m) * y;
      dj->fy = Fma(Fma(Splat<W>(-6.0 * p_.k3), y, (-2.0 * p_.c2_m) * yd), k[0], -(two_c2y * k[1]));
      dj->fyd = -Fma(two_c2y, k[0], c.m * k[1]);
      if (p_.has_resonator) {
        const V z = x[2], zd = x[3];
        dj->gz = (2.0 * p_.c2_r) * Fma(zd, k[2], z * k[3]);
        dj->gzd = Fma((2.0 * p_.c2_r) * z, k[2], c.r * k[3]);
      } else {
        dj->gz = dj->gzd = Splat<W>(0.0);
      }
    }
    template <bool kCurv>
    BISTABLE_INLINE void EvalWith(const V* x, V f, V* dx, Jac* j, Curv* c) const {
      const V y = x[0], yd = x[1], z = x[2], zd = x[3];
      V ff_m, sl_m, g = Splat<W>(0.0);
      if constexpr (kCurv)
        fric_m_.ForceSlopeCurvature<W>(yd, &ff_m, &sl_m, &c->m);
      else
        fric_m_.ForceSlope<W>(yd, &ff_m, &sl_m);
      const V y2 = y * y, damp_m = Fma(Splat<W>(p_.c2_m), y2, Splat<W>(p_.c0_m));
      j->fy = Fma(Splat<W>(-3.0 * p_.k3), y2, Splat<W>(-p_.k_lin)) - (2.0 * p_.c2_m) * (y * yd);
      j->fyd = -damp_m - sl_m;
      if (p_.has_resonator) {
        V ff_r, sl_r;
        if constexpr (kCurv)
          fric_r_.ForceSlopeCurvature<W>(zd, &ff_r, &sl_r, &c->r);
        else
          fric_r_.ForceSlope<W>(zd, &ff_r, &sl_r);
        const V z2 = z * z, damp_r = Fma(Splat<W>(p_.c2_r), z2, Splat<W>(p_.c0_r));
        g = Fma(Splat<W>(p_.k_r), z, Fma(damp_r, zd, ff_r));
        j->gz = Fma(Splat<W>(2.0 * p_.c2_r), z * zd, Splat<W>(p_.k_r));
        j->gzd = damp_r + sl_r;
      } else {
        j->gz = j->gzd = g;
        if constexpr (kCurv) c->r = g;
      }
      const V spring = Fma(Splat<W>(p_.k3), y2 * y, p_.k_lin * y);
      const V fm = (g - Fma(damp_m, yd, spring + ff_m)) * inv_m_m_;
      dx[0] = yd;
      dx[1] = fm + f;  // f = −(base acceleration)
      if (p_.has_resonator) {
        dx[2] = zd;
        dx[3] = Fma(-g, Splat<W>(inv_m_r_), -fm);
      } else {
        dx[2] = dx[3] = g;
      }
    }
    BISTABLE_INLINE void Apply(const Jac& j, const V* w, V* dw) const {
      TwoBodyApply<W>(j, w, dw, inv_m_m_, inv_m_r_, p_.has_resonator);
    }
    // The Jacobian's two dense rows, J[1][0..3] (the main mass's acceleration) and J[3][0..3] (the
    // resonator's), in the operations of Apply (rows 0 and 2 are (0 1 0 0) and (0 0 0 1)); without a
    // resonator row 3 is 0. For the linearly implicit integrators (ensemble_rosenbrock.h).
    BISTABLE_INLINE void JacRows(const Jac& j, V* a, V* b) const {
      a[0] = j.fy * inv_m_m_, a[1] = j.fyd * inv_m_m_, a[2] = j.gz * inv_m_m_, a[3] = j.gzd * inv_m_m_;
      if (p_.has_resonator) {
        const V im_r = Splat<W>(inv_m_r_);
        b[0] = -a[0], b[1] = -a[1];
        b[2] = Fma(-j.gz, im_r, -a[2]), b[3] = Fma(-j.gzd, im_r, -a[3]);
      } else {
        b[0] = b[1] = b[2] = b[3] = Splat<W>(0.0);
      }
    }
    bool has_resonator() const { return p_.has_resonator; }
    BISTABLE_INLINE void Output(const V* x, const V* dx, V* out, V* dout) const {
      out[0] = x[0], out[1] = x[1], dout[0] = dx[0], dout[1] = dx[1];
    }

   private:
    DimensionalParams p_;
    Stribeck::Lanes fric_m_, fric_r_;
    double inv_m_m_, inv_m_r_;
  };
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_DIMENSIONAL_MODEL_H_
