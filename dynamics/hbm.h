// Harmonic balance for the stand-alone and coupled oscillators (model.md §4): each degree of freedom
// y_i(τ) = c_i0 + Σ_{k=1..H} (a_ik cos kωτ + b_ik sin kωτ), ω = Ω/ν (ν = 1: period-1 orbits; ν = 2, 4, ...:
// branches switched onto at period doublings); the linear terms are balanced exactly per harmonic, the
// cubic stiffness by alternating frequency–time (AFT: evaluate on Nt ≥ 4H+4 samples of one period,
// project back), Newton on the residual, pseudo-arclength continuation in Ω or α, and the stability of
// every point from the Floquet multipliers of its orbit's monodromy matrix. Along a branch, folds,
// period doublings (a real multiplier through −1) and Neimark–Sacker points (a complex pair through
// |μ| = 1) are flagged and located by bisection on the arclength step; folds can be continued in
// (α, Ω) (ContinueFoldCurve: the boundary of the bistable region).
// Non-convergence is a result: a point that fails is recorded with converged = false.
#ifndef BISTABLE_DYNAMICS_HBM_H_
#define BISTABLE_DYNAMICS_HBM_H_

#include <cmath>
#include <complex>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "base/status.h"
#include "dynamics/point_spec.h"

namespace bistable {

enum class ContinuationParam { kOmega, kAlpha };

struct HbmOptions {
  ModelKind model = ModelKind::kStandalone;  // standalone | coupled | linear | linear-coupled
  NondimParams params;
  double alpha = 0.5, omega = 1.0;  // the parameter not continued stays fixed
  int harmonics = 5;                // H
  bool zero_mean = false;           // drop the constant terms (the paper's Eq. 9 ansatz)
  ContinuationParam param = ContinuationParam::kOmega;
  double from = 0.1, to = 3.0;                    // continuation range of the parameter
  double ds = 0.02, ds_min = 1e-5, ds_max = 0.1;  // arclength step and its bounds
  int max_points = 4000;                          // per branch
  double newton_tol = 1e-10;                      // on the residual's max norm
  int newton_max_iter = 20;
  int floquet_steps = 400;  // RK4 steps per forcing period for the monodromy matrix
  // Period doubling: at every period-doubling point of a branch of period ν < 2^switch_depth, switch onto
  // the period-2ν branch (harmonics of Ω/2ν, 2H of them, at most 50) and continue it. 0: flag only.
  int switch_depth = 0;
  int subharmonic = 1;  // ν: harmonics of Ω/ν (the forcing is harmonic ν); set by switching
};

// A bifurcation located on the arclength step that ends at the flagged point (bisection on the step's
// corrected points until the parameter is bracketed to 1e-10).
struct HbmLocated {
  double omega = NAN, alpha = NAN;
  double amplitude = NAN;  // max |y_m| of the orbit there
  std::complex<double>
      multiplier;     // the critical multiplier there (≈ −1 at a period doubling, e^{±iθ} at Neimark–Sacker)
  Eigen::VectorXd z;  // the orbit there
  bool valid() const { return std::isfinite(omega) && std::isfinite(alpha); }
};

struct HbmPoint {
  double omega = 0, alpha = 0;
  double amplitude = 0;                           // max |y_m| over a period
  double mean = 0;                                // constant term of y_m
  double y_min = 0, y_max = 0;                    // extremes of y_m over a period
  bool stable = false;                            // all Floquet multipliers inside the unit circle
  double max_multiplier = 0;                      // largest |μ|
  std::vector<std::complex<double>> multipliers;  // all Floquet multipliers over the orbit's period, largest |μ| first
  int period = 1;  // forcing periods per orbit: ν (2 on a branch switched onto at a period doubling)
  bool converged = true;
  bool fold = false;             // the parameter turns here (saddle-node)
  bool branch_point = false;     // the augmented Jacobian's determinant changes sign without a fold
  bool period_doubling = false;  // a real multiplier passed through −1 on the step ending here
  bool neimark_sacker = false;   // a complex pair passed through the unit circle on the step ending here
  HbmLocated fold_at, period_doubling_at, neimark_sacker_at;  // located on that step (valid() when flagged)
  std::vector<double> harmonics;                              // y_m: c0, a1, b1, ..., aH, bH (harmonics of Ω/ν)
  Eigen::VectorXd z;                                          // all coefficients (DOF-major)
};

// Where a periodic orbit of a bistable cell lives, by the rule of the maps' motion metric
// (point_metrics.cc): in the +well (y_m > 0 over the whole period, intrawell about +1), the −well
// (y_m < 0, about −1), or interwell (y_m crosses 0). Meaningless for the linear models (one well).
enum class OrbitWell { kPlus, kMinus, kInterwell };
OrbitWell WellOf(const HbmPoint& p);
const char* OrbitWellName(OrbitWell w);  // "+well", "-well", "interwell"

struct HbmBranch {
  std::vector<HbmPoint> points;
  std::string start;  // how the branch was seeded ("period-doubling at alpha = ..." for switched ones)
  int period = 1;     // ν of its points
};

struct HbmResult {
  std::vector<HbmBranch> branches;
  // Truncation check: max relative change of the amplitude on sample points when H grows by 2.
  double truncation_change = 0;
  // What the continuation could not do and the user should know (e.g. a period doubling whose doubled
  // branch could not be seeded), one sentence each.
  std::vector<std::string> notes;
};

Status ValidateHbmOptions(const HbmOptions& o);

// Continues branches seeded from steady states of time integrations started at several initial
// conditions (both wells, a large-amplitude start) at the range's start.
StatusOr<HbmResult> ContinueBranches(const HbmOptions& o);

// The balance machinery, exposed for tests and for seeding from known solutions.
class HarmonicBalance {
 public:
  explicit HarmonicBalance(const HbmOptions& o);
  int size() const { return n_; }
  int dofs() const { return dofs_; }
  // R(z) at (Ω, α) and its Jacobian ∂R/∂z.
  void Residual(const Eigen::VectorXd& z, double omega, double alpha, Eigen::VectorXd* r, Eigen::MatrixXd* jac) const;
  // Newton from z at fixed (Ω, α); returns iterations (negative when it did not converge).
  int Solve(Eigen::VectorXd* z, double omega, double alpha) const;
  // Coefficients of a sampled steady state (one period of each DOF, evenly spaced) by projection.
  Eigen::VectorXd FromSamples(const std::vector<std::vector<double>>& samples) const;
  // y_m over one period at m points.
  std::vector<double> MainSamples(const Eigen::VectorXd& z, int m) const;
  // Monodromy matrix of w' = J(x(τ)) w over the orbit's period 2πν/Ω (RK4, steps per forcing period),
  // the state ordered (y_m, y_m', y_r, y_r').
  Eigen::MatrixXd Monodromy(const Eigen::VectorXd& z, double omega, int steps) const;
  // Its eigenvalues, the Floquet multipliers, largest |μ| first (real ones have imag exactly 0).
  std::vector<std::complex<double>> Multipliers(const Eigen::VectorXd& z, double omega, int steps) const;
  // Floquet multipliers' largest modulus of the orbit z at (Ω, α).
  double MaxMultiplier(const Eigen::VectorXd& z, double omega, double alpha, int steps) const;
  HbmPoint Describe(const Eigen::VectorXd& z, double omega, double alpha, int floquet_steps) const;
  // Moves coefficients to H' harmonics (zero-padded or truncated).
  Eigen::VectorXd Resize(const Eigen::VectorXd& z, int h_new) const;
  // The period-doubled counterpart (ν' = 2ν, H' harmonics) of z: harmonic k of Ω/ν becomes harmonic 2k of Ω/2ν.
  Eigen::VectorXd Doubled(const Eigen::VectorXd& z, int h_new) const;
  // The critical Floquet vector of a period doubling at (z, Ω): the variational solution from the
  // eigenvector of the multiplier nearest −1, continued anti-periodically over two periods, as
  // coefficients of the doubled balance (ν' = 2ν, H' harmonics; odd harmonics only), unit norm.
  // *mu: that multiplier. Empty when the monodromy has no real negative multiplier.
  Eigen::VectorXd DoublingDirection(const Eigen::VectorXd& z, double omega, int steps, int h_new,
                                    std::complex<double>* mu) const;
  int subharmonic() const { return nu_; }
  int harmonics() const { return h_; }

