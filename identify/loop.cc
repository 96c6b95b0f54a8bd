#include "identify/loop.h"
#include "dynamics/cancel.h"
#include "identify/bootstrap.h"
#include "identify/loop_parts.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <optional>
#include <random>
#include <thread>
#include <utility>

#include "base/beside.h"
#include "base/cpus.h"

namespace bistable {
namespace {

// Mean over records (of ≥ 16 rows) of their correlation times (lags below 500), at least 1.
double CorrTime(const Eigen::VectorXd& e, const std::vector<int>& record_of_row) {
  double total = 0;
  int count = 0;
  size_t i = 0;
  const size_t n = static_cast<size_t>(e.size());
  while (i < n) {
    size_t j = i;
    while (j < n && record_of_row[j] == record_of_row[i]) ++j;
    if (j - i >= 16) total += CorrelationTime(e.data() + i, j - i, 500), ++count;
    i = j;
  }
  return count ? std::max(1.0, total / count) : 1.0;
}

// Least squares for the term parameters (and the mass) with the offsets held at m.theta's values.
std::vector<double> StartFromRegression(const IdentModel& m, const std::vector<PreparedRecord>& recs,
                                        const Setup& setup, std::vector<double>* sigma) {
  const Regression reg = BuildRegression(m, recs, setup);
  const int q = m.NumParams() - m.offsets;
  std::vector<Sign> signs = m.ParamSigns();
  signs.resize(q);
  const LinearFit lf = SolveRegression(reg.X.leftCols(q), reg.b, signs);
  std::vector<double> th = lf.theta;
  *sigma = lf.sigma;
  for (int k = 0; k < m.offsets; ++k) th.push_back(m.Offset(m.theta, k)), sigma->push_back(NAN);
  return th;
}

// Offsets of velocity-output records: per record, the displacement shift whose equation-error
// regression leaves the least residual (a scan over ±3 displacement ranges), so that a record in
// one well starts the fit in that well.
void EstimateOffsets(IdentModel* m, const std::vector<PreparedRecord>& recs, const Setup& setup) {
  if (m->offsets == 0) return;
  m->theta.assign(m->NumParams(), NAN);  // term values from the regression that follows
  for (int k = 0; k < m->offsets && k < static_cast<int>(recs.size()); ++k) {
    std::vector<PreparedRecord> one = {recs[k]};
    one[0].index = 0;
    IdentModel single = *m;
    single.offsets = 1;
    single.theta.assign(single.NumParams(), 0.0);
    const double range = std::max(recs[k].p_range, 1e-9);
    double best = INFINITY, best_d = 0;
    for (int j = -60; j <= 60; ++j) {
      const double d = 3.0 * range * j / 60.0;
      single.theta[single.OffsetIndex(0)] = d;
      const Regression reg = BuildRegression(single, one, setup, {}, 4000);
      const int q = single.NumParams() - 1;
      std::vector<Sign> signs = single.ParamSigns();
      signs.resize(q);
      const LinearFit lf = SolveRegression(reg.X.leftCols(q), reg.b, signs);
      if (lf.rss < best) best = lf.rss, best_d = d;
    }
    m->theta[m->OffsetIndex(k)] = best_d;
  }
}

}  // namespace

// Parameter scales for the fits: the value, 3σ, or — for a parameter at zero (clipped to its bound,
// or not yet estimated) — 5 % of the value whose force equals the RMS inertial force along the
// records; without that floor a parameter starting at 0 could never move in scaled coordinates.
std::vector<double> ScaleOf(const IdentModel& m, const std::vector<double>& th, const std::vector<double>& sigma,
                            const std::vector<PreparedRecord>& recs, const Setup& setup) {
  const Regression reg = BuildRegression(m, recs, setup, {}, 5000);
  const double f_typ = std::sqrt(reg.b.squaredNorm() / std::max<double>(1.0, static_cast<double>(reg.b.size())));
  std::vector<double> s(th.size());
  for (size_t i = 0; i < th.size(); ++i) {
    const double rms =
        reg.X.col(static_cast<long>(i)).norm() / std::sqrt(std::max<double>(1.0, static_cast<double>(reg.X.rows())));
    const double typ = rms > 0 && f_typ > 0 ? 0.05 * f_typ / rms : 0.0;
    s[i] = std::max({std::abs(th[i]), std::isfinite(sigma[i]) ? 3.0 * sigma[i] : 0.0, typ});
  }
  for (int k = 0; k < m.offsets; ++k) {  // offsets: the record's displacement range
    const int i = m.OffsetIndex(k);
    s[i] = std::max(std::abs(th[i]), k < static_cast<int>(recs.size()) ? recs[k].p_range : 1e-3);
  }
  return s;
}

namespace {

double ErrorOf(const Errors& e, Objective obj) {
  return obj == Objective::kFft ? e.fft : obj == Objective::kShooting ? e.shooting : e.nrmse;
}
double ErrorOf(const FitResult& f, Objective obj) { return ErrorOf(f.errors, obj); }
double ErrorOf(const OutputErrors& o, Objective obj) {  // one output's error under the objective
  return obj == Objective::kFft ? o.fft : obj == Objective::kShooting ? o.shooting : o.nrmse;
}

}  // namespace

ResidualCloud ResidualForce(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                            const Setup& setup) {
  const Regression reg = BuildRegression(m, recs, setup, {}, 20000);
  ResidualCloud c;
  Eigen::VectorXd t(static_cast<long>(th.size()));
  for (size_t i = 0; i < th.size(); ++i) t[static_cast<long>(i)] = th[i];
  const Eigen::VectorXd r = reg.b - reg.X * t;
  for (long i = 0; i < r.size(); ++i) {
    if (!std::isfinite(reg.q[static_cast<size_t>(i)])) continue;  // resonator rows
    c.q.push_back(reg.q[static_cast<size_t>(i)]);
    c.v.push_back(reg.v[static_cast<size_t>(i)]);
    c.r.push_back(-r[i]);  // force the model lacks, in the sense of F (opposing motion when positive)
  }
  return c;
}

double DeltaBic(double rss_ratio, size_t k, double n_eff) {
  return n_eff * std::log(std::max(rss_ratio, 1e-300)) + static_cast<double>(k) * std::log(n_eff);
}

namespace {

// ΔBIC, explained fraction and the candidate's coefficients for target ≈ [A, C] x against target ≈ A x.
CandidateScore ScoreColumns(const Eigen::MatrixXd& A, const Eigen::MatrixXd& C, const Eigen::VectorXd& target,
                            double rss0, double n_eff) {
  const long p = A.cols(), k = C.cols();
  Eigen::MatrixXd X(A.rows(), p + k);
  X << A, C;
  const LinearFit f = SolveRegression(X, target, std::vector<Sign>(p + k, Sign::kEither));
  CandidateScore s;
  s.explained = rss0 > 0 ? (rss0 - f.rss) / rss0 : 0.0;
  s.delta_bic = DeltaBic(std::max(f.rss, 1e-300) / std::max(rss0, 1e-300), static_cast<size_t>(k), n_eff);
  for (long j = 0; j < k; ++j) s.estimate.push_back(f.theta[p + j]), s.sigma.push_back(f.sigma[p + j]);
  return s;
}

// The library terms not yet in m that the trace may add (opt.candidates, or every term of a body
// the data constrain).
// Default: the force terms of the bodies measured; with a measured voltage also main.piezo and the
// offset and scale of every measured output. Output terms of an output the records lack are dropped.
std::vector<const TermDef*> FreshCandidates(const IdentModel& m, const std::vector<PreparedRecord>& recs,
                                            const Setup& setup, const IdentifyOptions& opt) {
  std::vector<const TermDef*> cands = opt.candidates;
  bool res_data = true, volt_data = !recs.empty();
  for (const PreparedRecord& r : recs)
    res_data = res_data && !r.z.empty(), volt_data = volt_data && r.Has(OutputSlot::kVoltage);
  auto measured = [&](const TermDef& t) {
    const int slot = OutputSlotOf(t, setup);
    return slot >= 0 && !recs.empty() && recs[0].Has(static_cast<OutputSlot>(slot));
  };
  if (cands.empty())
    for (const TermDef& t : EffectLibrary()) {
      if (t.IsForce() && (t.body == Body::kMain || (res_data && m.HasResonator())))
        cands.push_back(&t);
      else if (volt_data && (t.kind == TermKind::kPiezo || (t.body == Body::kOutput && measured(t))))
        cands.push_back(&t);
    }
  // A gain on the voltage is the piezo's own scale (w → λw, c → λc, a → a/λ leaves the beam as it is):
  // with main.piezo in the model, out.voltage.scale would only fit the start of the voltage transient.
  const bool piezo = m.PiezoIndex() >= 0;
  std::vector<const TermDef*> fresh;
  for (const TermDef* c : cands)
    if (std::find(m.terms.begin(), m.terms.end(), c) == m.terms.end() && (c->body != Body::kOutput || measured(*c)) &&
        !(piezo && c->kind == TermKind::kOutputScale && c->output == "voltage"))
      fresh.push_back(c);
  return fresh;
}

// The point a candidate is scored at: 0 for a term linear in its parameters (its output sensitivities at 0
// say what it adds). The piezo's output is bilinear (a multiplies the state that c drives), so at 0 it
// adds nothing to first order: it is scored at a = 0 with its circuit from the measured voltage (b, c by
// least squares on w' = −b w − c y'), where the voltage output and ∂(outputs)/∂a are those of the fitted
// circuit; without a measured voltage, b = ω (max|y'| / max|y|) and c = 1 (then only a c is identified).
std::vector<double> CandidateBase(const TermDef& c, const std::vector<PreparedRecord>& recs) {
  std::vector<double> base(c.params.size(), 0.0);
  if (c.kind != TermKind::kPiezo) return base;
  Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  double omega = 0;
  for (const PreparedRecord& r : recs) {
    omega += r.v_range / std::max(r.p_range, 1e-300) / static_cast<double>(recs.size());
    if (r.w.empty()) continue;
    const size_t edge = std::min<size_t>(std::max<size_t>(12, r.n() / 50), r.n() / 4);
    for (size_t i = edge; i + edge < r.n(); ++i) {
      const Eigen::Vector2d x(r.w[i], r.yd[i]);
      A += x * x.transpose();
      rhs -= x * r.wd[i];
    }
  }
  if (A(0, 0) > 0) {
    const Eigen::Vector2d bc = A.ldlt().solve(rhs);
    base[1] = std::max(bc[0], 0.0), base[2] = bc[1];
  } else {
    base[1] = omega, base[2] = 1.0;
  }
  return base;
}
bool IsZero(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double x) { return x == 0.0; });
}

