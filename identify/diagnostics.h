// What the loop (loop.h) reports about its result beyond the error: is the final residual white,
// and if not, what is left unexplained; how strongly the fitted parameters are correlated, how far
// the declared ones drift when a candidate is added, and — when dissipative terms trade off — which
// records would separate them; for chaotic records, the invariants (invariants.h) of every fit.
//
// Whiteness (WhitenessTest). The residual of the final model: the simulation error sim − meas of every
// record, or for chaotic records the short-horizon one (the state reset to the measured one every
// shooting horizon: a chaotic simulation error is not expected to be small). Each record's residual is
// band-limited to [0, f_band] (f_band: the record's derivative cutoff, 4× the output's 99.9 % power
// bandwidth — above it lies sensor noise the model does not claim) by an FFT brick wall and
// resampled at the band's Nyquist rate (every d-th sample, d = ⌊1/(2 f_band dt)⌋), which leaves white
// noise white; n_eff = n / d is the effective sample count. Ljung–Box on that series,
//   Q = n_eff (n_eff + 2) Σ_{k=1..h} ρ_k² / (n_eff − k),   h = min(20, n_eff / 5),
// summed over records (dof = Σ h), p = P(χ²_dof > Q). With thousands of samples Ljung–Box finds
// structure far too small to matter (the synthetic null case: the simulator's own < 0.05 % mismatch
// against the reference gives p ≈ 6e-4), so the size counts too: the spectral flatness of the
// band-limited residual (geometric over arithmetic mean of its Welch periodogram; 1 for white noise,
// → 0 for lines), whose complement is the share of the residual a linear predictor could take from
// its past. Far from white ⇔ p < α (1e-3) and that predictable share ≥ 10 % (white noise of these
// lengths gives 3–5 %, the Welch estimate's bias). Reported with them: the residual's strongest
// spectral lines below f_band.
//
// Unexplained. A final residual that is not white means the model lacks something (so does a final
// model that diverges from the measured state before anything could be tested). When the loop
// stopped because no candidate qualified (or the best one's refit did not confirm it, or --max-added
// was reached), that is said with the statistic and the residual's lines — and nothing is added for
// it: the trace's acceptance (ΔBIC, explained share, sign, refit improvement; loop.h) is unchanged.
//
// Correlations: ρ_ij = C_ij / sqrt(C_ii C_jj) of the final fit's Gauss–Newton covariance (FitResult::
// covariance; time objective only), pairs with |ρ| > 0.9. Drift: for every refit with a candidate,
// each parameter of the model before it: relative change (after − before)/|before| and in units of its
// σ before. Separability: when a dissipative term of the final model is correlated beyond 0.9 with
// another term, or a refit moves a dissipative parameter by more than 30 % (the pair: it and the term
// added) and the term was not kept, or was kept while the final fit still correlates the two beyond 0.9
// (or has no covariance: the spectral objective), the records cannot tell the two apart; a kept term
// that the final fit separates (|ρ| < 0.9) only says the declared value had absorbed its effect;
// the hint names what would: terms whose force grows with a different power of the amplitude (viscous
// 1, y² damping 3, v³ damping 3, drag 2, friction 0; measured from the basis at the records' amplitude)
// separate with records at other amplitudes; terms of the same power but a different split between
// displacement and velocity (y² v against v³) with records at another frequency.
#ifndef BISTABLE_IDENTIFY_DIAGNOSTICS_H_
#define BISTABLE_IDENTIFY_DIAGNOSTICS_H_

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "identify/fit.h"
#include "identify/invariants.h"

