// Stribeck friction (Specker et al.; the paper's Eqs. 18–19 with its typos removed, model.md §2):
//   F_f(v) = (F_s − F_c tanh(v_sp/v_t)) g(v) + F_c tanh(v/v_t),   g(v) = (v/v_sp) exp(1/2 − v²/(2 v_sp²))
// so that F_f(v_sp) = F_s (static peak) and F_f → F_c sign(v) (Coulomb) for |v| ≫ v_sp.
// Units: forces in N, velocities in m/s. The one home of the law: the dimensional model (dynamics/)
// uses Force/Slope, identification and term-model sweeps (dynamics/terms.h) the same law as a basis linear in F_s, F_c.
#ifndef BISTABLE_DYNAMICS_FRICTION_H_
#define BISTABLE_DYNAMICS_FRICTION_H_

#include <cmath>
#include <type_traits>

#include "dynamics/lane_math.h"

namespace bistable {

// std::exp of the hump's exponent x = 1/2 − u²/2, with the same bits: below −746 std::exp underflows
// to +0 (its smallest nonzero result is at −745.13), and skipping the call there avoids libm's slow
// underflow path (errno), which sliding at |v| > 39 v_sp otherwise takes at every evaluation.
inline double HumpExpOf(double x) { return x < -746.0 ? 0.0 : std::exp(x); }
inline double HumpExp(double u) { return HumpExpOf(0.5 - 0.5 * u * u); }

// f applied to a double, or to each lane of a GCC vector pack (dynamics/lanes.h): a lane's value is
// the scalar function's, whatever the width.
template <class T, class F>
inline T EachLane(T x, F f) {
  if constexpr (std::is_floating_point_v<T>) {
    return f(x);
  } else {
    T r;
    for (int l = 0; l < static_cast<int>(sizeof(T) / sizeof(double)); ++l) r[l] = f(x[l]);
    return r;
  }
}

// The law in lanes from its coefficients — a_vsp = (F_s − F_c tanh(v_sp/v_t))/v_sp, two_a_vsp = 2 a_vsp, F_c,
// F_c/v_t, the same in every lane for the rig (Stribeck::Lanes) and per lane for a term model (term_model.h) — and
// the constants −1/(2 v_sp²) and 1/v_t: F_f and dF_f/dv. The hump's exponent x = 1/2 − u²/2 (u = v/v_sp) is one
// fused multiply-add and its slope factor 1 − u² = 2x: 10 multiplications and fused multiply-adds besides Exp and
// Tanh (the rig's step is bound by the multiply-add units: docs/numerics.md).
template <int W>
BISTABLE_INLINE void StribeckLawLanes(Vec<W> v, Vec<W> a_vsp, Vec<W> two_a_vsp, Vec<W> f_c, Vec<W> f_c_vt,
                                      double neg_half_inv_vsp2, double inv_vt, Vec<W>* force, Vec<W>* slope) {
  const Vec<W> x = Fma(v * neg_half_inv_vsp2, v, Splat<W>(0.5));
  const Vec<W> e = Exp<W>(x);
  const Vec<W> th = Tanh<W>(v * inv_vt);
  *force = Fma(f_c, th, (v * a_vsp) * e);
  *slope = Fma(e * two_a_vsp, x, f_c_vt * Fma(-th, th, Splat<W>(1.0)));
}

// scale · g(v), evaluated as (scale · v/v_sp) · exp(1/2 − v²/(2 v_sp²)) (scale = 1: g itself, exactly).
inline double StribeckHump(double scale, double v, double v_sp) {
  const double u = v / v_sp;
  return scale * u * HumpExp(u);
}

struct Stribeck {
  double f_s = 0;       // static (peak) friction force, N, ≥ 0
  double f_c = 0;       // kinetic (Coulomb) friction force, N, ≥ 0
  double v_sp = 0.002;  // Stribeck peak velocity, m/s, > 0
  double v_t = 0.001;   // transition velocity of the tanh, m/s, > 0

