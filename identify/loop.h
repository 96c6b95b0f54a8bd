// The measured-data loop (issue 5): fit the declared model, compute the force it fails to explain
// along the measured trajectory, score every library term not yet in the model against that
// residual, add the one the evidence supports (or none), refit by simulation, repeat (bounded).
//
// Tracing. Two residuals are scored against every candidate term c (k_c parameters β):
//  * the simulation-error residual e (the objective's residual vector, fit.h) — the deciding one, a
//    score test: −e ≈ J_θ δ + J_c β by least squares, with J the output sensitivities (exact
//    derivatives of the discrete simulation from its sensitivity equations, one pass for the declared
//    parameters and every candidate's; J_c at β = 0), so the declared values may shift while c enters;
//  * the restoring force the model lacks along the measured trajectory, r = b − X θ of the
//    equation-error rows (smoothed second derivatives: noisy, reported as supporting evidence and
//    drawn against displacement and velocity).
// A candidate is taken when, on the simulation residual,
//   ΔBIC = n_eff ln(RSS_c / RSS_0) + k_c ln(n_eff) < −bic_threshold   (n_eff: samples / correlation time
//   of the residual's part the declared columns leave; with twins, of the twins' — the null's — residual)
//   it explains at least `min_explained` of the residual's sum of squares,
//   its physically signed parameters come out with their sign (damping, drag, friction ≥ 0),
// and the best such candidate is kept only if the refit by simulation lowers the error by at least
// `min_improvement` (relative): evidence in the residual that the simulation does not confirm is
// reported and not added.
#ifndef BISTABLE_IDENTIFY_LOOP_H_
#define BISTABLE_IDENTIFY_LOOP_H_

#include <string>
#include <vector>

#include "identify/bootstrap.h"
#include "identify/diagnostics.h"
#include "identify/fit.h"
#include "identify/predictability.h"

