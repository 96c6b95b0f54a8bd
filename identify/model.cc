#include "identify/model.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <type_traits>

#include <Eigen/Dense>

#include "dynamics/cancel.h"
#include "dynamics/lanes.h"
#include "dynamics/rk4.h"

namespace bistable {

int IdentModel::PiezoIndex() const {
  int k = 0;
  for (const TermDef* t : terms) {
    if (t->kind == TermKind::kPiezo) return k;
    k += static_cast<int>(t->params.size());
  }
  return -1;
}

bool IdentModel::HasResonator() const {
  for (const TermDef* t : terms)
    if (t->body == Body::kResonator) return true;
  return false;
}

int IdentModel::NumTermParams() const {
  int n = 0;
  for (const TermDef* t : terms) n += static_cast<int>(t->params.size());
  return n;
}

int IdentModel::NumParams() const { return NumTermParams() + (FitsMass() ? 1 : 0) + offsets; }

std::vector<std::string> IdentModel::ParamNames() const {
  std::vector<std::string> out;
  for (const TermDef* t : terms)
    for (const TermParam& p : t->params) out.push_back(t->id + "." + p.name);
  if (FitsMass()) out.push_back("m_main");
  for (int k = 0; k < offsets; ++k) out.push_back("offset." + std::to_string(k));
  return out;
}

std::vector<std::string> IdentModel::ParamUnits() const {
  std::vector<std::string> out;
  for (const TermDef* t : terms)
    for (const TermParam& p : t->params) out.push_back(p.unit);
  if (FitsMass()) out.push_back("kg");
  for (int k = 0; k < offsets; ++k) out.push_back("m");
  return out;
}

std::vector<Sign> IdentModel::ParamSigns() const {
  std::vector<Sign> out;
  for (const TermDef* t : terms)
    for (const TermParam& p : t->params) out.push_back(p.sign);
  if (FitsMass()) out.push_back(Sign::kNonNegative);
  for (int k = 0; k < offsets; ++k) out.push_back(Sign::kEither);
  return out;
}

int IdentModel::Offset(const TermDef* t) const {
  int k = 0;
  for (const TermDef* u : terms) {
    if (u == t) return k;
    k += static_cast<int>(u->params.size());
  }
  return -1;
}

double IdentModel::Force(Body body, const std::vector<double>& th, double q, double v) const {
  double f = 0, phi[kMaxTermParams];
  int k = 0;
  for (const TermDef* t : terms) {
    const int np = static_cast<int>(t->params.size());
    if (t->body == body) {
      TermBasis(*t, q, v, fc, phi);
      for (int j = 0; j < np; ++j) f += th[k + j] * phi[j];
    }
    k += np;
  }
  return f;
}

IdentModel IdentModel::With(const TermDef* t, const std::vector<double>& initial) const {
  IdentModel m = *this;
  const int nt = NumTermParams();
  std::vector<double> th(theta.begin(), theta.begin() + nt);
  th.insert(th.end(), initial.begin(), initial.end());
  th.insert(th.end(), theta.begin() + nt, theta.end());  // m_main, offsets
  m.terms.push_back(t);
  m.theta = th;
  return m;
}

namespace {

// Bounds of the largest rates along the measured range: damping-like λ ≥ |∂a/∂v| and stiffness-like
// ω² ≥ |∂a/∂q| (sums over the terms of their largest slopes on a grid of the measured range), and the
// RK4 substeps per sample that keep h λ ≤ lam_limit and h ω ≤ om_limit.
int SubstepsWithin(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r, double lam_limit,
                   double om_limit) {
  const double mm = std::max(std::abs(m.Mass(th)), 1e-300);
  double dv_main = 0, dq_main = 0, dv_res = 0, dq_res = 0;
  const double qs[] = {0.0, 0.5 * r.p_range, r.p_range, 1.5 * r.p_range};
  const double vs[] = {0.0, 0.5 * r.v_range, r.v_range, 1.5 * r.v_range};
  int k = 0;
  for (const TermDef* t : m.terms) {
    double tq = 0, tv = 0;
    for (double q : qs)
      for (double v : vs) {
        double a, b;
        TermSlopes(*t, &th[k], q, v, m.fc, &a, &b);
        tq = std::max(tq, std::abs(a));
        tv = std::max(tv, std::abs(b));
      }
    if (t->body == Body::kMain)
      dq_main += tq, dv_main += tv;
    else
      dq_res += tq, dv_res += tv;
    k += static_cast<int>(t->params.size());
  }
  double lam = dv_main / mm, om2 = dq_main / mm;
  const int pz = m.PiezoIndex();  // the circuit's rate b; the coupling's stiffness a c (w ≈ −c y when b is slow)
  if (pz >= 0) lam += std::abs(th[pz + 1]), om2 += std::abs(th[pz] * th[pz + 2]) / mm;
  if (m.HasResonator() && m.m_res > 0) {
    lam += dv_res * (1.0 / m.m_res + 1.0 / mm);
    om2 += dq_res * (1.0 / m.m_res + 1.0 / mm);
  }
  const double h_max = std::min(lam_limit / std::max(lam, 1e-300), om_limit / std::sqrt(std::max(om2, 1e-300)));
  const double steps = std::ceil(r.dt / h_max);
  if (std::isnan(steps)) return 1;  // non-finite parameters: the simulation refuses them (SimulateImpl)
  return static_cast<int>(std::clamp(steps, 1.0, 2000.0));
}

}  // namespace

// RK4 is stable for h λ < 2.785 on the real axis; h λ ≤ 2 keeps a margin, h ω ≤ 0.5 the accuracy.
int SubstepsFor(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r) {
  return SubstepsWithin(m, th, r, 2.0, 0.5);
}

// RK4's stability limits are 2.785 (real axis) and 2.83 (imaginary axis); 2.5 for both keeps a margin.
int StableSubsteps(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r) {
  return SubstepsWithin(m, th, r, 2.5, 2.5);
}

int AccurateSubsteps(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r) {
  return SubstepsWithin(m, th, r, 2.5, 0.5);
}

int OscillationSubsteps(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r) {
  return SubstepsWithin(m, th, r, INFINITY, 0.5);
}

namespace {

// One term of a simulation: its definition and first parameter column (model terms at their place in
// ParamNames; candidate terms after all the model's parameters, at value 0).
struct SimTerm {
  const TermDef* t;
  int col;
};

// The columns of the non-force terms of a simulation (model terms, then the candidates'): the piezo's
// a, b, c and, per output slot, the offset d and the scale g (−1 where absent).
struct SpecialCols {
  int piezo = -1;
  int offset[kOutputSlots] = {-1, -1, -1}, scale[kOutputSlots] = {-1, -1, -1};
  bool AnyOutputTerm() const {
    for (int k = 0; k < kOutputSlots; ++k)
      if (offset[k] >= 0 || scale[k] >= 0) return true;
    return false;
  }
};

SpecialCols FindSpecialCols(const IdentModel& m, const std::vector<const TermDef*>& extra, const Setup* setup) {
  SpecialCols sc;
  int col = 0;
  auto visit = [&](const TermDef* t) {
    if (t->kind == TermKind::kPiezo) sc.piezo = col;
    if (t->body == Body::kOutput && setup) {
      const int slot = OutputSlotOf(*t, *setup);
      if (slot >= 0) (t->kind == TermKind::kOutputOffset ? sc.offset : sc.scale)[slot] = col;
    }
    col += static_cast<int>(t->params.size());
  };
  for (const TermDef* t : m.terms) visit(t);
  col = m.NumParams();
  for (const TermDef* t : extra) visit(t);
  return sc;
}

// The terms' coordinates from the state (p, p', r, r') and the input (u, u'): the main body's y, y' (relative
// to the base under a base displacement) and the resonator's z, z' (0 without one). T: double or a lane pack.
template <class T>
BISTABLE_INLINE void BodyCoordinates(InputKind in, bool res, T p, T pd, T r, T rd, double u, double ud, T* y, T* yd,
                                     T* z, T* zd) {
  const bool disp = in == InputKind::kBaseDisplacement;
  *y = disp ? p - u : p, *yd = disp ? pd - ud : pd;
  *z = res ? (disp ? r - p : r) : T{}, *zd = res ? (disp ? rd - pd : rd) : T{};
}

// p'' and r'' (a₁, a₃) from the main body's force F and the resonator's G under the record's input u;
// `inv`: the part divided by the main mass (its derivative by m_main is −inv/m). T: double or a lane pack.
template <class T>
BISTABLE_INLINE void Accelerations(InputKind in, bool res, T F, T G, double u, T mm, double mr, T* a1, T* a3, T* inv) {
  switch (in) {
    case InputKind::kBaseDisplacement:
      *a1 = *inv = (-F + G) / mm;
      *a3 = res ? -G / mr : *a1;
      return;
    case InputKind::kBaseAcceleration:
      *inv = (-F + G) / mm;
      *a1 = *inv - u;
      *a3 = res ? -G / mr - *inv : T{};
      return;
    case InputKind::kForce:
      *a1 = *inv = (u - F + G) / mm;
      *a3 = res ? -G / mr - *a1 : T{};
      return;
  }
  *a1 = *a3 = *inv = T{};
}

// A record's equations of motion (model.h) as a System for dynamics/rk4.h. The state is (p, p', r, r')
// and, with a piezo (kD = 5), the voltage w. Without sensitivities it is of fixed size, so that stepping
// allocates nothing (Simulate is the hot loop of identification). With them (kSens) it is that state
// followed by the sensitivity columns (∂p, ∂p', ∂r, ∂r'[, ∂w])/∂θ_j, one per parameter: the variational
// equations S' = (∂f/∂x) S + ∂f/∂θ_j, integrated by the same RK4 steps, so that the columns are the exact
// derivative of the discrete simulation. Force terms are linear in their parameters, so ∂F/∂θ_j is the
// basis value φ_j, already computed for F; the piezo's a multiplies −w, its b and c the circuit's w and y'.
// The columns are stored component-major (SensIndex: every column's ∂p, then every column's ∂p', ...,
// padded to whole packs), so that one branch-free loop runs over the columns in SIMD packs; the few
// columns with a term of their own beyond φ (the mass, the piezo's b and c) take it from a column array.
template <bool kSens, int kD>
class RecordSystem {
 public:
  using State = std::conditional_t<kSens, Eigen::VectorXd, Eigen::Matrix<double, kD, 1>>;
  // `param_cols` false: no parameter columns; `state_cols` (0 or kD): columns ∂x/∂x(t_k) of the segment's
  // start state after the parameters' (multiple shooting, SegmentStates).
  RecordSystem(const IdentModel& m, const std::vector<double>& th, const std::vector<const TermDef*>& extra,
               const PreparedRecord& r, InputKind in, bool param_cols = true, int state_cols = 0)
      : r_(r), in_(in), res_(m.HasResonator()), mm_(m.Mass(th)), mr_(m.m_res), fb_(FrictionBasis(m.fc)), th_(th) {
    int col = 0;
    for (const TermDef* t : m.terms) {
      if (t->IsForce()) terms_.push_back({t, col});
      col += static_cast<int>(t->params.size());
    }
    cols_ = m.NumParams();
    mass_col_ = m.FitsMass() ? m.NumTermParams() : -1;
    if constexpr (kSens) {
      for (const TermDef* t : extra) {
        if (t->IsForce()) terms_.push_back({t, cols_});
        cols_ += static_cast<int>(t->params.size());
      }
    }
    th_.resize(cols_, 0.0);
    piezo_col_ = FindSpecialCols(m, kSens ? extra : std::vector<const TermDef*>{}, nullptr).piezo;
    // φ_j on the main body (phi_main_) or the resonator (phi_res_); 0 for columns without a force term
    // there (the other body's, the mass, offsets, b, c, output terms, state columns), never written.
    first_ = param_cols ? 0 : cols_;
    end_ = cols_ + state_cols;
    stride_ = (end_ - first_ + kW - 1) / kW * kW;
    phi_main_.assign(first_ + stride_, 0.0);
    phi_res_.assign(first_ + stride_, 0.0);
    own_a_.assign(first_ + stride_, 0.0);
    own_w_.assign(first_ + stride_, 0.0);
  }
  int dim() const { return kSens ? kD + kD * stride_ : kD; }
  int cols() const { return cols_; }
  // Position in the state of component c of held sensitivity column l (0 ≤ l < end − first).
  int SensIndex(int c, int l) const { return kD + c * stride_ + l; }
  BISTABLE_INLINE void operator()(double t, const State& x, State& dx) const {
    // RK4's second and third stages are at the same time: the input is evaluated once for both.
    if (t != input_t_) r_.in_spline.Eval(t, &input_u_, &input_ud_), input_t_ = t;
    const double u = input_u_, ud = input_ud_;
    double y, yd, z, zd;
    BodyCoordinates(in_, res_, x[0], x[1], x[2], x[3], u, ud, &y, &yd, &z, &zd);
    double F = 0, Fq = 0, Fv = 0, G = 0, Gq = 0, Gv = 0;
    double phi[kMaxTermParams], pq[kMaxTermParams], pv[kMaxTermParams];
    for (const SimTerm& st : terms_) {
      const bool main = st.t->body == Body::kMain;
      if (!main && !res_) continue;
      TermBasisSlopes(*st.t, main ? y : z, main ? yd : zd, fb_, phi, kSens ? pq : nullptr, kSens ? pv : nullptr);
      double f = 0, fq = 0, fv = 0;
      double* phi_col = main ? phi_main_.data() : phi_res_.data();
      for (size_t j = 0; j < st.t->params.size(); ++j) {
        const double th = th_[st.col + j];
        f += th * phi[j];
        if constexpr (kSens) fq += th * pq[j], fv += th * pv[j], phi_col[st.col + j] = phi[j];
      }
      if (main)
        F += f, Fq += fq, Fv += fv;
      else
        G += f, Gq += fq, Gv += fv;
    }
    // The piezo: back-force −a w on the main body, circuit w' = −b w − c y'.
    double w = 0, wdot = 0, pa = 0, pb = 0, pc = 0;
    if constexpr (kD == 5) {
      w = x[4];
      if (piezo_col_ >= 0) {
        pa = th_[piezo_col_], pb = th_[piezo_col_ + 1], pc = th_[piezo_col_ + 2];
        F += -pa * w;
        wdot = -pb * w - pc * yd;
        if constexpr (kSens) phi_main_[piezo_col_] = -w;
      }
    }
    // p'' and r''; `inv`: the part divided by the main mass.
    double a1, a3, inv;
    Accelerations(in_, res_, F, G, u, mm_, mr_, &a1, &a3, &inv);
    if constexpr (!kSens) {
      // dx written whole: one vector store, which the integrator's next vector load of dx can forward
      // (four scalar stores cannot be, and cost ~4 % of the simulation).
      if constexpr (kD == 4)
        dx = State(x[1], a1, x[3], a3);
      else
        dx << x[1], a1, x[3], a3, wdot;
    } else {
      dx[0] = x[1], dx[1] = a1, dx[2] = x[3], dx[3] = a3;
      if constexpr (kD == 5) dx[4] = wdot;
      // The columns with a term beyond φ: ∂/∂m_main of (−F + G)/m is −inv/m; ∂w'/∂b = −w, ∂w'/∂c = −y'.
      if (Held(mass_col_)) own_a_[mass_col_] = inv / mm_;
      if (piezo_col_ >= 0 && Held(piezo_col_ + 1)) own_w_[piezo_col_ + 1] = w;
      if (piezo_col_ >= 0 && Held(piezo_col_ + 2)) own_w_[piezo_col_ + 2] = yd;
      const Coefs k{Fq, Fv, Gq, Gv, pa, pb, pc, piezo_col_ >= 0};
      if (in_ == InputKind::kBaseDisplacement)
        res_ ? Columns<true, true>(k, x, dx) : Columns<true, false>(k, x, dx);
      else
        res_ ? Columns<false, true>(k, x, dx) : Columns<false, false>(k, x, dx);
    }
  }

