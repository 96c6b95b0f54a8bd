// A model made of effect-library terms (dynamics/terms.h) — what `bistable identify` fits — for the lane
// kernel (ensemble_generic.h): one model description for identification and sweeps (issue 42).
//
// State (y, y', z, z'): the main body relative to a sine base, the resonator relative to the main body,
// as the rig's (dimensional_model.h):
//   m_main y'' = −F(y, y') + G(z, z') − m_main a0,   m_res z'' = −G(z, z') − m_res (y'' + a0),
//   F = Σ θ_k φ_k(y, y') over the main body's terms, G over the resonator's; a0 = −A0 ω² sin(ω t).
// Each force is evaluated term by term in declaration order, in the lane form of the terms (below:
// coefficients per lane, checked against TermBasisSlopes, the identification simulator's basis). Parameters may differ
// per lane (a robustness sweep draws them per sample); the terms, masses and friction constants are lane 0's.
//
// Not here (yet): the piezo's voltage state and output terms (refused by ValidateTermModel), the
// Rosenbrock path (the friction basis has no curvature): term models integrate by RK4 with substeps from
// the Jacobian's spectral radius at rest (TermRk4Substeps), as the rig does under integrator = "rk4".
#ifndef BISTABLE_DYNAMICS_TERM_MODEL_H_
#define BISTABLE_DYNAMICS_TERM_MODEL_H_

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "base/status.h"
#include "dynamics/dimensional_model.h"
#include "dynamics/lanes.h"
#include "dynamics/point_spec.h"
#include "dynamics/terms.h"

namespace bistable {

struct TermModel {
  std::vector<const TermDef*> terms;  // force terms of the main body and the resonator, in declaration order
  std::vector<double> theta;          // their parameters, term by term (TermDef::params order)
  double m_main = 0;                  // kg
  double m_res = 0;                   // kg; needed when any res.* term is declared
  FrictionConstants fc;