namespace bistable {

struct CandidateScore {
  std::string term;
  double delta_bic = NAN;  // simulation residual (deciding)
  double explained = NAN;  // fraction of its sum of squares
  bool sign_ok = true;
  std::vector<double> estimate, sigma;  // the candidate's parameters from the linearised fit
  double force_delta_bic = NAN;         // restoring-force residual (supporting)
  double force_explained = NAN;
  // Records fitted on short horizons (chaotic, --objective auto): the largest share this candidate explains
  // of the residual of the fitted model's own twin records (TwinRecords), where nothing is missing; NaN when
  // not calibrated. The candidate qualifies only above kTwinFactor times it.
  double twin_explained = NAN;
};

// A candidate must explain this many times what it explains on the fitted model's twins (the null).
inline constexpr double kTwinFactor = 2.0;

// ΔBIC of k more columns that leave RSS_c of RSS_0 (rss_ratio = RSS_c / RSS_0), with n_eff independent residuals.
double DeltaBic(double rss_ratio, size_t k, double n_eff);

struct LoopStep {
  std::vector<CandidateScore> scores;  // sorted, best first
  std::string chosen;                  // "" when nothing qualified
  std::string verdict;                 // why it stopped or what was added
  // The effective sample size ΔBIC counts (rows / correlation time): the twins' mean where they calibrate the
  // trace, else the record's own (record_n_eff, which a missing term's smooth signature shortens). RMS
  // residual force [N].
  double n_eff = 0, record_n_eff = 0, residual_rms = 0;
};

struct AddedEffect {
  std::string term;
  std::vector<std::string> names, units;
  std::vector<double> params, sigma;
  double error_before = NAN, error_after = NAN;  // NRMSE % (or FFT %) around this addition
};

// Residual force along the trajectory (main body rows), for the restoring-force plots.
struct ResidualCloud {
  std::vector<double> q, v, r;
};

struct IdentifyOptions {
  FitOptions fit;
  int max_added = 3;
  double bic_threshold = 10;
  double min_explained = 0.05;
  double min_improvement = 0.02;
  std::vector<const TermDef*> candidates;  // empty: every library term of a body the data constrain
  // Velocity outputs: fit a displacement offset per record (IdentModel::offsets), started from an
  // equation-error scan. Off by default: on the harvester's chaotic record it traded off against a
  // bias term (docs/identification.md).
  bool fit_offsets = false;
  // Several outputs: their weights in the joint error. kNoise: from the noise levels only
  // (SetOutputWeights). kResidual: from each output's error in the declared fit and again after every
  // added effect (ReweightOutputs in loop.cc), floored at the noise — the noise weights once the model
  // matches to the noise, and no output dominating because it is clean while the model misses it.
  enum class OutputWeights { kNoise, kResidual } output_weights = OutputWeights::kResidual;
  // --objective auto (with fit.objective kTime): each record's horizon chosen from the records before the
  // declared fit (ChooseHorizons): its whole simulation where that is meaningful, short horizons from the
  // measured state where it is chaos. False: every record's whole simulation (--objective time).
  bool choose_objective = false;
  // --bootstrap N: the final σ and covariance from N refits of the final model's twin records
  // (identify/bootstrap.h); 0: the Gauss–Newton covariance.
  int bootstrap = 0;
};

// The objective's choice (IdentifyOptions::choose_objective), per record. The twin experiment
// (predictability.h) runs at the regression start; when a record changes well (≥ 2 changes measured) or is
// unpredictable there, the declared model is first fitted on short horizons only (fit.shooting_horizon_s,
// no global stage: a model near the vector field, which the regression start with its noisy second
// derivatives is not) and the experiment repeated with it: that decides. Sets each record's horizon_s.
inline constexpr double kPrefitHorizon = 0.1;  // s, the short-horizon fit that decides
// A chaotic record's shooting segments are at most as long as the decision model, from fitted states, still
// follows the record: its shooting error on a segment no more than kFollowableGrowth × its error on
// kPrefitHorizon segments (ChooseHorizons halves the twins' horizon until it is). The twins bound the
// segment by the input's noise only; the segment's state fit must also find the orbit from the measured
// start, and over a long chaotic segment it does not: the true model's 0.5 s shooting error was 17.6 % and
// 6.7 % on two standalone records (0.34 and 0.41 % at 0.1 s, 0.43 and 0.60 % at 0.3 s). At 2× the bound let
// the shooting cost fall below the truth's on a chaotic coupled record (h_c_drag_12 at 0.5 s: a fit with the
// drag absorbed in c0 and F_c, 0.340 % against the truth's 0.365 %; the truth wins at 0.25 s), and a null
// standalone record's fit stopped in a neighbouring friction basin (s_null_15 at 0.38 s). At 1.25× both are
// right and 16 other cases of the 20 keep their verdicts; c_y2_14 was not measured (docs/identification.md).
inline constexpr double kFollowableGrowth = 1.25;
struct ObjectiveChoice {
  bool made = false;
  // The objective the loop runs: kTime when every record's long simulation is meaningful, else kShooting
  // (segments of `horizon_s` from re-estimated states: the states are unknowns, so noise in them does not
  // bias θ as restarts from the measured states do) with the shortest horizon of the chaotic records.
  Objective objective = Objective::kTime;
  double horizon_s = 0;
  std::vector<Predictability> records;  // the deciding experiment per record
  std::string model;                    // "regression start" or "short-horizon fit"
  // The short-horizon fit's parameters (empty when the regression start decided): the declared fit starts
  // from them. Fitted on 0.1 s horizons of the same records with the same terms, they are nearer the vector
  // field than the regression start; on a coupled record from the regression start the declared fit of the
  // long simulation stopped at 26.9 % (k3 and the friction far off) where the truth gives 2.92 %.
  std::vector<double> theta;
  // Horizon continuation: when the loop ran multiple shooting, the final model is tested again (twins, and
  // whether it follows each record); where it follows every record within kMeaningfulFloor and its twins
  // stay together, its long simulation is fitted from the shooting fit's values (the long simulation
  // error's narrow valley found from inside) and replaces the shooting fit when its long error is lower.
  // A record fitted by shooting because the decision model did not follow it (a missing effect, or a
  // model that understates the chaos) gets the long simulation where it can after all.
  struct Continuation {
    bool tried = false, ran = false;
    std::vector<Predictability> records;         // the final model's twin experiment
    double long_before = NAN, long_after = NAN;  // % long simulation error at the shooting fit and after
    std::string reason;
  } continuation;
  double seconds = 0;
};
ObjectiveChoice ChooseHorizons(const IdentModel& m, std::vector<PreparedRecord>* recs, const Setup& setup,
                               const IdentifyOptions& opt);

// The horizon continuation (ObjectiveChoice::Continuation) of the model m fitted as *fit by multiple shooting
// (opt.fit: the shooting objective and its horizon): *fit is replaced by m's long simulation fit when m
// follows every record with predictable twins and that fit lowers the long simulation error; *c says what
// was tried and why.
void ContinueToLongSimulation(const IdentModel& m, FitResult* fit, const std::vector<PreparedRecord>& recs,
                              const Setup& setup, const IdentifyOptions& opt, ObjectiveChoice::Continuation* c);

struct IdentifyResult {
  IdentModel declared, final_model;
  FitResult before, after;
  std::vector<LoopStep> steps;
  std::vector<AddedEffect> added;
  ResidualCloud residual_before, residual_after;
  std::vector<FitSnapshot> fits;     // the declared fit, then every refit with a candidate (kept or not)
  LoopDiagnostics diagnostics;       // whiteness / unexplained, correlations, drift, invariants (diagnostics.h)
  ObjectiveChoice objective_choice;  // --objective auto: which records are fitted on short horizons, and why
  BootstrapResult bootstrap;         // --bootstrap N (twins = 0 when not asked)
  double seconds = 0;
};

// Output weights from a fit's errors (IdentifyOptions::OutputWeights::kResidual): the level of output o
// is its relative error under the objective, floored at its relative noise ν_o, and λ_o = (level_main /
// level_o)² (SetOutputWeightsFrom). These are the maximum-likelihood weights when each output's error
// variance is estimated from its own residual. Noise weights alone say how well a perfect model would
// match: while the model misses by far more than the noise they let the cleanest output dominate (the
// harvester's voltage, σ 4 µV: λ = 100 at the clip; the fit then gave up velocity for voltage). True
// when a weight moved by more than a factor 2 (the fit is then repeated with the new weights).
bool ReweightOutputs(const Errors& e, Objective obj, const Setup& setup, std::vector<PreparedRecord>* recs);

// Whether a confirmed refit with term `t` (the model `next` = `m` with t, fitted: `refit`; `before`: the error
// of the fit of `m` it started from) gained by the term
// or by leaving the fit's basin (a restart from elsewhere can find a better optimum of the model before
// the step): true when t's parameters are not significant — all exactly zero, or a Wald test θ_tᵀ Σ_tt⁻¹ θ_t
// below the χ² 95 % quantile (one parameter: |θ| < 1.96 σ; NaN σ or no covariance: significant) — and
// the model without t, at the refit's other values, keeps the gain: its error at most after +
// min_improvement·(before − after) and below before·(1 − min_improvement). Then *without is that model's
// fit (θ; the covariance conditional on t = 0, Σ_kk − Σ_kt Σ_tt⁻¹ Σ_tk, and its σ; its errors evaluated)
// and the loop goes on from it, t not added and passed over by the next traces.
bool GainWithoutTheTerm(const IdentModel& m, const IdentModel& next, const FitResult& refit, const TermDef* t,
                        double before, const std::vector<PreparedRecord>& recs, const Setup& setup,
                        const IdentifyOptions& opt, FitResult* without);

IdentifyResult Identify(const IdentModel& declared, const std::vector<PreparedRecord>& recs, const Setup& setup,
                        const IdentifyOptions& opt);

// The residual force of a model with parameters `th` along the records (main-body rows).
ResidualCloud ResidualForce(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                            const Setup& setup);

// Scores every candidate against the residual of `m` (fitted `th`); exposed for tests and reports. Terms in
// `passed_over` (whose refit gained by leaving the basin, GainWithoutTheTerm) are scored but not chosen.
LoopStep TraceResidual(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                       const Setup& setup, const IdentifyOptions& opt,
                       const std::vector<std::string>& passed_over = {});

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_LOOP_H_