// Supporting evidence: the restoring-force residual of the equation-error rows, regressed on the
// declared columns (base) and scored against each candidate's columns (after them in `reg`).
struct ForceEvidence {
  Regression reg;
  Eigen::VectorXd r0;               // residual force of the fitted model
  LinearFit base;                   // r0 on the declared columns
  double n_eff = 0;                 // rows / correlation time
  std::vector<double> step_of_col;  // typical parameter step of every column (finite differences)
};

ForceEvidence ForceResidual(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                            const Setup& setup, const std::vector<const TermDef*>& fresh) {
  const int p = m.NumParams();
  ForceEvidence f{BuildRegression(m, recs, setup, fresh, 30000), {}, {}, 0, {}};
  const Regression& reg = f.reg;
  Eigen::VectorXd t(p);
  for (int i = 0; i < p; ++i) t[i] = th[i];
  f.r0 = reg.b - reg.X.leftCols(p) * t;
  f.base = SolveRegression(reg.X.leftCols(p), f.r0, std::vector<Sign>(p, Sign::kEither));
  Eigen::VectorXd d(p);
  for (int i = 0; i < p; ++i) d[i] = f.base.theta[i];
  f.n_eff = static_cast<double>(reg.X.rows()) / CorrTime(f.r0 - reg.X.leftCols(p) * d, reg.record_of_row);
  // Typical parameter steps: a change worth 2 % of the RMS inertial force along the trajectory.
  const double f_typ =
      std::sqrt(reg.b.squaredNorm() / std::max<double>(1.0, static_cast<double>(reg.b.size()))) + 1e-300;
  f.step_of_col.resize(reg.X.cols());
  for (long j = 0; j < reg.X.cols(); ++j) {
    const double rms = reg.X.col(j).norm() / std::sqrt(static_cast<double>(std::max<long>(1, reg.X.rows())));
    f.step_of_col[j] = rms > 0 ? 0.02 * f_typ / rms : 1e-6;
  }
  return f;
}