  bool HasResonator() const;
  int NumParams() const;                        // Σ over terms of their parameter count
  std::vector<std::string> ParamNames() const;  // "main.linear.k_lin", ...
  std::vector<std::string> ParamUnits() const;  // "N/m", ...
  int IndexOf(const std::string& name) const;   // of a ParamNames() entry, −1 if none
  // The rig of the paper's Table 2 (or any DimensionalParams) as terms: linear, stiffness_y3, viscous,
  // damping_y2 and friction on each body (the resonator's without a cubic spring). InvalidArgument when the
  // two bodies' friction laws have different v_sp or v_t (a term model has one pair).
  static StatusOr<TermModel> FromDimensional(const DimensionalParams& p);
  // A cell of the paper's non-dimensional models (standalone, coupled, linear, linear-coupled; docs/model.md) as
  // terms, in its own units (time τ, lengths in δ-units, masses per m_m): main.linear −1 (+1 for a linear beam),
  // main.stiffness_y3 ε (bistable), main.viscous η, and with the resonator (z = y_r − y_m, m_res = φ)
  // res.linear φλ², res.viscous φη_r. A term sweep at a0_mm = 1000 α, f0_hz = Ω/2π then runs the cell's point.
  // Series chains are not two-body models (N bodies in a row): InvalidArgument, as for the dimensional rig
  // (FromDimensional).
  static StatusOr<TermModel> FromCell(ModelKind kind, const NondimParams& p);
};

// Refuses what the lane model cannot run: no terms, a term that is not a force of the main body or the
// resonator (piezo, output terms), a parameter count that does not match, masses not positive and finite
// (m_res only with resonator terms), friction constants not positive. The field named is `terms`,
// `theta`, `m_main`, `m_res` or `friction`.
Status ValidateTermModel(const TermModel& m);

// F (main body) or G (resonator) of a term model at (q, v) with parameters th, and its slopes.
void TermForce(const TermModel& m, Body body, const double* th, double q, double v, double* f, double* fq, double* fv);
// The rest states of the main body: the origin and every zero of F(q, 0) found on a log grid of |q| from
// 1 µm to 1 km (bisected to 1e-9 relative), ascending.
std::vector<double> TermRestStates(const TermModel& m, const double* th);
// The positive well: the smallest positive rest state where ∂F/∂q > 0 (a stable equilibrium), 0 when there is
// none (a monostable model; its lanes start at the origin).
double TermWell(const TermModel& m, const double* th);
// RK4 steps per output step dt: the Jacobian's spectral radius ρ at the rest states (the origin and every
// zero of F(q, 0) found on a log grid of |q| from 1 µm to 1 km), h ≤ 2/ρ — the rig's rule (Rk4Substeps).
int TermRk4Substeps(const TermModel& m, const double* th, double dt);

// The lane kernel's form of a term (TermLaneModel): per lane, a few coefficients made from the term's
// parameters once (at Load), so that a step evaluates the force and its slopes in the hand kernel's operations
// rather than as θ·φ over TermBasisSlopes' basis (which divides by v_sp and v_t and multiplies every slope,
// zeros included: 0.64x the hand rig kernel's lane-steps/s). Coefficients k by kind: linear, viscous, bias θ;
// stiffness_y2, damping_y2, drag θ, 2θ; stiffness_y3, damping_v3 θ, 3θ; stiffness_y5 θ, 5θ; friction
// (F_s − F_c tanh(v_sp/v_t))/v_sp, twice that, F_c, F_c/v_t (dynamics/friction.h's law, per lane). The two
// forms agree to rounding (TermModel.TheLaneFormIsTheBasisForm).
inline constexpr int kMaxTermLaneCoefficients = 4;
struct TermLaneFriction {
  explicit TermLaneFriction(const FrictionConstants& fc)
      : v_sp(fc.v_sp),
        v_t(fc.v_t),
        inv_vt(1.0 / fc.v_t),
        neg_half_inv_vsp2(-0.5 / (fc.v_sp * fc.v_sp)),
        tanh_sp(std::tanh(fc.v_sp / fc.v_t)) {}
  double v_sp, v_t, inv_vt, neg_half_inv_vsp2, tanh_sp;
};
int TermLaneCoefficients(TermKind kind);
void TermLaneCoefficientValues(TermKind kind, const double* theta, const TermLaneFriction& fric, double* k);

// One lane of a term-model sweep (ensemble_generic.h): a sine base x0 = A0 sin(ω t), or (force) a force
// F0 sin(ω t) on the main body with the base at rest; output cell y, y'.
struct TermLaneInput {
  double amp = 0, omega = 0, base_amp = 0;  // A0 ω² [m/s²] (force: F0/m_main), ω [rad/s], A0 [m] (force: 0)
  bool force = false;                       // amp drives the main body alone (the resonator feels it through y'')
  const TermModel* model = nullptr;         // the structure every lane shares (lane 0's)
  const double* theta = nullptr;            // this lane's parameters (model->NumParams()); null: model->theta
  std::array<double, 4> x0 = {0, 0, 0, 0};
};

struct TermLaneModel {
  static constexpr int kDim = 4;
  using Input = TermLaneInput;

  template <int W>
  class Lanes {
   public:
    using V = Vec<W>;
    using Jac = TwoBodyJac<W, Lanes>;

    explicit Lanes(const Input& in)
        : fric_(in.model->fc),
          inv_m_m_(1.0 / in.model->m_main),
          inv_m_r_(in.model->HasResonator() ? 1.0 / in.model->m_res : 0.0),
          res_(in.model->HasResonator()),
          force_(in.force) {
      int offset = 0, coef = 0;
      for (const TermDef* t : in.model->terms) {
        (t->body == Body::kMain ? main_ : resonator_).push_back({t->kind, offset, coef});
        offset += static_cast<int>(t->params.size());
        coef += TermLaneCoefficients(t->kind);
      }
      k_.resize(coef);
    }
    int dim() const { return kDim; }
    int tangent_dims() const { return res_ ? 4 : 2; }
    void Load(int l, const Input& in) {
      const double* th = in.theta ? in.theta : in.model->theta.data();
      for (const std::vector<Term>* body : {&main_, &resonator_})
        for (const Term& t : *body) {
          double c[kMaxTermLaneCoefficients];
          TermLaneCoefficientValues(t.kind, th + t.offset, fric_, c);
          for (int i = 0; i < TermLaneCoefficients(t.kind); ++i) k_[t.coef + i][l] = c[i];
        }
    }

