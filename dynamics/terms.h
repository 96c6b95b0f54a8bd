// The effect library: terms with stable ids, each a force on one body that is linear in its parameters,
// F = Σ θ_k φ_k(q, v), so that a model is a parameter vector over basis functions (fits by simulation,
// residual regressions and uncertainties all use the same φ). One model description (issue 42): the
// identification (identify/) fits these terms, and a sweep maps a model made of them in lanes
// (dynamics/term_model.h), with the same basis code.
//
// Bodies and coordinates (model.md §2): on the main body q = y = x − x0 (relative to the base, or the
// displacement itself under a force input), v = y'; on the resonator q = z = x_r − x, v = z'.
// Sign: the force is a restoring / dissipative force, subtracted in the equation of motion:
//   m_m x'' = −F_main(y, y') + G_res(z, z') [+ u],   m_r x_r'' = −G_res(z, z').
// So a positive stiffness or damping parameter opposes motion; `bias` is a constant force F = f_b
// (the body settles where the other forces balance −f_b).
//
//  id suffix      basis φ(q, v)                         parameter  unit      sign
//  linear         q                                      k_lin      N/m       either (bistable: < 0)
//  stiffness_y2   q²   (resonator: stiffness_z2)         k2         N/m²      either (asymmetric wells)
//  stiffness_y3   q³   (stiffness_z3)                    k3         N/m³      either
//  stiffness_y5   q⁵   (stiffness_z5)                    k5         N/m⁵      either
//  viscous        v                                      c0         N s/m     ≥ 0
//  damping_y2     q² v (damping_z2)                      c2         N s/m³    ≥ 0
//  damping_v3     v³                                     c3         N s³/m³   ≥ 0
//  drag           v |v|                                  cq         N s²/m²   ≥ 0
//  friction       g(v), tanh(v/v_t) − tanh(v_sp/v_t) g(v)  F_s, F_c  N        ≥ 0 (Stribeck: dynamics/friction.h's
//                 law and basis; g(v) = (v/v_sp) exp(1/2 − v²/2v_sp²); v_sp, v_t are known constants)
//  bias           1                                      f_b        N         either
//
// A term with its own state (main body only):
//  piezo          the piezoelectric transducer: a voltage state w with C_p w' + w/R + θ y' = 0 and the
//                 back-force −θ w on the beam (m y'' + … − θ w = −m a_base). Identifiable per unit of the
//                 main mass: a = θ/m_main · m_main = θ [N/V] (with m_main = 1: θ/m), b = 1/(R C_p) [1/s] (≥ 0),
//                 c = θ/C_p [V/m]: w' = −b w − c y', F = −a w. The model then predicts a voltage output
//                 (w); a coupling that damps the beam has a·c > 0 (an electrode polarity flips both signs).
//
// Output-side effects (on a measured output, not forces; ids out.<output>.offset / .scale, where
// <output> is the output's kind: displacement, velocity, analogue, resonator, voltage):
//  offset         output = model + d                     d          output unit  either
//  scale          output = (1 + g) model                 g          1            either (sensor gain error)
#ifndef BISTABLE_DYNAMICS_TERMS_H_
#define BISTABLE_DYNAMICS_TERMS_H_

#include <cmath>
#include <string>
#include <vector>

#include "base/status.h"
#include "dynamics/friction.h"