// Deciding evidence: the simulation residual e of the fitted model, the output sensitivities J to its
// parameters and Jc to every candidate's at zero (one sensitivity pass: exact derivatives of the
// discrete simulation), and the part of −e that J cannot explain (base).
struct SimulationEvidence {
  std::vector<int> sub;    // substeps held fixed for every simulation of the trace
  std::vector<double> e0;  // residual vector
  Eigen::VectorXd target;  // −e
  Eigen::MatrixXd J, Jc;   // declared parameters; candidates' parameters (in `fresh` order)
  LinearFit base;          // target on J
  double n_eff = 0;        // samples / correlation time of what J leaves
};

// J and Jc by finite differences (the spectral objective): central differences for the declared
// parameters, forward differences of the model with each candidate parameter at its typical step
// `steps` (substeps no fewer than the trace's); a candidate whose simulation diverges gets NaN columns.
// Why not the sensitivities: a chaotic record's exact derivative grows like e^{λt} over the record and
// says nothing about the spectrum a step away; differences at a finite step average over that.
void DifferenceSensitivities(const IdentModel& m, const std::vector<double>& th,
                             const std::vector<const TermDef*>& fresh, const double* steps,
                             const std::vector<PreparedRecord>& recs, const Setup& setup, Objective obj,
                             SimulationEvidence* s) {
  const int p = m.NumParams();
  const long N = static_cast<long>(s->e0.size());
  s->J.resize(N, p);
  std::vector<double> ep, em;
  for (int i = 0; i < p; ++i) {
    const double h = 1e-4 * (std::abs(th[i]) > 0 ? std::abs(th[i]) : steps[i]);
    std::vector<double> a = th, b = th;
    a[i] += h, b[i] -= h;
    if (!ObjectiveResiduals(m, a, recs, setup, obj, s->sub, &ep) ||
        !ObjectiveResiduals(m, b, recs, setup, obj, s->sub, &em)) {
      s->J.col(i).setZero();
      continue;
    }
    for (long k = 0; k < N; ++k) s->J(k, i) = (ep[k] - em[k]) / (2 * h);
  }
  long cols = 0;
  for (const TermDef* c : fresh) cols += static_cast<long>(c->params.size());
  s->Jc.resize(N, cols);
  long col = 0;
  for (const TermDef* c : fresh) {
    const int k = static_cast<int>(c->params.size());
    for (int j = 0; j < k; ++j, ++col) {
      std::vector<double> init(k, 0.0);
      init[j] = steps[p + col];
      const IdentModel mc = m.With(c, init);
      std::vector<int> subc = FixedSubsteps(mc, mc.theta, recs, obj);
      for (size_t r = 0; r < subc.size(); ++r) subc[r] = std::max(subc[r], s->sub[r]);
      std::vector<double> ec, e0c = s->e0;
      if (!ObjectiveResiduals(mc, mc.theta, recs, setup, obj, subc, &ec) ||
          !(subc == s->sub || ObjectiveResiduals(m, th, recs, setup, obj, subc, &e0c))) {
        s->Jc.col(col).setConstant(NAN);
        continue;
      }
      for (long i = 0; i < N; ++i) s->Jc(i, col) = (ec[i] - e0c[i]) / init[j];
    }
  }
}

// False when the fitted model diverges on a record. Time objective: J and Jc from one sensitivity pass;
// spectral objective: finite differences (DifferenceSensitivities).
bool SimulationResidual(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                        const Setup& setup, Objective obj, double horizon_s, const std::vector<const TermDef*>& fresh,
                        const std::vector<double>& steps, SimulationEvidence* s) {
  const int p = m.NumParams();
  s->sub = FixedSubsteps(m, th, recs, obj);
  if (obj != Objective::kFft) {
    Eigen::MatrixXd all;
    if (!ObjectiveJacobian(m, th, recs, setup, obj, s->sub, fresh, &s->e0, &all, horizon_s)) return false;
    s->J = all.leftCols(p);
    s->Jc = all.rightCols(all.cols() - p);
  } else {
    if (!ObjectiveResiduals(m, th, recs, setup, obj, s->sub, &s->e0)) return false;
    DifferenceSensitivities(m, th, fresh, steps.data(), recs, setup, obj, s);
  }
  const long N = static_cast<long>(s->e0.size());
  s->target = -Eigen::Map<const Eigen::VectorXd>(s->e0.data(), N);
  s->base = SolveRegression(s->J, s->target, std::vector<Sign>(p, Sign::kEither));
  Eigen::VectorXd db(p);
  for (int i = 0; i < p; ++i) db[i] = std::isfinite(s->base.theta[i]) ? s->base.theta[i] : 0.0;
  const Eigen::VectorXd e_base = s->target - s->J * db;
  s->n_eff = static_cast<double>(N) / CorrTime(e_base, std::vector<int>(static_cast<size_t>(N), 0));
  return true;
}

// Physically signed: a dissipative term (damping, drag, friction) must take energy out at every
// velocity of the records, F(q, v)·v ≥ 0 — for one-coefficient terms, the coefficient ≥ 0; for
// friction, the Coulomb level and the Stribeck peak together.
bool DissipatesEnergy(const TermDef& c, const std::vector<double>& estimate, const std::vector<PreparedRecord>& recs,
                      const FrictionConstants& fc) {
  double vmax = 0, qmax = 0;
  for (const PreparedRecord& r : recs) vmax = std::max(vmax, r.v_range), qmax = std::max(qmax, r.p_range);
  double phi[kMaxTermParams];
  bool any = false;
  for (int iv = 1; iv <= 200; ++iv) {
    const double v = vmax * 1.5 * iv / 200.0;
    for (double q : {0.0, 0.5 * qmax, qmax}) {
      TermBasis(c, q, v, fc, phi);
      double f = 0;
      for (size_t j = 0; j < c.params.size(); ++j) f += estimate[j] * phi[j];
      if (f * v < -1e-12 * std::max(1.0, std::abs(f))) return false;
      any = any || f * v > 0;
    }
  }
  return any;
}