 private:
  // The stage's slopes of the forces and the piezo's values, shared by every column.
  struct Coefs {
    double Fq, Fv, Gq, Gv, pa, pb, pc;
    bool piezo;
  };
  bool Held(int j) const { return j >= first_ && j < end_; }
  // Every held column in packs of kW (the stride is a multiple of kW; padding columns stay 0), lane by lane
  // the operations of the scalar column loop this replaced (-ffp-contract=off: the same bits). A column's own
  // term (own_a_, own_w_) is 0 but for the mass's and the piezo's b and c, and x − (+0) is x to the bit.
  template <bool kDisp, bool kRes>
  void Columns(const Coefs& k, const State& x, State& dx) const {
    using V = Vec<kW>;
    auto load = [](const double* p) {
      V v;
      std::memcpy(&v, p, sizeof v);
      return v;
    };
    auto store = [](double* p, const V& v) { std::memcpy(p, &v, sizeof v); };
    const int N = stride_;
    const V Fq = Splat<kW>(k.Fq), Fv = Splat<kW>(k.Fv), Gq = Splat<kW>(k.Gq), Gv = Splat<kW>(k.Gv);
    const V pa = Splat<kW>(k.pa), pb = Splat<kW>(k.pb), pc = Splat<kW>(k.pc);
    const V mm = Splat<kW>(mm_), mr = Splat<kW>(mr_);
    const double* phi_f = phi_main_.data() + first_;
    const double* phi_g = phi_res_.data() + first_;
    const double* own_a = own_a_.data() + first_;
    const double* own_w = own_w_.data() + first_;
    const double* S = x.data() + kD;
    double* D = dx.data() + kD;
    for (int l = 0; l < N; l += kW) {
      const V dy = load(S + l), dyd = load(S + N + l);
      const V dz = kDisp ? load(S + 2 * N + l) - dy : load(S + 2 * N + l);
      const V dzd = kDisp ? load(S + 3 * N + l) - dyd : load(S + 3 * N + l);
      V dF = Fq * dy + Fv * dyd + load(phi_f + l);
      const V dG = kRes ? Gq * dz + Gv * dzd + load(phi_g + l) : V{};
      if constexpr (kD == 5) {
        const V dw = load(S + 4 * N + l);
        dF += -pa * dw;
        store(D + 4 * N + l, k.piezo ? -pb * dw - pc * dyd - load(own_w + l) : V{});
      }
      const V dinv = (-dF + dG) / mm - load(own_a + l);
      V da3;
      if constexpr (kDisp)
        da3 = kRes ? -dG / mr : dinv;
      else
        da3 = kRes ? -dG / mr - dinv : V{};
      store(D + l, dyd);
      store(D + N + l, dinv);
      store(D + 2 * N + l, load(S + 3 * N + l));
      store(D + 3 * N + l, da3);
    }
  }

