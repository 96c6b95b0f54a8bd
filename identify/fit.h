// Fitting an IdentModel to prepared records.
//   1. Equation error (restoring-force regression): along the measured, smoothed trajectory the
//      equations of motion are linear in the parameters; least squares gives a start and the
//      residual force used to trace missing effects (loop.h).
//   2. Global stage: NLopt CRS2 (controlled random search with local mutation) in a box around the
//      start, on the simulation error; sign constraints are bounds.
//   3. Local stage: Ceres Levenberg–Marquardt on the simulation error (scaled parameters, exact
//      Jacobians from sensitivity equations, RK4 substeps held fixed so the objective is smooth).
//   Uncertainty: σ_θ from the Gauss–Newton covariance s²(JᵀJ)⁻¹ at the solution, inflated by the
//   residuals' correlation time (samples of a simulation error are far from independent).
// Objectives: "time" — Σ_records Σ_outputs λ_o NRMSE² (each record weighs the same; outputs weighted by
// their noise levels, model.h SetOutputWeights); "fft" — the paper's Eq. 20 on velocity spectra
// magnitudes (for chaotic records, where a time-domain match is not expected), normalised per record by
// the measured spectrum's norm (a voltage output: its own spectrum, weighted likewise); "shooting" —
// multiple shooting for chaotic records: the record cut into segments of a few forcing periods
// (FitOptions::shooting_horizon_s), each simulated from its own start state, which is re-estimated for
// every θ (Levenberg–Marquardt per segment from the measured state: variable projection), the error
// weighted as "time". The θ-Jacobian is the exact sensitivity with the state directions projected out
// per segment (Kaufman's variable-projection Jacobian), so a segment's error grows at most like
// e^{λ·horizon} and the fit sees the vector field, not the long-run phase of a chaotic orbit.
#ifndef BISTABLE_IDENTIFY_FIT_H_
#define BISTABLE_IDENTIFY_FIT_H_

#include <string>
#include <vector>

#include <Eigen/Dense>

#include "identify/model.h"