// A candidate scored at its base point (CandidateBase): the model with the candidate at `base`, its
// residual e_c and sensitivities (declared parameters J_d, candidate J_c: one sensitivity pass, or finite
// differences for the spectral objective); −e_c ≈ J_d δ + J_c (β − base) by least squares, compared with
// what the declared parameters alone leave of −e (sim.base.rss).
CandidateScore ScoreAtBase(const IdentModel& m, const std::vector<double>& th, const TermDef& c,
                           const std::vector<double>& base, const std::vector<PreparedRecord>& recs, const Setup& setup,
                           Objective obj, double horizon_s, const ForceEvidence& force, const SimulationEvidence& sim) {
  CandidateScore s;
  const int p = m.NumParams(), nt = m.NumTermParams(), k = static_cast<int>(c.params.size());
  IdentModel mc = m;
  mc.theta = th;
  mc = mc.With(&c, base);
  SimulationEvidence ev;
  ev.sub = FixedSubsteps(mc, mc.theta, recs, obj);
  for (size_t r = 0; r < ev.sub.size(); ++r) ev.sub[r] = std::max(ev.sub[r], sim.sub[r]);
  bool ok = false;
  Eigen::MatrixXd all;
  if (obj != Objective::kFft) {
    ok = ObjectiveJacobian(mc, mc.theta, recs, setup, obj, ev.sub, {}, &ev.e0, &all, horizon_s);
  } else if (ObjectiveResiduals(mc, mc.theta, recs, setup, obj, ev.sub, &ev.e0)) {
    std::vector<double> steps(mc.NumParams());
    for (int i = 0; i < mc.NumParams(); ++i) {
      const int fi = i < nt ? i : i < nt + k ? -1 : i - k;  // the column in the force regression (declared)
      steps[i] = fi >= 0 ? force.step_of_col[fi] : std::max(std::abs(base[i - nt]), 1e-6);
    }
    DifferenceSensitivities(mc, mc.theta, {}, steps.data(), recs, setup, obj, &ev);
    all = ev.J;
    ok = all.allFinite();
  }
  if (!ok || static_cast<long>(ev.e0.size()) != static_cast<long>(sim.e0.size())) {
    s.explained = 0, s.delta_bic = INFINITY;
    s.estimate = base, s.sigma.assign(k, NAN);
    return s;
  }
  const long N = static_cast<long>(ev.e0.size());
  Eigen::MatrixXd Jd(N, p);
  Jd << all.leftCols(nt), all.rightCols(p - nt);
  const Eigen::VectorXd target = -Eigen::Map<const Eigen::VectorXd>(ev.e0.data(), N);
  s = ScoreColumns(Jd, all.middleCols(nt, k), target, sim.base.rss, sim.n_eff);
  for (int j = 0; j < k; ++j) s.estimate[j] += base[j];
  return s;
}

}  // namespace

namespace {

// The trace proper (TraceResidual): every candidate scored; `twins` — the fitted model's twin records, whose
// scores calibrate the choice (CandidateScore::twin_explained), or empty.
LoopStep TraceScores(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                     const Setup& setup, const IdentifyOptions& opt, const std::vector<std::string>& passed_over,
                     const std::vector<std::vector<PreparedRecord>>& twins);

}  // namespace

LoopStep TraceResidual(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                       const Setup& setup, const IdentifyOptions& opt, const std::vector<std::string>& passed_over) {
  // Records fitted on short horizons, or that snap between wells: the trace's null from the fitted model's twins.
  const bool chaotic = std::any_of(recs.begin(), recs.end(),
                                   [](const PreparedRecord& r) { return r.chaotic || r.snaps || r.horizon_s > 0; });
  const std::vector<std::vector<PreparedRecord>> twins =
      chaotic ? TwinRecords(m, th, recs, setup, kTwins,
                            opt.fit.objective == Objective::kShooting ? opt.fit.shooting_horizon_s : 0.0)
              : std::vector<std::vector<PreparedRecord>>{};
  return TraceScores(m, th, recs, setup, opt, passed_over, twins);
}