namespace bistable {

inline constexpr double kWhitenessAlpha = 1e-3;
inline constexpr double kPredictableShare = 0.1;
inline constexpr double kStrongCorrelation = 0.9;
inline constexpr double kLargeDrift = 0.3;

struct Whiteness {
  double statistic = NAN;  // Ljung–Box Q, summed over records
  int dof = 0;             // lags, summed over records
  double p_value = NAN;    // P(χ²_dof > Q)
  double alpha = kWhitenessAlpha;
  double n_eff = 0;                 // band-limited samples, all records
  double flatness = NAN;            // spectral flatness of the band-limited residual, mean over records
  bool white = true;                // p ≥ alpha, or 1 − flatness < kPredictableShare
  std::vector<double> dominant_hz;  // strongest lines of the residual below the band edge, strongest first (≤ 3)
  std::string residual;             // which residual was tested
  bool diverged = false;            // a record's simulation diverged: its residual tested up to there
  // Records fitted on short horizons: the largest predictable share (1 − flatness) of the same test on the
  // final model's twin records (TwinRecords: nothing missing), NaN when not calibrated. Then far from white
  // means also beyond it: 1 − flatness ≥ twin_predictable_share + kPredictableShare.
  double twin_predictable_share = NAN;
};

// Whiteness of residual series (one per record, sampled every dt[i]), each band-limited to
// [0, band_hz[i]] (band_hz ≤ 0 or above Nyquist: the whole band). Series under 64 samples or with a
// non-finite value are left out; with none left, dof = 0 and the residual counts as white.
Whiteness WhitenessTest(const std::vector<std::vector<double>>& residuals, const std::vector<double>& dt,
                        const std::vector<double>& band_hz, double alpha = kWhitenessAlpha);

// The whiteness verdict of a white residual in words, as `bistable identify` prints it: what was tested and
// what its p means ("residual indistinguishable from white noise: Ljung–Box test of its autocorrelation on 20
// lags, p = 0.31 (p: the chance that white noise correlates this much; p < 0.001 would say it is not white)");
// when p < alpha, why it still counts as white (the predictable share under its bound); dof = 0: not tested.
std::string WhitenessVerdict(const Whiteness& w);

struct ParamCorrelation {
  std::string a, b;
  double rho = NAN;
};
// Pairs with |ρ| > threshold of a covariance over `names`, strongest first.
std::vector<ParamCorrelation> StrongCorrelations(const std::vector<std::string>& names, const Eigen::MatrixXd& cov,
                                                 double threshold = kStrongCorrelation);

struct ParamDrift {
  std::string name;
  double before = NAN, after = NAN;
  double relative = NAN;  // (after − before) / |before|
  double in_sigma = NAN;  // (after − before) / σ_before (NaN without σ)
};
// Every parameter of `before` that `after` still has (matched by name).
std::vector<ParamDrift> DriftOf(const IdentModel& before, const FitResult& fit_before, const IdentModel& after,
                                const FitResult& fit_after);

// A fit the loop made: the declared model's, then every refit with a candidate, kept or not.
struct FitSnapshot {
  IdentModel model;
  FitResult fit;
  std::string term;  // the candidate added ("" for the declared fit)
  bool kept = false;
  // The refit with `term` gained by leaving the fit's basin, not by the term (GainWithoutTheTerm): the
  // snapshot is the model before the step at the refit's other values, kept in its place.
  bool refound = false;
};

struct StepDiagnostics {
  std::string term;
  bool kept = false;
  bool refound = false;           // FitSnapshot::refound
  std::vector<ParamDrift> drift;  // the model before against this refit
  Invariants before, after;       // when the records are chaotic
  std::string attractor_loss;     // AttractorLoss(before, after), chaotic records
};

struct LoopDiagnostics {
  ChaosCheck chaos;
  Invariants declared, final;          // the declared fit and the final model (chaotic records)
  std::string attractor_loss;          // AttractorLoss(declared, final): what the loop's model lost
  std::vector<StepDiagnostics> steps;  // one per refit, in order
  Whiteness whiteness;  // of the final model's residual: the first output far from white, else the main one
  std::vector<std::pair<std::string, Whiteness>> whiteness_by_output;  // every measured output, by OutputName
  std::string unexplained;  // "" when the residual is white, else what is left and why
  std::vector<ParamCorrelation> correlations;
  std::vector<std::string> separability;  // hints: which records would separate terms these cannot
  std::vector<std::string> absorbed;      // a declared value that moved > 30 % when a term was added and kept,
                                          // while the final fit separates the two (|ρ| < 0.9)
};

// What the free run of a model (its invariants `after`) lost of the measured attractor that the model
// before it (`before`) still had; "" when nothing. A step can fit the short horizons better and still do
// this (the asym harvester record over 40 s: the piezo lowers the short-horizon error 72 → 56 % while the
// model stops changing well). Lost are: the changes of well — the record changes well, `before` did, and
// `after` does not (no change over the record, or no second well); and the section — `before` within the
// measured section's half-against-half floor, `after` beyond it (or not computed).
std::string AttractorLoss(const Invariants& before, const Invariants& after);

// v with `digits` significant digits (printf %g), as the messages above and the reports print numbers.
std::string FormatSignificant(double v, int digits);

// The diagnostics of a loop's fits (fits[0] the declared model's; the final model is the last one
// kept); `stop` says why the loop stopped (its last verdict).
LoopDiagnostics Diagnose(const std::vector<FitSnapshot>& fits, const std::vector<PreparedRecord>& recs,
                         const Setup& setup, const FitOptions& fo, const std::string& stop);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_DIAGNOSTICS_H_