namespace bistable {

enum class Body { kMain, kResonator, kOutput };
enum class TermKind {
  kLinear,
  kStiffness2,
  kStiffness3,
  kStiffness5,
  kViscous,
  kDamping2,
  kDampingV3,
  kDrag,
  kFriction,
  kBias,
  kPiezo,
  kOutputOffset,
  kOutputScale
};
// The outputs a record may have: the main body's (the setup's output kind: displacement, velocity or
// analogue), the resonator's displacement and the piezo voltage. An output term names its output by kind.
enum class OutputSlot { kMain = 0, kResonator = 1, kVoltage = 2 };
constexpr int kOutputSlots = 3;
// The most parameters one term has (the piezo: a, b, c): basis buffers are this long.
constexpr int kMaxTermParams = 3;
enum class Sign { kEither, kNonNegative };

struct TermParam {
  std::string name;  // "k3", "F_s"
  std::string unit;  // "N/m^3"
  Sign sign = Sign::kEither;
};

struct TermDef {
  std::string id;  // "main.stiffness_y3"
  Body body = Body::kMain;
  TermKind kind = TermKind::kLinear;
  std::string formula;  // "k3 y^3"
  std::string meaning;  // one line for reports
  std::vector<TermParam> params;
  // Output terms (Body::kOutput): the output they act on, by its kind name ("velocity", "voltage", ...).
  std::string output;
  // A force term of the main or resonator body: F = Σ θ_k φ_k(q, v) (not the piezo nor an output term).
  bool IsForce() const { return body != Body::kOutput && kind != TermKind::kPiezo; }
};

// Every term of the library, main body first; ids are stable (used in specs, JSON and reports).
const std::vector<TermDef>& EffectLibrary();
// The term of an id; InvalidArgument naming the id and the nearest known one.
StatusOr<const TermDef*> FindTerm(const std::string& id);
// Parses "main.linear,main.stiffness_y3"; rejects unknown and repeated ids.
StatusOr<std::vector<const TermDef*>> ParseTerms(const std::string& list);

// Constants the basis functions need.
struct FrictionConstants {
  double v_sp = 0.002;  // m/s
  double v_t = 0.001;   // m/s
};

// The friction term's law (dynamics/friction.h) with these constants.
inline StribeckBasis FrictionBasis(const FrictionConstants& fc) { return StribeckBasis(fc.v_sp, fc.v_t); }

// Appends the term's basis values φ_k(q, v) (one per parameter) to `out`.
void TermBasis(const TermDef& t, double q, double v, const FrictionConstants& fc, double* out);
// The basis values and, when phi_q and phi_v are given, their derivatives ∂φ/∂q and ∂φ/∂v — the one
// switch over term kinds (simulation, sensitivities, regressions); `fb`: FrictionBasis(fc), constant per
// model, so that a simulation computes it once rather than per step. Inline: the simulator's inner loop.
// T is double or a lane pack Vec<W> (plain simulations of several parameter vectors side by side, with
// every lane's operations those of the double: -ffp-contract=off, the same bits).
template <class T>
BISTABLE_INLINE void TermBasisSlopes(const TermDef& t, T q, T v, const StribeckBasis& fb, T* phi, T* phi_q, T* phi_v) {
  const bool d = phi_q != nullptr;  // derivatives wanted (both or neither)
  const T zero{}, one = zero + 1.0;
  T dq = zero, dv = zero;
  switch (t.kind) {
    case TermKind::kLinear:
      phi[0] = q, dq = one;
      break;
    case TermKind::kStiffness2:
      phi[0] = q * q, dq = 2.0 * q;
      break;
    case TermKind::kStiffness3:
      phi[0] = q * q * q, dq = 3.0 * q * q;
      break;
    case TermKind::kStiffness5:
      phi[0] = q * q * q * q * q, dq = 5.0 * q * q * q * q;
      break;
    case TermKind::kViscous:
      phi[0] = v, dv = one;
      break;
    case TermKind::kDamping2:
      phi[0] = q * q * v, dq = 2.0 * q * v, dv = q * q;
      break;
    case TermKind::kDampingV3:
      phi[0] = v * v * v, dv = 3.0 * v * v;
      break;
    case TermKind::kDrag:
      phi[0] = v * AbsOf(v), dv = 2.0 * AbsOf(v);
      break;
    case TermKind::kFriction:
      fb.Eval(v, phi, d ? phi_v : nullptr);
      if (d) phi_q[0] = phi_q[1] = zero;
      return;
    case TermKind::kBias:
      phi[0] = one;
      break;
    case TermKind::kPiezo:  // no force of (q, v): the back-force needs the voltage state (model.cc)
      phi[0] = phi[1] = phi[2] = zero;
      if (d) phi_q[0] = phi_q[1] = phi_q[2] = phi_v[0] = phi_v[1] = phi_v[2] = zero;
      return;
    case TermKind::kOutputOffset:
    case TermKind::kOutputScale:
      phi[0] = zero;
      break;  // not a force
  }
  if (d) phi_q[0] = dq, phi_v[0] = dv;
}
// dF/dv and dF/dq of the term at (q, v) for parameters `theta` (its own slice), for step-size bounds.
void TermSlopes(const TermDef& t, const double* theta, double q, double v, const FrictionConstants& fc, double* dfdq,
                double* dfdv);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_TERMS_H_