namespace {

LoopStep TraceScores(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                     const Setup& setup, const IdentifyOptions& opt, const std::vector<std::string>& passed_over,
                     const std::vector<std::vector<PreparedRecord>>& twins) {
  LoopStep step;
  const std::vector<const TermDef*> fresh = FreshCandidates(m, recs, setup, opt);
  const int p = m.NumParams();
  const ForceEvidence force = ForceResidual(m, th, recs, setup, fresh);
  step.residual_rms = std::sqrt(force.r0.squaredNorm() / static_cast<double>(force.reg.X.rows()));
  SimulationEvidence sim;
  if (!SimulationResidual(m, th, recs, setup, opt.fit.objective, opt.fit.shooting_horizon_s, fresh, force.step_of_col,
                          &sim)) {
    step.verdict = "the fitted model diverges on a record; nothing traced";
    return step;
  }
  step.n_eff = step.record_n_eff = sim.n_eff;
  int col = p;
  for (const TermDef* c : fresh) {
    const int k = static_cast<int>(c->params.size());
    CandidateScore s;
    if (sim.Jc.middleCols(col - p, k).allFinite()) {
      s = ScoreColumns(sim.J, sim.Jc.middleCols(col - p, k), sim.target, sim.base.rss, sim.n_eff);
    } else {  // its simulation diverged
      s.explained = 0;
      s.delta_bic = INFINITY;
      s.estimate.assign(k, 0.0);
      s.sigma.assign(k, NAN);
    }
    const std::vector<double> base = CandidateBase(*c, recs);
    if (!IsZero(base))
      s = ScoreAtBase(m, th, *c, base, recs, setup, opt.fit.objective, opt.fit.shooting_horizon_s, force, sim);
    s.term = c->id;
    if (c->params[0].sign == Sign::kNonNegative) s.sign_ok = DissipatesEnergy(*c, s.estimate, recs, m.fc);
    if (c->kind == TermKind::kPiezo) s.sign_ok = s.estimate[0] * s.estimate[2] > 0;  // the coupling damps the beam
    const CandidateScore fs =
        ScoreColumns(force.reg.X.leftCols(p), force.reg.X.middleCols(col, k), force.r0, force.base.rss, force.n_eff);
    s.force_delta_bic = fs.delta_bic;
    s.force_explained = fs.explained;
    step.scores.push_back(s);
    col += k;
  }
  double twin_n_eff = 0;
  for (const std::vector<PreparedRecord>& twin : twins) {
    const LoopStep null = TraceScores(m, th, twin, setup, opt, passed_over, {});
    twin_n_eff += null.n_eff / static_cast<double>(twins.size());
    for (CandidateScore& s : step.scores)
      for (const CandidateScore& n : null.scores)
        if (n.term == s.term && std::isfinite(n.explained))
          s.twin_explained = std::isfinite(s.twin_explained) ? std::max(s.twin_explained, n.explained) : n.explained;
  }
  // With twins, ΔBIC counts the residuals the twins leave independent: the effective sample size is a
  // property of the null hypothesis (the model right, its residual the noise through the flow), which the
  // twins realise. The record's own residual, when a term is missing, carries that term's smooth signature,
  // and its correlation time then shrank n_eff exactly where the evidence is strongest: on s_y2_12 (the
  // quadratic stiffness undeclared) the declared fit's residual left n_eff ≈ 30 of 3,600 samples, and a
  // candidate explaining 31 % of it (0.1 % on every twin) scored ΔBIC −8.1, short of −10.
  if (twin_n_eff > 1 && std::isfinite(twin_n_eff)) {
    step.n_eff = twin_n_eff;
    for (CandidateScore& s : step.scores)
      if (std::isfinite(s.delta_bic)) s.delta_bic = DeltaBic(1.0 - s.explained, s.estimate.size(), twin_n_eff);
  }
  std::sort(step.scores.begin(), step.scores.end(),
            [](const CandidateScore& a, const CandidateScore& b) { return a.delta_bic < b.delta_bic; });
  for (const CandidateScore& s : step.scores) {
    if (!s.sign_ok || !(s.delta_bic < -opt.bic_threshold) || !(s.explained >= opt.min_explained)) continue;
    if (std::isfinite(s.twin_explained) && !(s.explained > kTwinFactor * s.twin_explained))
      continue;  // as much as in noise
    if (std::find(passed_over.begin(), passed_over.end(), s.term) != passed_over.end()) continue;
    step.chosen = s.term;
    break;
  }
  return step;
}

}  // namespace

IdentifyResult IdentifyIndexed(IdentModel m, std::vector<PreparedRecord> recs, const Setup& setup,
                               const IdentifyOptions& opt);

IdentifyResult Identify(const IdentModel& declared, const std::vector<PreparedRecord>& recs, const Setup& setup,
                        const IdentifyOptions& opt) {
  IdentModel m = declared;
  m.fc = setup.fc;
  if (opt.fit_offsets && setup.output == OutputKind::kVelocity && m.offsets == 0) {
    m.offsets = static_cast<int>(recs.size());
    if (!m.theta.empty()) m.theta.resize(m.NumParams(), NAN);
  }
  std::vector<PreparedRecord> indexed = recs;  // each record knows its offset parameter
  for (size_t i = 0; i < indexed.size(); ++i) indexed[i].index = static_cast<int>(i);
  SetOutputWeights(&indexed);  // several outputs: weights from their noise levels
  return IdentifyIndexed(m, std::move(indexed), setup, opt);
}

namespace {

// The declared model's start (m->theta): offsets from the equation-error scan, then the given
// guesses (non-NaN, offsets included) win, and the regression fills in the rest; `sigma0` its σ.
void StartDeclared(IdentModel* m, const std::vector<PreparedRecord>& recs, const Setup& setup,
                   std::vector<double>* sigma0) {
  const std::vector<double> given = m->theta;
  EstimateOffsets(m, recs, setup);
  if (given.size() == m->theta.size())
    for (size_t i = 0; i < given.size(); ++i)
      if (std::isfinite(given[i])) m->theta[i] = given[i];
  const std::vector<double> start = StartFromRegression(*m, recs, setup, sigma0);
  if (static_cast<int>(m->theta.size()) != m->NumParams())
    m->theta = start;
  else  // given guesses win; missing ones (NaN) come from the regression
    for (int i = 0; i < m->NumParams(); ++i)
      if (!std::isfinite(m->theta[i])) m->theta[i] = start[i];
}

}  // namespace

// Physically signed as fitted: a piezo coupling takes energy from the beam (a c > 0; a c < 0 would feed
// the beam from the circuit). Signed force parameters are bounds of the fit and need no check here.
bool Physical(const IdentModel& m, const std::vector<double>& th) {
  const int pz = m.PiezoIndex();
  return pz < 0 || th[pz] * th[pz + 2] > 0;
}

namespace {}  // namespace

bool ReweightOutputs(const Errors& e, Objective obj, const Setup& setup, std::vector<PreparedRecord>* recs) {
  if (recs->empty()) return false;
  std::array<double, kOutputSlots> level = RelativeNoise(*recs);
  int outputs = 0;
  for (int k = 0; k < kOutputSlots; ++k) {
    const OutputSlot slot = static_cast<OutputSlot>(k);
    if (!(*recs)[0].Has(slot)) continue;
    ++outputs;
    for (const OutputErrors& o : e.outputs)
      if (o.name == OutputName(setup, slot)) {
        const double err = 0.01 * ErrorOf(o, obj);
        if (std::isfinite(err)) level[k] = std::isfinite(level[k]) ? std::max(level[k], err) : err;
      }
  }
  if (outputs < 2) return false;
  double old[kOutputSlots];
  std::copy(std::begin((*recs)[0].weight), std::end((*recs)[0].weight), old);
  SetOutputWeightsFrom(level, recs);
  bool moved = false;
  for (int k = 1; k < kOutputSlots; ++k) {
    const double ratio = (*recs)[0].weight[k] / old[k];
    moved = moved || !(ratio < 2.0 && ratio > 0.5);
  }
  return moved;
}