  // The hump's scale F_s − F_c tanh(v_sp/v_t) (constant: callers in a loop compute it once).
  double HumpScale() const { return f_s - f_c * std::tanh(v_sp / v_t); }
  double Force(double v) const { return StribeckHump(HumpScale(), v, v_sp) + f_c * std::tanh(v / v_t); }
  // dF_f/dv.
  double Slope(double v) const {
    const double a = HumpScale();
    double force, slope;
    ForceSlope(a, a / v_sp, v, &force, &slope);
    return slope;
  }
  // F_f(v) and dF_f/dv from one exp and one tanh, for a double or a lane pack T; a = HumpScale(),
  // a_vsp = a / v_sp. For a double (the per-point models): the same operations as Force(v) and
  // Slope(v), so the same bits. For a lane pack use Lanes below.
  template <class T>
  void ForceSlope(double a, double a_vsp, T v, T* force, T* slope) const {
    const T u = v / v_sp;
    const T e = EachLane<T>(0.5 - 0.5 * u * u, HumpExpOf);
    const T th = EachLane<T>(v / v_t, [](double x) { return std::tanh(x); });
    *force = a * u * e + f_c * th;
    *slope = a_vsp * e * (1.0 - u * u) + f_c * (1.0 - th * th) / v_t;
  }
  // The law for lane packs (the lane models): F_f and dF_f/dv per lane with the project's Exp and Tanh
  // (dynamics/lane_math.h) and fused multiply-adds, products with reciprocals instead of divisions —
  // the same operations at every width, W = 1 included, so a lane's bits do not depend on W; within
  // a few ulp of ForceSlope on doubles (glibc), not bit-equal to it.
  //
  // A body without friction (F_s = F_c = +0, a spec's choice, the same in every lane) skips the law: the
  // law's own operations give exactly force = v·0 (±0 with v's sign, NaN for a non-finite v) and
  // slope = 0·x + 0 (+0; NaN where the hump's exponent x is −∞ or NaN, i.e. |v| ≳ 10¹⁵¹ v_sp or v
  // NaN) there, so the skip keeps the bits
  // (DimensionalLanes.FrictionlessBodySkipsTheLawWithItsBits) and the branch is the same in every
  // lane and step. The rig's step then costs what its springs and dampers cost (docs/numerics.md).
  struct Lanes {
    explicit Lanes(const Stribeck& f)
        : a(f.HumpScale()),
          f_c(f.f_c),
          f_c_vt(f.f_c / f.v_t),
          inv_vt(1.0 / f.v_t),
          a_vsp(a / f.v_sp),
          two_a_vsp(2.0 * a_vsp),
          neg_half_inv_vsp2(-0.5 / (f.v_sp * f.v_sp)),
          neg_two_a_vsp3(-2.0 * a_vsp / (f.v_sp * f.v_sp)),
          neg_two_fc_vt2(-2.0 * f_c_vt / f.v_t),
          off(f.f_s == 0 && f.f_c == 0 && !std::signbit(f.f_s) && !std::signbit(f.f_c)) {}
    template <int W>
    BISTABLE_INLINE void ForceSlope(Vec<W> v, Vec<W>* force, Vec<W>* slope) const {
      if (off) {
        const Vec<W> zero = Splat<W>(0.0);
        *force = v * zero;
        *slope = Fma(zero, HumpExponent<W>(v), zero);
        return;
      }
      Law<W>(v, force, slope);
    }
    // The law itself (StribeckLawLanes), also for a body without friction (the skip's test compares the two).
    template <int W>
    BISTABLE_INLINE void Law(Vec<W> v, Vec<W>* force, Vec<W>* slope) const {
      StribeckLawLanes<W>(v, Splat<W>(a_vsp), Splat<W>(two_a_vsp), Splat<W>(f_c), Splat<W>(f_c_vt), neg_half_inv_vsp2,
                          inv_vt, force, slope);
    }
    template <int W>
    BISTABLE_INLINE Vec<W> HumpExponent(Vec<W> v) const {
      return Fma(v * neg_half_inv_vsp2, v, Splat<W>(0.5));
    }
    // F_f and dF_f/dv as ForceSlope (the same operations, so the same bits), and d²F_f/dv² =
    // −2 a v e (1 + x)/v_sp³ − 2 F_c th (1 − th²)/v_t² (x the hump's exponent, e = exp x, th = tanh(v/v_t)):
    // the curvature a linearly implicit integrator's tangent needs (ensemble_rosenbrock.h). 0 without friction.
    template <int W>
    BISTABLE_INLINE void ForceSlopeCurvature(Vec<W> v, Vec<W>* force, Vec<W>* slope, Vec<W>* curv) const {
      if (off) {
        ForceSlope<W>(v, force, slope);
        *curv = Splat<W>(0.0);
        return;
      }
      const Vec<W> one = Splat<W>(1.0);
      const Vec<W> x = HumpExponent<W>(v);
      const Vec<W> e = Exp<W>(x);
      const Vec<W> th = Tanh<W>(v * inv_vt);
      const Vec<W> sech2 = Fma(-th, th, one);
      *force = Fma(Splat<W>(f_c), th, (v * a_vsp) * e);
      *slope = Fma(e * two_a_vsp, x, f_c_vt * sech2);
      *curv = Fma((v * neg_two_a_vsp3) * e, x + one, (th * neg_two_fc_vt2) * sech2);
    }
    double a, f_c, f_c_vt, inv_vt, a_vsp, two_a_vsp, neg_half_inv_vsp2, neg_two_a_vsp3, neg_two_fc_vt2;
    bool off;  // F_s = F_c = +0 (a −0 keeps the law, whose zeros then carry other signs)
  };
};

// The law as a basis linear in the two forces: F_f(v) = F_s φ[0] + F_c φ[1] with φ[0] = g(v) and
// φ[1] = tanh(v/v_t) − tanh(v_sp/v_t) g(v); φ depends on v_sp, v_t only. Identification's simulator
// evaluates it per RK4 stage and body, so tanh(v_sp/v_t) is computed once, and exp and tanh are the
// project's lane math at W = 1 (dynamics/lane_math.h: within 1–2 ulp of glibc's; glibc's tanh and expm1 were
// 18 % of the coupled rig loop's profile). It divides by v_sp and v_t rather than multiplying by their reciprocals: the
// coupled rig's fit ends in another of its near-truth minima (1.087 % against 1.080 %) when the law's last bits change
// that way (docs/identification.md, "Session 15"). tanh_sp is glibc's and th the lane Tanh, so φ[1](v_sp) is within a
// few ulp of 0 rather than exactly 0 (F_f(v_sp) = F_s to that).
struct StribeckBasis {
  StribeckBasis(double v_sp, double v_t) : v_sp(v_sp), v_t(v_t), tanh_sp(std::tanh(v_sp / v_t)) {}
  // φ and, when dphi is given, dφ/dv; T is double or a lane pack Vec<W> (the same bits per lane).
  template <class T>
  BISTABLE_INLINE void Eval(T v, T* phi, T* dphi) const {
    constexpr int W = sizeof(T) / sizeof(double);
    const T u = v / v_sp, x = 0.5 - 0.5 * u * u;
    // Sliding fast (|v| ≳ 39 v_sp) the hump's exponent is below −746, where Exp returns +0: skipped when
    // every lane is there (lanes there in a mixed pack get that +0 from Exp: the same bits).
    T e{};
    if constexpr (W == 1 && std::is_floating_point_v<T>) {
      if (!(x <= -746.0)) e = Exp<1>(Vec<1>{x})[0];
    } else {
      bool all_below = true;
      for (int l = 0; l < W; ++l) all_below = all_below && x[l] <= -746.0;
      if (!all_below) e = Exp<W>(x);
    }
    const T g = u * e;
    T th;
    if constexpr (std::is_floating_point_v<T>)
      th = Tanh<1>(Vec<1>{v / v_t})[0];
    else
      th = Tanh<W>(v / v_t);
    phi[0] = g;
    phi[1] = th - tanh_sp * g;
    if (dphi) {
      const T gd = e * (1.0 - u * u) / v_sp;
      dphi[0] = gd;
      dphi[1] = (1.0 - th * th) / v_t - tanh_sp * gd;
    }
  }
  double v_sp, v_t, tanh_sp;
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_FRICTION_H_