  const PreparedRecord& r_;
  const InputKind in_;
  const bool res_;
  const double mm_, mr_;
  const StribeckBasis fb_;
  std::vector<double> th_;      // the model's values, then 0 for candidate columns
  std::vector<SimTerm> terms_;  // force terms
  int cols_ = 0, mass_col_ = -1, piezo_col_ = -1;
  int first_ = 0, end_ = 0;     // sensitivity columns held: [first_, end_) (state columns from cols_)
  static constexpr int kW = 4;  // columns per pack
  int stride_ = 0;              // end_ − first_ rounded up to packs: the state's stride per component
  mutable std::vector<double> phi_main_, phi_res_;  // basis value of every term column at the current stage
  mutable std::vector<double> own_a_, own_w_;       // a column's own term in p'' and in w' (the mass; the piezo's b, c)
  mutable double input_t_ = NAN, input_u_ = 0, input_ud_ = 0;  // the input and its slope at time input_t_
};

// The main output's value at sample i from its state component (`s_oc`, SimulateImpl's oc): relative to the
// base, or with the base's velocity added, as the setup's frame asks.
double MainOutputValue(const PreparedRecord& r, const Setup& setup, double s_oc, size_t i) {
  double value = s_oc;
  if (setup.input == InputKind::kBaseDisplacement) {
    if (setup.frame == OutputFrame::kRelative) value -= r.base_x[i];
  } else if (setup.output == OutputKind::kVelocity && setup.input == InputKind::kBaseAcceleration &&
             setup.frame == OutputFrame::kAbsolute) {
    value += r.base_v[i];
  }
  return value;
}

// The bound on |p| past which a simulation counts as diverged (100 × the record's range, offset included).
double DivergenceLimit(const PreparedRecord& r, double offset) {
  return 100.0 * (r.p_range + std::abs(r.ic_p[0]) + std::abs(offset)) + 1e-12;
}

// The state component the main output reads (before MainOutputValue): p' for a velocity output under an
// acceleration or force input, else p.
int MainStateComponent(const Setup& setup) {
  return setup.input != InputKind::kBaseDisplacement && setup.output == OutputKind::kVelocity ? 1 : 0;
}

// Output slot k's effects on a model value: (1 + g) value + d (g, d: θ at the slot's scale and offset columns).
double WithOutputEffects(const SpecialCols& sc, const std::vector<double>& thx, int k, double value) {
  const double g = sc.scale[k] >= 0 ? thx[sc.scale[k]] : 0.0, d = sc.offset[k] >= 0 ? thx[sc.offset[k]] : 0.0;
  return (1.0 + g) * value + d;
}

// A simulation's outputs and their sensitivity rows at sample i (SimulateImpl's emit): the main output (state
// component oc, MainOutputValue), the resonator's (s[2], plus s[0] when res_plus_p), the voltage (the piezo's state, 0
// without a piezo), each with its output effects; and the early stop's running error.
template <bool kSens, int kD, class Sys>
struct OutputRows {
  const PreparedRecord& r;
  const Setup& setup;
  const SpecialCols& sc;
  const std::vector<double>& thx;
  const Sys& sys;
  typename Sys::State& s;
  SimOutputs* so;
  EarlyStop* stop;
  int P, SC, oc;
  bool res, res_plus_p, any_output_term;