namespace {

// The model `m` (fitted: `fit`) with the step's chosen term added (`*next`), refitted by simulation
// from two starts — the trace's estimate, and the extended model's equation-error regression
// (another basin) — the better kept. The trace's estimate is a linearisation about the fit: far from
// it the objective can be worse than with the term at zero (on the harvester's chaotic record under
// shooting, a bias refit from its estimate ended at 58.6 % against 37.5 % without it). So the first
// start is the best of the estimate scaled by 1, 1/2, 1/4 and 0 — at 0 the fitted model itself, from
// which the local stage cannot end above the error before the term.
FitResult RefitWith(const IdentModel& m, const FitResult& fit, const TermDef* t, const LoopStep& step,
                    const std::vector<PreparedRecord>& recs, const Setup& setup, const IdentifyOptions& opt,
                    IdentModel* next) {
  const CandidateScore& s = *std::find_if(step.scores.begin(), step.scores.end(),
                                          [&](const CandidateScore& c) { return c.term == step.chosen; });
  std::vector<double> init = s.estimate;
  for (size_t j = 0; j < init.size(); ++j)
    if (t->params[j].sign == Sign::kNonNegative) init[j] = std::max(init[j], 0.0);
  const double horizon = opt.fit.objective == Objective::kShooting ? opt.fit.shooting_horizon_s : 0;
  double best = ErrorOf(fit, opt.fit.objective), best_scale = 0;
  for (double scale : {1.0, 0.5, 0.25}) {
    std::vector<double> scaled = init;
    for (double& v : scaled) v *= scale;
    const IdentModel trial = m.With(t, scaled);
    const double e = ErrorOf(Evaluate(trial, trial.theta, recs, setup, horizon), opt.fit.objective);
    if (e < best) best = e, best_scale = scale;  // NaN (diverged) never wins
    if (best_scale == scale) break;              // the largest step that helps
  }
  for (double& v : init) v *= best_scale;
  *next = m.With(t, init);
  std::vector<double> sig = fit.sigma;
  sig.insert(sig.begin() + m.NumTermParams(), s.sigma.begin(), s.sigma.end());
  IdentModel alt = *next;
  std::vector<double> sig_alt;
  alt.theta = StartFromRegression(alt, recs, setup, &sig_alt);
  const std::vector<double> scale = ScaleOf(*next, next->theta, sig, recs, setup),
                            scale_alt = ScaleOf(alt, alt.theta, sig_alt, recs, setup);
  FitResult refit, refit2;
  // The two fits are independent: with two CPUs, run them side by side. With several records each fit
  // runs on one thread (a fit spreads its records over the CPUs, and three records on two cores leave one
  // idle half the time); with one record each keeps its threads (the record's simulation uses one core, a
  // fit's sequential stages — CRS2, the trace — leave the other idle, and the two fits fill each other's
  // gaps). Fits do not depend on their thread count (Identify.FitsOfSeveralRecordsDoNotDependOnThreads,
  // Identify.OneRecordFitOnTwoThreadsEqualsTheSequentialFit).
  const int cpus = opt.fit.threads > 0 ? opt.fit.threads : UsableCpus();
  if (cpus >= 2) {
    FitOptions one = opt.fit;
    if (recs.size() > 1) one.threads = 1;
    RunBeside([&] { refit2 = Fit(alt, scale_alt, recs, setup, one); },
              [&] { refit = Fit(*next, scale, recs, setup, one); });
  } else {
    refit = Fit(*next, scale, recs, setup, opt.fit);
    refit2 = Fit(alt, scale_alt, recs, setup, opt.fit);
  }
  const bool p1 = Physical(*next, refit.theta), p2 = Physical(*next, refit2.theta);
  if ((p2 && !p1) || (p2 == p1 && ErrorOf(refit2, opt.fit.objective) < ErrorOf(refit, opt.fit.objective)))
    refit = refit2;
  return refit;
}

}  // namespace

// Whether a confirmed refit with term `t` (model `next` = `m` with t) gained by the term or by leaving the
// fit's basin: when every parameter of t ends within 2σ of zero (or at zero) and the model without it, at the
// refit's other values, keeps all but min_improvement of the gain, it is the latter, and *without is that
// model's fit (θ, σ and covariance without t's rows; its errors evaluated).
bool GainWithoutTheTerm(const IdentModel& m, const IdentModel& next, const FitResult& refit, const TermDef* t,
                        double before, const std::vector<PreparedRecord>& recs, const Setup& setup,
                        const IdentifyOptions& opt, FitResult* without) {
  const int off = next.Offset(t), np = static_cast<int>(t->params.size()), n = static_cast<int>(refit.theta.size());
  if (off < 0 || off + np > n || static_cast<int>(refit.sigma.size()) != n) return false;
  std::vector<int> term, keep;
  for (int i = 0; i < n; ++i) (i >= off && i < off + np ? term : keep).push_back(i);
  const bool has_cov = refit.covariance.rows() == n && refit.covariance.cols() == n && refit.covariance.allFinite();
  // Σ_tt's factorisation, when it is positive definite: the Wald test and the conditional covariance.
  std::optional<Eigen::LDLT<Eigen::MatrixXd>> tt;
  if (has_cov) {
    Eigen::LDLT<Eigen::MatrixXd> ldlt(refit.covariance(term, term));
    if (ldlt.info() == Eigen::Success && ldlt.vectorD().minCoeff() > 0) tt = std::move(ldlt);
  }
  Eigen::VectorXd th_t(np);
  for (int j = 0; j < np; ++j) th_t[j] = refit.theta[off + j];
  if (!th_t.isZero(0.0)) {  // exactly zero: the model without t is the same model
    constexpr double kChi2_95[] = {3.841, 5.991, 7.815, 9.488, 11.070, 12.592};
    if (!tt || np > 6) return false;  // no covariance, or a singular one: cannot tell, significant
    if (!(th_t.dot(tt->solve(th_t)) < kChi2_95[np - 1])) return false;  // NaN: significant
  }
  FitResult w;
  for (int i : keep) w.theta.push_back(refit.theta[i]), w.sigma.push_back(refit.sigma[i]);
  if (w.theta.size() != m.theta.size()) return false;
  if (has_cov) {  // conditional on θ_t = 0: the model without t has no t to trade against
    const Eigen::MatrixXd s_kk = refit.covariance(keep, keep), s_kt = refit.covariance(keep, term);
    w.covariance = tt ? Eigen::MatrixXd(s_kk - s_kt * tt->solve(s_kt.transpose())) : s_kk;
    for (int i = 0; i < static_cast<int>(keep.size()); ++i) w.sigma[i] = std::sqrt(std::max(0.0, w.covariance(i, i)));
  }
  const double horizon = opt.fit.objective == Objective::kShooting ? opt.fit.shooting_horizon_s : 0;
  w.errors = Evaluate(m, w.theta, recs, setup, horizon);
  w.simulations = refit.simulations + 1;
  w.seconds = refit.seconds;
  w.message = refit.message;
  const double e = ErrorOf(w, opt.fit.objective), after = ErrorOf(refit, opt.fit.objective);
  if (!(e <= after + opt.min_improvement * (before - after)) || !(e < before * (1.0 - opt.min_improvement)))
    return false;
  *without = std::move(w);
  return true;
}