    BISTABLE_INLINE void Eval(const V* x, V f, V* dx, Jac* j) const {
      const V y = x[0], yd = x[1];
      V force, fq, fv;
      Force(main_, y, yd, &force, &fq, &fv);
      j->fy = -fq, j->fyd = -fv;
      V g = Splat<W>(0.0);
      if (res_) {
        Force(resonator_, x[2], x[3], &g, &j->gz, &j->gzd);
      } else {
        j->gz = j->gzd = g;
      }
      const V fm = (g - force) * inv_m_m_;
      dx[0] = yd;
      dx[1] = fm + f;  // f = −(base acceleration)
      if (res_) {      // z'' = −G/m_res − (y'' + base acceleration): −fm under a base, −(fm + f) under a force
        dx[2] = x[3];
        dx[3] = Fma(-g, Splat<W>(inv_m_r_), force_ ? -(fm + f) : -fm);
      } else {
        dx[2] = dx[3] = g;
      }
    }
    BISTABLE_INLINE void Apply(const Jac& j, const V* w, V* dw) const {
      TwoBodyApply<W>(j, w, dw, inv_m_m_, inv_m_r_, res_);
    }
    BISTABLE_INLINE void Output(const V* x, const V* dx, V* out, V* dout) const {
      out[0] = x[0], out[1] = x[1], dout[0] = dx[0], dout[1] = dx[1];
    }

   private:
    struct Term {
      TermKind kind;
      int offset;  // of its first parameter in the model's θ
      int coef;    // of its first coefficient in k_
    };
    // F = Σ over a body's terms and its slopes ∂F/∂q, ∂F/∂v, in declaration order, each term as a force from
    // its per-lane coefficients (TermLaneCoefficientValues): the hand kernel's operations, not θ·φ.
    BISTABLE_INLINE void Force(const std::vector<Term>& terms, V q, V v, V* f, V* fq, V* fv) const {
      V sum = Splat<W>(0.0), sq = sum, sv = sum;
      for (const Term& t : terms) {
        const V* k = &k_[t.coef];
        switch (t.kind) {
          case TermKind::kLinear:
            sum = Fma(k[0], q, sum), sq = sq + k[0];
            break;
          case TermKind::kStiffness2:
            sum = Fma(k[0] * q, q, sum), sq = Fma(k[1], q, sq);
            break;
          case TermKind::kStiffness3: {
            const V q2 = q * q;
            sum = Fma(k[0] * q2, q, sum), sq = Fma(k[1], q2, sq);
            break;
          }
          case TermKind::kStiffness5: {
            const V q2 = q * q, q4 = q2 * q2;
            sum = Fma(k[0] * q4, q, sum), sq = Fma(k[1], q4, sq);
            break;
          }
          case TermKind::kViscous:
            sum = Fma(k[0], v, sum), sv = sv + k[0];
            break;
          case TermKind::kDamping2: {
            const V kq2 = k[0] * (q * q);
            sum = Fma(kq2, v, sum), sq = Fma(k[1] * q, v, sq), sv = sv + kq2;
            break;
          }
          case TermKind::kDampingV3: {
            const V v2 = v * v;
            sum = Fma(k[0] * v2, v, sum), sv = Fma(k[1], v2, sv);
            break;
          }
          case TermKind::kDrag: {
            const V av = AbsOf(v);
            sum = Fma(k[0] * v, av, sum), sv = Fma(k[1], av, sv);
            break;
          }
          case TermKind::kFriction: {  // the rig's law with a per-lane hump scale and Coulomb level
            V ff, fs;
            StribeckLawLanes<W>(v, k[0], k[1], k[2], k[3], fric_.neg_half_inv_vsp2, fric_.inv_vt, &ff, &fs);
            sum = sum + ff, sv = sv + fs;
            break;
          }
          case TermKind::kBias:
            sum = sum + k[0];
            break;
          default:  // piezo and output terms: refused by ValidateTermModel
            break;
        }
      }
      *f = sum, *fq = sq, *fv = sv;
    }

    TermLaneFriction fric_;
    double inv_m_m_, inv_m_r_;
    bool res_, force_;
    std::vector<Term> main_, resonator_;
    std::vector<V> k_;  // per coefficient, the lanes' values
  };
};

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_TERM_MODEL_H_