 private:
  int Index(int dof, int coeff) const { return dof * per_dof_ + coeff; }
  // Integrates the columns of *phi along the orbit over its period; each(s, phi) before step s.
  void Propagate(const Eigen::VectorXd& z, double omega, int steps, Eigen::MatrixXd* phi,
                 const std::function<void(int, const Eigen::MatrixXd&)>& each) const;
  HbmOptions o_;
  int h_, nu_, dofs_, per_dof_, n_, nt_;
  double k_lin_, eps_;
  Eigen::Matrix2d c_, k_;  // damping and stiffness (top-left 1x1 for one DOF)
};

// Two-parameter continuation of a fold in (α, Ω): the fold point (z, Ω, α) solves R = 0 together with
// the minimally augmented condition g = 0, where [J b; cᵀ 0] [v; g] = [0; 1] (J = ∂R/∂z, b and c the
// left and right null vectors of the previous point), continued by pseudo-arclength in (z, Ω, α). It
// passes through cusps (where two fold curves of the (α, Ω) plane meet), so one start traces both edges
// of a bistable (hysteresis) region.
struct FoldCurveOptions {
  double alpha_lo = 0.01, alpha_hi = 3.0, omega_lo = 0.05, omega_hi = 3.0;  // the box the curve stays in
  double ds = 0.01, ds_min = 1e-6, ds_max = 0.05;
  int max_points = 2000;  // per direction
};
struct FoldCurvePoint {
  double alpha = 0, omega = 0, amplitude = 0, mean = 0, y_min = 0, y_max = 0;
  bool cusp = false;  // the curve's (α, Ω) direction reverses here (its chords on either side point apart)
  Eigen::VectorXd z;
};
struct FoldCurve {
  std::vector<FoldCurvePoint> points;
  std::string start;      // the fold it was started from
  bool converged = true;  // false when the corrector failed before the curve left the box
};
// The arclength step after an accepted corrector, for every continuation (branches and fold curves): grow it
// when the corrector converged fast (≤ 3 iterations), shrink it when slowly (≥ 8), within [ds_min, ds_max].
double NextArclengthStep(int iterations, double ds, double ds_min, double ds_max);

Status ValidateFoldCurveOptions(const FoldCurveOptions& f);
// One fold curve through the fold at (z, Ω, α) (a point near it: the first corrector finds it at this α).
StatusOr<FoldCurve> ContinueFoldCurve(const HbmOptions& o, const FoldCurveOptions& f, const Eigen::VectorXd& z,
                                      double omega, double alpha);
// Fold curves through the located folds of the period-1 branches of r (continued with o), one per
// distinct curve: a fold already on a computed curve, or the mirror image (y → −y) of one, is skipped.
StatusOr<std::vector<FoldCurve>> ContinueFoldCurves(const HbmOptions& o, const FoldCurveOptions& f, const HbmResult& r);

// The one-harmonic, zero-mean balance in closed form: the corrected counterpart of the paper's Eq. 9
// (which has sign and factor slips), for the stand-alone and the coupled oscillator. With complex
// amplitudes y = Re(Y e^{iΩτ}), F = −iαΩ², the linear resonator eliminates as Y_r = (F + cY_m)/d,
// c = λ² + iη_rΩ, d = λ² − Ω² + iη_rΩ, leaving (B + ¾ε q²) Y_m = F (1 + φc/d) with
// B = k_lin − Ω² + iηΩ − φcΩ²/d (φ = 0 without resonator): a cubic in q² = |Y_m|². Returns every
// positive real amplitude q, ascending.
std::vector<double> Eq9Amplitudes(ModelKind model, const NondimParams& p, double alpha, double omega);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_HBM_H_