namespace {

// An added effect's values and σ as fitted in `fit` of model `m`.
void TakeValues(AddedEffect* a, const IdentModel& m, const FitResult& fit) {
  const int off = m.Offset(*FindTerm(a->term));
  for (size_t j = 0; j < a->names.size(); ++j) a->params[j] = fit.theta[off + j], a->sigma[j] = fit.sigma[off + j];
}

AddedEffect Added(const TermDef* t, const IdentModel& m, const FitResult& fit, double before, double after) {
  AddedEffect a;
  a.term = t->id;
  for (const TermParam& p : t->params) a.names.push_back(p.name), a.units.push_back(p.unit);
  a.params.resize(t->params.size());
  a.sigma.resize(t->params.size());
  TakeValues(&a, m, fit);
  a.error_before = before;
  a.error_after = after;
  return a;
}

// The verdict of a round whose best candidate is not added: its refit feeds energy into the beam (not `physical`),
// or did not confirm it.
std::string NotAddedVerdict(const TermDef* t, const IdentModel& next, const FitResult& refit, double before,
                            double after, bool physical) {
  char buf[512];
  if (!physical) {
    const int pz = next.PiezoIndex();
    std::snprintf(buf, sizeof buf,
                  "%s scored best but its refit feeds energy into the beam (a c = %.3g < 0; error %.3g %% -> %.3g "
                  "%%); not added",
                  t->id.c_str(), refit.theta[pz] * refit.theta[pz + 2], before, after);
  } else {
    std::snprintf(buf, sizeof buf,
                  "%s scored best but the refit by simulation did not confirm it (error %.3g %% -> %.3g %%); not added",
                  t->id.c_str(), before, after);
  }
  return buf;
}

// The verdict of a round whose refit gained by leaving the basin (GainWithoutTheTerm): the model without the term
// keeps the gain (its error `e`).
std::string LeftTheBasinVerdict(const TermDef* t, double before, double after, double e) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "%s scored best and its refit gained (error %.3g %% -> %.3g %%), but by leaving the fit's basin: its "
                "parameters ended insignificant (Wald test, 95 %%) and the model without it keeps the gain (%.3g %%); "
                "not added, the model before goes on at the refit's values",
                t->id.c_str(), before, after, e);
  return buf;
}

// Why the loop stopped, for the diagnostics: its last step's verdict, or that it reached --max-added.
std::string StopReason(const IdentifyResult& out) {
  const bool went_on =
      !out.steps.empty() && (!out.steps.back().chosen.empty() || out.fits.back().refound);  // not a stop
  return out.steps.empty() ? "--max-added 0, nothing traced"
         : went_on         ? "it reached --max-added after: " + out.steps.back().verdict
                           : out.steps.back().verdict;
}

}  // namespace

// `recs` by value: their output weights may be re-estimated below.
// --bootstrap N: the final fit's σ and covariance from N refits of its twin records (identify/bootstrap.h), with
// the final objective (the long simulation of whole records when the horizon continuation ran); the Gauss–Newton
// σ stays in *b. Without twin records the Gauss–Newton covariance stands and b->note says why.
static void Bootstrap(const IdentModel& m, const std::vector<PreparedRecord>& recs, const Setup& setup,
                      const IdentifyOptions& opt, const ObjectiveChoice& choice, FitResult* fit, BootstrapResult* b) {
  FitOptions fo = opt.fit;
  std::vector<PreparedRecord> fitted = recs;
  if (choice.continuation.ran) {
    fo.objective = Objective::kTime, fo.shooting_horizon_s = 0;
    for (PreparedRecord& r : fitted) r.horizon_s = 0, r.chaotic = false;
  }
  *b = BootstrapFit(m, *fit, fitted, setup, fo, opt.bootstrap);
  if (!b->ok()) return;
  fit->covariance = b->covariance;
  for (size_t i = 0; i < fit->sigma.size(); ++i) fit->sigma[i] = std::sqrt(std::max(0.0, b->covariance(i, i)));
}