  // Component c of sensitivity column j (parameters 0 … P − 1, then the state columns).
  double& sens(int c, int j) const { return s[sys.SensIndex(c, j)]; }
  // Output effects of slot k on a model value (and its sensitivity row): (1 + g) value + d.
  double output_effects(int k, size_t i, double value) const {
    if (!any_output_term) return value;
    const double g = sc.scale[k] >= 0 ? thx[sc.scale[k]] : 0.0;
    if constexpr (kSens) {
      if (sc.scale[k] >= 0) {
        for (int j = 0; j < P; ++j) so->d[k](static_cast<long>(i), j) *= 1.0 + g;
        for (int j = 0; j < SC; ++j) so->ds[k](static_cast<long>(i), j) *= 1.0 + g;
        if (P > 0) so->d[k](static_cast<long>(i), sc.scale[k]) = value;
      }
      if (sc.offset[k] >= 0 && P > 0) so->d[k](static_cast<long>(i), sc.offset[k]) = 1.0;
    }
    return WithOutputEffects(sc, thx, k, value);
  }
  // Row i of slot k's sensitivities: component c of every column, plus component c2 when c2 >= 0.
  void sens_row(int k, size_t i, int c, int c2) const {
    if constexpr (kSens) {
      for (int j = 0; j < P; ++j) so->d[k](static_cast<long>(i), j) = sens(c, j) + (c2 >= 0 ? sens(c2, j) : 0.0);
      for (int j = 0; j < SC; ++j)
        so->ds[k](static_cast<long>(i), j) = sens(c, P + j) + (c2 >= 0 ? sens(c2, P + j) : 0.0);
    }
  }
  void Emit(size_t i) const {
    double value = MainOutputValue(r, setup, s[oc], i);
    sens_row(0, i, oc, -1);
    value = output_effects(0, i, value);
    so->out[0][i] = value;
    if (stop) {
      const double d = (value - (*stop->meas)[i]) * stop->w;
      stop->sse += d * d;
      stop->stopped = stop->sse > stop->budget;
    }
    if (!so->out[1].empty() && res) {
      sens_row(1, i, 2, res_plus_p ? 0 : -1);
      so->out[1][i] = output_effects(1, i, res_plus_p ? s[2] + s[0] : s[2]);
    }
    if (!so->out[2].empty()) {  // the voltage: the piezo's state, 0 without a piezo
      double w = 0;
      if constexpr (kD == 5) {
        w = s[4];
        sens_row(2, i, 4, -1);
      } else if constexpr (kSens) {
        if (P > 0) so->d[2].row(static_cast<long>(i)).setZero();
      }
      so->out[2][i] = output_effects(2, i, w);
    }
  }
};

template <bool kSens, int kD>
bool SimulateImpl(const IdentModel& m, const std::vector<double>& th, const std::vector<const TermDef*>& extra,
                  const PreparedRecord& r, const Setup& setup, int substeps, int restart_every, SimOutputs* so,
                  EarlyStop* stop = nullptr, const SegmentStates* seg = nullptr) {
  const size_t n = r.n();
  for (int k = 0; k < kOutputSlots; ++k) so->out[k].clear(), so->d[k].resize(0, 0), so->ds[k].resize(0, 0);
  for (int k = 0; k < kOutputSlots; ++k)
    if (r.Has(static_cast<OutputSlot>(k))) so->out[k].assign(n, NAN);
  const double mm = m.Mass(th);
  if (!(mm > 0) || !std::isfinite(mm)) return false;
  for (double v : th)
    if (!std::isfinite(v)) return false;
  const bool res = m.HasResonator();
  if (res && !(m.m_res > 0)) return false;
  const int ns = substeps > 0 ? substeps : SubstepsFor(m, th, r);
  const double h = r.dt / ns;
  const InputKind in = setup.input;
  // Multiple shooting with given segment states (and their sensitivity columns).
  const std::vector<double>* given = seg && restart_every > 0 ? seg->states : nullptr;
  if (given && given->size() != NumSegments(n, restart_every) * kStateDim) return false;
  const std::vector<char>* active = given ? seg->active : nullptr;
  if (active && active->size() != NumSegments(n, restart_every)) return false;
  const bool pcols = !seg || seg->parameters;
  const int SC = kSens && seg && seg->sensitivities ? kD : 0;  // state columns
  using Sys = RecordSystem<kSens, kD>;
  const Sys sys(m, th, extra, r, in, pcols, SC);
  const int P = kSens && pcols ? sys.cols() : 0;
  const SpecialCols sc = FindSpecialCols(m, extra, &setup);
  std::vector<double> thx = th;  // the model's values, then 0 for candidate columns
  thx.resize(std::max<size_t>(thx.size(), static_cast<size_t>(sys.cols())), 0.0);
  if constexpr (kSens) {
    for (int k = 0; k < kOutputSlots; ++k)
      if (r.Has(static_cast<OutputSlot>(k))) {
        if (pcols) so->d[k].setConstant(static_cast<long>(n), P, NAN);
        if (SC > 0) so->ds[k].setZero(static_cast<long>(n), kStateDim);
      }
  }
  // State (p, p', r, r'[, w]); initial values from the smoothed measurement (w: the measured voltage, or 0).
  const double offset = m.Offset(th, r.index);
  const int offset_col = pcols && m.offsets > 0 && r.index >= 0 && r.index < m.offsets ? m.OffsetIndex(r.index) : -1;
  const bool volt_meas = !r.ic_w.empty();
  typename Sys::State s;
  if constexpr (kSens) s.resize(sys.dim());
  s.setZero();
  s[0] = r.ic_p[0] + offset;
  s[1] = r.ic_pd[0];
  s[2] = res && !r.ic_r.empty() ? r.ic_r[0] : (in == InputKind::kBaseDisplacement ? r.ic_p[0] : 0.0);
  s[3] = res && !r.ic_rd.empty() ? r.ic_rd[0] : (in == InputKind::kBaseDisplacement ? r.ic_pd[0] : 0.0);
  if constexpr (kD == 5) s[4] = volt_meas ? r.ic_w[0] : 0.0;
  // Segment k's given start state (the voltage only where measured; else it runs on).
  auto set_given = [&](size_t k) {
    const double* g = given->data() + k * kStateDim;
    for (int c = 0; c < 4; ++c) s[c] = g[c];
    if constexpr (kD == 5)
      if (volt_meas) s[4] = g[4];
  };
  if (given) set_given(0);
  // At a (re)start only the offset moves the state; an unmeasured voltage runs on (state and columns).
  // State columns restart as the identity (the new segment's start state).
  // Component c of sensitivity column j (parameters 0 … P − 1, then the state columns).
  auto sens = [&](int c, int j) -> double& { return s[sys.SensIndex(c, j)]; };
  auto reset_sensitivities = [&](bool keep_w) {
    if constexpr (kSens) {
      for (int j = 0; j < P; ++j)
        for (int c = 0; c < (keep_w ? 4 : kD); ++c) sens(c, j) = 0.0;
      if (offset_col >= 0) sens(0, offset_col) = 1.0;
      for (int j = 0; j < SC; ++j)
        for (int c = 0; c < kD; ++c) sens(c, P + j) = c == j ? 1.0 : 0.0;
    }
  };
  reset_sensitivities(false);
  const double limit_p = DivergenceLimit(r, offset);
  // The compared output is state component `oc` (plus a known signal); the resonator's is s[2] (+ s[0]).
  const int oc = MainStateComponent(setup);
  const bool res_plus_p = in != InputKind::kBaseDisplacement;
  const OutputRows<kSens, kD, Sys> rows{r,    setup, sc, thx, sys, s,          so,
                                        stop, P,     SC, oc,  res, res_plus_p, sc.AnyOutputTerm()};
  rows.Emit(0);
  Rk4<Sys> rk4(sys);
  for (size_t i = 1; i < n; ++i) {
    if (CancelRequested()) [[unlikely]]
      return false;  // Ctrl-C: every simulation fails at once, the loop ends
    if (restart_every > 0 && (i - 1) % static_cast<size_t>(restart_every) == 0 && i > 1) {
      if (given) {
        set_given((i - 1) / static_cast<size_t>(restart_every));
      } else {
        s[0] = r.ic_p[i - 1] + offset, s[1] = r.ic_pd[i - 1];
        if (res && !r.ic_r.empty()) s[2] = r.ic_r[i - 1], s[3] = r.ic_rd[i - 1];
        if constexpr (kD == 5)
          if (volt_meas) s[4] = r.ic_w[i - 1];
      }
      reset_sensitivities(!volt_meas);
    }
    if (active && !(*active)[(i - 1) / static_cast<size_t>(restart_every)]) continue;  // a skipped segment
    for (int sub = 0; sub < ns; ++sub) rk4.Step(r.t0 + static_cast<double>(i - 1) * r.dt + sub * h, s, h);
    if (!std::isfinite(s[0]) || !std::isfinite(s[1]) || std::abs(s[0]) > limit_p) return false;
    if constexpr (kD == 5)
      if (!std::isfinite(s[4])) return false;
    rows.Emit(i);
    if (stop && stop->stopped) return false;
  }
  return true;
}

// Plain simulations of W parameter vectors of one model side by side, lane l with *ths[l] (forward-difference
// columns of the spectral objective): SimulateImpl<false, kD>'s operations — RecordSystem's equations and
// Rk4's step — lane by lane, so that every lane has the bits of its own scalar simulation (-ffp-contract=off;
// Identify.LaneSimulationsEqualTheScalarOnes). The record's input is evaluated once for all lanes. Whole
// records only (no segments, no early stop); `ns` substeps for every lane; false when any lane fails.
template <int W, int kD>
bool SimulateLanesImpl(const IdentModel& m, const std::vector<double>* const* ths, const PreparedRecord& r,
                       const Setup& setup, int ns, SimOutputs* so) {
  using V = Vec<W>;
  const size_t n = r.n();
  for (int l = 0; l < W; ++l)
    for (int k = 0; k < kOutputSlots; ++k) {
      so[l].out[k].clear(), so[l].d[k].resize(0, 0), so[l].ds[k].resize(0, 0);
      if (r.Has(static_cast<OutputSlot>(k))) so[l].out[k].assign(n, NAN);
    }
  const bool res = m.HasResonator();
  if ((res && !(m.m_res > 0)) || ns <= 0) return false;
  const int P = m.NumParams();
  std::vector<V> th(static_cast<size_t>(P));
  V mm, limit_p;
  V s[kD];  // the state, from the measured one at sample 0
  for (int l = 0; l < W; ++l) {
    const std::vector<double>& t = *ths[l];
    if (static_cast<int>(t.size()) < P) return false;
    for (double v : t)
      if (!std::isfinite(v)) return false;
    mm[l] = m.Mass(t);
    if (!(mm[l] > 0) || !std::isfinite(mm[l])) return false;
    for (int j = 0; j < P; ++j) th[static_cast<size_t>(j)][l] = t[static_cast<size_t>(j)];
    limit_p[l] = DivergenceLimit(r, m.Offset(t, r.index));
    const std::array<double, kStateDim> x0 = MeasuredState(m, t, r, setup, 0);
    for (int c = 0; c < kD; ++c) s[c][l] = x0[static_cast<size_t>(c)];
  }
  std::vector<SimTerm> terms;
  int col = 0;
  for (const TermDef* t : m.terms) {
    if (t->IsForce() && (t->body == Body::kMain || res)) terms.push_back({t, col});
    col += static_cast<int>(t->params.size());
  }
  const SpecialCols sc = FindSpecialCols(m, {}, &setup);
  const StribeckBasis fb = FrictionBasis(m.fc);
  const InputKind in = setup.input;
  const double mr = m.m_res, h = r.dt / ns;
  double input_t = NAN, input_u = 0, input_ud = 0;
  // RecordSystem::operator() without sensitivities.
  auto f = [&](double t, const V* x, V* dx) BISTABLE_INLINE_LAMBDA {
    if (t != input_t) r.in_spline.Eval(t, &input_u, &input_ud), input_t = t;
    const double u = input_u, ud = input_ud;
    V y, yd, z, zd;
    BodyCoordinates(in, res, x[0], x[1], x[2], x[3], u, ud, &y, &yd, &z, &zd);
    V F{}, G{};
    for (const SimTerm& st : terms) {
      const bool main = st.t->body == Body::kMain;
      V phi[kMaxTermParams];
      TermBasisSlopes<V>(*st.t, main ? y : z, main ? yd : zd, fb, phi, nullptr, nullptr);
      V fs{};
      for (size_t j = 0; j < st.t->params.size(); ++j) fs += th[static_cast<size_t>(st.col) + j] * phi[j];
      if (main)
        F += fs;
      else
        G += fs;
    }
    V wdot{};
    if constexpr (kD == 5) {
      if (sc.piezo >= 0) {
        const V w = x[4], pa = th[static_cast<size_t>(sc.piezo)], pb = th[static_cast<size_t>(sc.piezo) + 1],
                pc = th[static_cast<size_t>(sc.piezo) + 2];
        F += -pa * w;
        wdot = -pb * w - pc * yd;
      }
    }
    V a1, a3, inv;
    Accelerations(in, res, F, G, u, mm, mr, &a1, &a3, &inv);
    dx[0] = x[1], dx[1] = a1, dx[2] = x[3], dx[3] = a3;
    if constexpr (kD == 5) dx[4] = wdot;
  };
  // Rk4::Step on Eigen vectors, component by component.
  V k1[kD], k2[kD], k3[kD], k4[kD], tmp[kD];
  auto step = [&](double t) BISTABLE_INLINE_LAMBDA {
    f(t, s, k1);
    for (int c = 0; c < kD; ++c) tmp[c] = s[c] + (0.5 * h) * k1[c];
    f(t + 0.5 * h, tmp, k2);
    for (int c = 0; c < kD; ++c) tmp[c] = s[c] + (0.5 * h) * k2[c];
    f(t + 0.5 * h, tmp, k3);
    for (int c = 0; c < kD; ++c) tmp[c] = s[c] + h * k3[c];
    f(t + h, tmp, k4);
    for (int c = 0; c < kD; ++c) s[c] += (h / 6.0) * (k1[c] + 2.0 * k2[c] + 2.0 * k3[c] + k4[c]);
  };
  const int oc = MainStateComponent(setup);
  const bool res_plus_p = in != InputKind::kBaseDisplacement;
  const bool any_output_term = sc.AnyOutputTerm();
  auto effects = [&](int l, int k, double value) {
    return any_output_term ? WithOutputEffects(sc, *ths[l], k, value) : value;
  };
  auto emit = [&](size_t i) {
    for (int l = 0; l < W; ++l) {
      so[l].out[0][i] = effects(l, 0, MainOutputValue(r, setup, s[oc][l], i));
      if (!so[l].out[1].empty() && res) so[l].out[1][i] = effects(l, 1, res_plus_p ? s[2][l] + s[0][l] : s[2][l]);
      if (!so[l].out[2].empty()) {
        double w = 0;
        if constexpr (kD == 5) w = s[4][l];
        so[l].out[2][i] = effects(l, 2, w);
      }
    }
  };
  emit(0);
  for (size_t i = 1; i < n; ++i) {
    if (CancelRequested()) [[unlikely]]
      return false;
    for (int sub = 0; sub < ns; ++sub) step(r.t0 + static_cast<double>(i - 1) * r.dt + sub * h);
    for (int l = 0; l < W; ++l) {
      if (!std::isfinite(s[0][l]) || !std::isfinite(s[1][l]) || std::abs(s[0][l]) > limit_p[l]) return false;
      if constexpr (kD == 5)
        if (!std::isfinite(s[4][l])) return false;
    }
    emit(i);
  }
  return true;
}

template <int W>
bool SimulateLanesOf(const IdentModel& m, const std::vector<const std::vector<double>*>& ths, const PreparedRecord& r,
                     const Setup& setup, int substeps, std::vector<SimOutputs>* outs) {
  const std::vector<double>* lanes[W];
  for (int l = 0; l < W; ++l)
    lanes[l] = ths[std::min<size_t>(static_cast<size_t>(l), ths.size() - 1)];  // padding: the last
  SimOutputs so[W];
  const bool ok = m.PiezoIndex() >= 0 ? SimulateLanesImpl<W, 5>(m, lanes, r, setup, substeps, so)
                                      : SimulateLanesImpl<W, 4>(m, lanes, r, setup, substeps, so);
  for (size_t l = 0; l < ths.size(); ++l) (*outs)[l] = std::move(so[l]);
  return ok;
}

}  // namespace

std::array<double, kStateDim> MeasuredState(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                                            const Setup& setup, size_t i) {
  const bool res = m.HasResonator(), disp = setup.input == InputKind::kBaseDisplacement;
  std::array<double, kStateDim> x{};
  x[0] = r.ic_p[i] + m.Offset(th, r.index);
  x[1] = r.ic_pd[i];
  x[2] = res && !r.ic_r.empty() ? r.ic_r[i] : (disp ? r.ic_p[i] : 0.0);
  x[3] = res && !r.ic_rd.empty() ? r.ic_rd[i] : (disp ? r.ic_pd[i] : 0.0);
  x[4] = r.ic_w.empty() ? 0.0 : r.ic_w[i];
  return x;
}

bool SimulateOutputs(const IdentModel& m, const std::vector<double>& th, const std::vector<const TermDef*>& extra,
                     const PreparedRecord& r, const Setup& setup, int substeps, int restart_every, bool sensitivities,
                     SimOutputs* out, EarlyStop* stop, const SegmentStates* segments) {
  bool piezo = m.PiezoIndex() >= 0;
  if (sensitivities)
    for (const TermDef* t : extra) piezo = piezo || t->kind == TermKind::kPiezo;
  const bool sens = sensitivities || (segments && segments->sensitivities);
  if (sens) {
    const std::vector<const TermDef*>& x = sensitivities ? extra : std::vector<const TermDef*>{};
    return piezo ? SimulateImpl<true, 5>(m, th, x, r, setup, substeps, restart_every, out, stop, segments)
                 : SimulateImpl<true, 4>(m, th, x, r, setup, substeps, restart_every, out, stop, segments);
  }
  return piezo ? SimulateImpl<false, 5>(m, th, {}, r, setup, substeps, restart_every, out, stop, segments)
               : SimulateImpl<false, 4>(m, th, {}, r, setup, substeps, restart_every, out, stop, segments);
}

bool SimulateOutputsLanes(const IdentModel& m, const std::vector<const std::vector<double>*>& ths,
                          const PreparedRecord& r, const Setup& setup, int substeps, std::vector<SimOutputs>* outs) {
  outs->assign(ths.size(), SimOutputs{});
  if (ths.empty() || ths.size() > static_cast<size_t>(kMaxSimLanes)) return false;
  for (const std::vector<double>* t : ths)
    if (!t) return false;
  if (substeps <= 0) return false;
  if (ths.size() == 1) return SimulateOutputs(m, *ths[0], {}, r, setup, substeps, 0, false, &(*outs)[0]);
  if (ths.size() == 2) return SimulateLanesOf<2>(m, ths, r, setup, substeps, outs);
  if (ths.size() <= 4) return SimulateLanesOf<4>(m, ths, r, setup, substeps, outs);
  return SimulateLanesOf<8>(m, ths, r, setup, substeps, outs);
}

bool Simulate(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r, const Setup& setup,
              std::vector<double>* out, std::vector<double>* out_res, int substeps, int restart_every,
              EarlyStop* stop) {
  SimOutputs so;
  const bool ok = SimulateOutputs(m, th, {}, r, setup, substeps, restart_every, false, &so, stop);
  *out = std::move(so.out[0]);
  if (out_res) *out_res = so.out[1].empty() ? std::vector<double>(r.n(), NAN) : std::move(so.out[1]);
  return ok;
}

bool SimulateSensitivities(const IdentModel& m, const std::vector<double>& th, const std::vector<const TermDef*>& extra,
                           const PreparedRecord& r, const Setup& setup, int substeps, int restart_every,
                           std::vector<double>* out, Eigen::MatrixXd* dout, std::vector<double>* out_res,
                           Eigen::MatrixXd* dres) {
  SimOutputs so;
  const bool ok = SimulateOutputs(m, th, extra, r, setup, substeps, restart_every, true, &so);
  *out = std::move(so.out[0]);
  *dout = std::move(so.d[0]);
  if (out_res) *out_res = std::move(so.out[1]);
  if (dres) *dres = std::move(so.d[1]);
  return ok;
}

}  // namespace bistable