namespace bistable {

enum class Objective { kTime, kFft, kShooting };

// One output's errors (over all records): the output's name (OutputName), NRMSE and spectral error,
// and its noise level and weight in the joint fit (SetOutputWeights).
struct OutputErrors {
  std::string name;
  double nrmse = NAN, fft = NAN;  // %
  double shooting = NAN;          // % NRMSE of the segment predictions (shooting objective only)
  double noise = NAN;             // σ, RMS over records, output unit
  double weight = 1;              // λ of its NRMSE² in the objective
};

struct Errors {
  // % over all records: 100 sqrt(Σ e² / Σ (meas − mean)²) of the main output; with several outputs the
  // weighted mean over outputs, sqrt(Σ λ_o NRMSE_o² / Σ λ_o) (the loop's decision error). A record with its
  // own horizon (PreparedRecord::horizon_s > 0, a chaotic record) counts with its short-horizon error.
  double nrmse = NAN;
  double fft = NAN;   // % mean over records of 100 ‖|V_sim| − |V_meas|‖ / ‖V_meas‖
  double eq20 = NAN;  // the paper's Eq. 20 value, in the output's velocity unit (m/s)
  // % short-horizon error (Objective::kShooting, segments from re-estimated states): like nrmse, with
  // several outputs the λ-weighted mean; NaN for the other objectives.
  double shooting = NAN;
  std::vector<OutputErrors> outputs;  // every measured output, main first
  std::vector<double> record_nrmse;   // % per record (main output)
  std::vector<double> record_fft;     // % per record
  std::vector<double> record_rms;     // RMS of sim − meas per record, output unit
  // % NRMSE of the whole simulation of every record (main output), whatever the records' own horizons
  // (PreparedRecord::horizon_s): equal to nrmse's main-output part when no record has one. Pooled and per record.
  double long_nrmse = NAN;
  std::vector<double> record_long_nrmse;
  bool diverged = false;
};

// Integrated autocorrelation time of a series, 1 + 2 Σ_{k≥1} ρ_k summed up to the first ρ_k < 0.05 (lags below
// n/4 and max_lag): samples per independent sample, for σ (fit) and effective sample counts (the trace).
// 1 for fewer than 8 samples or a constant series.
double CorrelationTime(const double* e, size_t n, size_t max_lag);

// `shooting_horizon_s` > 0: also the shooting error (Errors::shooting) for segments of that length.
Errors Evaluate(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                const Setup& setup, double shooting_horizon_s = 0);

// Rows of the equation-error regression X θ = b over a subsample of every record (edges dropped).
struct Regression {
  Eigen::MatrixXd X;  // one column per parameter of the model it was built for
  Eigen::VectorXd b;
  std::vector<int> record_of_row;
  std::vector<double> q, v;  // main-body y, y' of each row (for residual plots)
};
// `extra` terms get columns after the model's own parameters (in the order given).
Regression BuildRegression(const IdentModel& m, const std::vector<PreparedRecord>& recs, const Setup& setup,
                           const std::vector<const TermDef*>& extra = {}, size_t max_rows = 40000);

struct LinearFit {
  std::vector<double> theta, sigma;
  double rss = 0;
};
// Least squares on a regression's columns; sign constraints by clipping to 0 and refitting the rest.
LinearFit SolveRegression(const Eigen::MatrixXd& X, const Eigen::VectorXd& b, const std::vector<Sign>& signs);

// The objective's residual vector (weighted: Σ squares = Σ_records NRMSE², or the normalised Eq. 20
// differences); substeps per record as Simulate (empty: automatic); `horizon_s`: the shooting objective's
// segment length. False on divergence.
bool ObjectiveResiduals(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                        const Setup& setup, Objective obj, const std::vector<int>& substeps, std::vector<double>* out,
                        double horizon_s = 0);
// The residual vector and its derivatives by θ (N × P: the model's parameters, then the `extra` terms'
// at value 0), exact for the discrete simulation (SimulateSensitivities). False on divergence.
// The spectral objective's Jacobian in scaled parameters u = θ / scale as a fit's local stage computes it:
// forward differences with the columns on `column_threads` threads — or, with ceres_reference, by Ceres'
// DynamicNumericDiffCostFunction<FORWARD>, which the fit's must equal to the bit. Row-major, residuals ×
// parameters; false when a simulation fails. For tests.
bool SpectralForwardJacobian(const IdentModel& m, const std::vector<double>& scale, const std::vector<double>& u,
                             const std::vector<PreparedRecord>& recs, const Setup& setup,
                             const std::vector<int>& substeps, int column_threads, bool ceres_reference,
                             std::vector<double>* residuals, std::vector<double>* jac);
bool ObjectiveJacobian(const IdentModel& m, const std::vector<double>& th, const std::vector<PreparedRecord>& recs,
                       const Setup& setup, Objective obj, const std::vector<int>& substeps,
                       const std::vector<const TermDef*>& extra, std::vector<double>* out, Eigen::MatrixXd* jac,
                       double horizon_s = 0);
// The shooting objective's segment length in samples of a record (≥ 2).
int ShootingSegment(double horizon_s, double dt);
// One record's outputs under the shooting objective: segments of horizon_s from re-estimated start
// states (shooting.h ShootRecord). False on divergence.
bool SimulateShooting(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r, const Setup& setup,
                      double horizon_s, SimOutputs* out);
// Substeps per record for parameters th held by a fit of objective `obj`: SubstepsFor times a safety factor;
// under the shooting objective OscillationSubsteps times the safety, at least StableSubsteps (sim_cost.cc).
std::vector<int> FixedSubsteps(const IdentModel& m, const std::vector<double>& th,
                               const std::vector<PreparedRecord>& recs, Objective obj, double safety = 1.5);

struct FitOptions {
  Objective objective = Objective::kTime;
  int global_evals = 150;   // CRS2 evaluations (0: local stage only)
  double global_box = 1.0;  // the box: θ0 ± global_box · max(|θ0|, σ0)
  int lm_iterations = 60;
  // Time objective: also start from a short-horizon fit (restarts from the measured state; 0: off).
  // Shooting objective: the segment length.
  double shooting_horizon_s = 0.5;
  // Time objective with friction terms: the short-horizon stage fits the law with its tanh transition
  // velocity v_t times this factor (a smoothed law; 1: the declared one), the full-error stage after it the
  // declared law from there (fit.cc, "Smoothed friction"). With a second factor a second short-horizon stage
  // runs beside the first, and the full-error stage starts from the result with the lower short-horizon cost
  // under the first factor's law (and the plain LM from the start is left out: fit.cc). One stage when either
  // factor is ≤ 1 or the two are equal.
  double shooting_friction_smoothing = 2.5;
  double shooting_friction_smoothing_second = 3.5;
  int threads = 0;  // records simulated in parallel (0: all cores)
};

struct FitResult {
  std::vector<double> theta, sigma;
  Eigen::MatrixXd
      covariance;  // Gauss–Newton covariance of theta (σ² on its diagonal); empty for the spectral objective
  Errors errors;
  int simulations = 0;
  double seconds = 0;
  std::string message;  // Ceres' summary line
};

// Fits m.theta (the start) and returns the fitted parameters. `scale`: typical magnitude of each
// parameter (for scaling and the global box).
FitResult Fit(const IdentModel& m, const std::vector<double>& scale, const std::vector<PreparedRecord>& recs,
              const Setup& setup, const FitOptions& opt);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_FIT_H_