IdentifyResult IdentifyIndexed(IdentModel m, std::vector<PreparedRecord> recs, const Setup& setup,
                               const IdentifyOptions& opt_in) {
  const auto t0 = std::chrono::steady_clock::now();
  IdentifyOptions opt = opt_in;  // --objective auto may choose multiple shooting below
  const bool reweight = opt.output_weights == IdentifyOptions::OutputWeights::kResidual;
  IdentifyResult out;
  std::vector<double> sigma0;
  StartDeclared(&m, recs, setup, &sigma0);
  if (opt.choose_objective && opt.fit.objective == Objective::kTime) {
    out.objective_choice = ChooseHorizons(m, &recs, setup, opt);
    if (out.objective_choice.objective == Objective::kShooting)
      opt.fit.objective = Objective::kShooting, opt.fit.shooting_horizon_s = out.objective_choice.horizon_s;
    if (out.objective_choice.theta.size() == m.theta.size()) m.theta = out.objective_choice.theta;
  }
  out.declared = m;
  // From the short-horizon fit the long simulation is fitted directly: that start already did the time
  // objective's short-horizon stages (and follows every record, or the objective would not be time). Run
  // again from it, those stages (with smoothed friction) left it: on a coupled null record the declared fit
  // ended at 25.3 % where its start and the truth give 2.9 %.
  FitOptions declared_fo = opt.fit;
  if (opt.fit.objective == Objective::kTime && out.objective_choice.theta.size() == m.theta.size())
    declared_fo.shooting_horizon_s = 0;
  FitResult fit = Fit(m, ScaleOf(m, m.theta, sigma0, recs, setup), recs, setup, declared_fo);
  // The reweighted declared fit starts from the first one (σ as scale): the same basin, new weights.
  if (reweight && ReweightOutputs(fit.errors, opt.fit.objective, setup, &recs)) {
    m.theta = fit.theta;
    fit = Fit(m, ScaleOf(m, m.theta, fit.sigma, recs, setup), recs, setup, opt.fit);
  }
  m.theta = fit.theta;
  out.before = fit;
  out.fits.push_back({m, fit, "", true});
  out.residual_before = ResidualForce(m, m.theta, recs, setup);
  const bool finite_fit = std::all_of(fit.theta.begin(), fit.theta.end(), [](double v) { return std::isfinite(v); });
  if (!finite_fit) {  // nothing to trace from (the caller reports the non-finite parameters as an error)
    LoopStep step;
    step.verdict = "the fit of the declared model gave non-finite parameters; nothing traced";
    out.steps.push_back(step);
  }
  // The loop goes on from `model` fitted as `f` (the last snapshot). When the output weights move, it is
  // refitted under the new ones; the step's verdict and errors stay those of `f` (both errors under one
  // set of weights), the model goes on, and is diagnosed, as refitted.
  auto go_on = [&](const IdentModel& model, const FitResult& f) {
    m = model;
    m.theta = f.theta;
    fit = f;
    if (reweight && ReweightOutputs(fit.errors, opt.fit.objective, setup, &recs)) {
      fit = Fit(m, ScaleOf(m, m.theta, fit.sigma, recs, setup), recs, setup, opt.fit);
      m.theta = fit.theta;
      out.fits.back().fit = fit;
      out.fits.back().model.theta = fit.theta;
    }
  };
  std::vector<std::string> passed_over;  // terms whose refit gained by leaving the basin (not chosen again)
  // Rounds that add a term count against --max-added; a refound one does not (it adds nothing), and each
  // passes its term over, so the loop still ends: at most max_added + the candidates' number of traces.
  const int max_traces = opt.max_added + static_cast<int>(FreshCandidates(m, recs, setup, opt).size());
  for (int round = 0, traces = 0; round < (finite_fit ? opt.max_added : 0) && traces < max_traces; ++round, ++traces) {
    if (CancelRequested()) break;  // what follows would be cut short (the caller reports nothing)
    const auto tr0 = std::chrono::steady_clock::now();
    LoopStep step = TraceResidual(m, m.theta, recs, setup, opt, passed_over);
    if (std::getenv("BISTABLE_IDENTIFY_DEBUG"))
      std::fprintf(stderr, "trace %.2f s\n",
                   std::chrono::duration<double>(std::chrono::steady_clock::now() - tr0).count());
    if (step.chosen.empty()) {
      step.verdict = "no candidate beats the noise (ΔBIC < −" + std::to_string(static_cast<int>(opt.bic_threshold)) +
                     ", ≥ " + std::to_string(static_cast<int>(100 * opt.min_explained)) + " % of the residual, signed)";
      out.steps.push_back(step);
      break;
    }
    const TermDef* t = *FindTerm(step.chosen);
    IdentModel next;
    const FitResult refit = RefitWith(m, fit, t, step, recs, setup, opt, &next);
    const double before = ErrorOf(fit, opt.fit.objective), after = ErrorOf(refit, opt.fit.objective);
    const bool physical = Physical(next, refit.theta);
    const bool confirmed = physical && after < before * (1.0 - opt.min_improvement);
    out.fits.push_back({next, refit, t->id, confirmed});
    if (!physical || !confirmed) {
      step.verdict = NotAddedVerdict(t, next, refit, before, after, physical);
      step.chosen.clear();
      out.steps.push_back(step);
      break;
    }
    if (FitResult without; GainWithoutTheTerm(m, next, refit, t, before, recs, setup, opt, &without)) {
      // A better optimum of the model before the step: it goes on in that model's place (traced again).
      step.verdict = LeftTheBasinVerdict(t, before, after, ErrorOf(without, opt.fit.objective));
      step.chosen.clear();
      passed_over.push_back(t->id);
      out.steps.push_back(step);
      out.fits.back() = {m, without, t->id, true, true};
      go_on(m, without);
      --round;  // nothing was added
      continue;
    }
    char buf[512];
    std::snprintf(buf, sizeof buf, "added %s: error %.3g %% -> %.3g %%", t->id.c_str(), before, after);
    if (std::getenv("BISTABLE_IDENTIFY_DEBUG"))
      std::fprintf(stderr, "refit: %s (%d simulations, %.1f s)\n", refit.message.c_str(), refit.simulations,
                   refit.seconds);
    step.verdict = buf;
    out.steps.push_back(step);
    out.added.push_back(Added(t, next, refit, before, after));
    go_on(next, refit);
  }
  if (out.objective_choice.made && opt.fit.objective == Objective::kShooting && !CancelRequested())
    ContinueToLongSimulation(m, &fit, recs, setup, opt, &out.objective_choice.continuation);
  if (opt.bootstrap > 0 && !CancelRequested())
    Bootstrap(m, recs, setup, opt, out.objective_choice, &fit, &out.bootstrap);
  out.final_model = m;
  out.after = fit;
  for (AddedEffect& a : out.added) TakeValues(&a, m, fit);  // the final values (later additions refit everything)
  out.residual_after = ResidualForce(m, m.theta, recs, setup);
  out.diagnostics = Diagnose(out.fits, recs, setup, opt.fit, StopReason(out));
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace bistable
