// Harmonic balance for the stand-alone and coupled oscillators (model.md §4): each degree of freedom
// y_i(τ) = c_i0 + Σ_{k=1..H} (a_ik cos kΩτ + b_ik sin kΩτ); the linear terms are balanced exactly per
// harmonic, the cubic stiffness by alternating frequency–time (AFT: evaluate on Nt ≥ 4H+4 samples of
// one period, project back), Newton on the residual, pseudo-arclength continuation in Ω or α, and the
// stability of every point from the Floquet multipliers of its orbit's monodromy matrix.
// Non-convergence is a result: a point that fails is recorded with converged = false.
#ifndef BISTABLE_DYNAMICS_HBM_H_
#define BISTABLE_DYNAMICS_HBM_H_

#include <string>
#include <vector>

#include <Eigen/Dense>

#include "dynamics/point_spec.h"
#include "base/status.h"

namespace bistable {

enum class ContinuationParam { kOmega, kAlpha };

struct HbmOptions {
  ModelKind model = ModelKind::kStandalone;  // standalone | coupled | linear | linear-coupled
  NondimParams params;
  double alpha = 0.5, omega = 1.0;           // the parameter not continued stays fixed
  int harmonics = 5;                         // H
  bool zero_mean = false;                    // drop the constant terms (the paper's Eq. 9 ansatz)
  ContinuationParam param = ContinuationParam::kOmega;
  double from = 0.1, to = 3.0;               // continuation range of the parameter
  double ds = 0.02, ds_min = 1e-5, ds_max = 0.1;  // arclength step and its bounds
  int max_points = 4000;                     // per branch
  double newton_tol = 1e-10;                 // on the residual's max norm
  int newton_max_iter = 20;
  int floquet_steps = 400;                   // RK4 steps per period for the monodromy matrix
};

struct HbmPoint {
  double omega = 0, alpha = 0;
  double amplitude = 0;        // max |y_m| over a period
  double mean = 0;             // constant term of y_m
  double y_min = 0, y_max = 0; // extremes of y_m over a period
  bool stable = false;         // all Floquet multipliers inside the unit circle
  double max_multiplier = 0;   // largest |μ|
  bool converged = true;
  bool fold = false;           // the parameter turns here (saddle-node)
  bool branch_point = false;   // the augmented Jacobian's determinant changes sign without a fold
  std::vector<double> harmonics;  // y_m: c0, a1, b1, ..., aH, bH
  Eigen::VectorXd z;           // all coefficients (DOF-major)
};

// Where a periodic orbit of a bistable cell lives, by the rule of the maps' motion metric
// (point_metrics.cc): in the +well (y_m > 0 over the whole period, intrawell about +1), the −well
// (y_m < 0, about −1), or interwell (y_m crosses 0). Meaningless for the linear models (one well).
enum class OrbitWell { kPlus, kMinus, kInterwell };
OrbitWell WellOf(const HbmPoint& p);
const char* OrbitWellName(OrbitWell w);  // "+well", "-well", "interwell"

struct HbmBranch {
  std::vector<HbmPoint> points;
  std::string start;           // how the branch was seeded
};

struct HbmResult {
  std::vector<HbmBranch> branches;
  // Truncation check: max relative change of the amplitude on sample points when H grows by 2.
  double truncation_change = 0;
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
  // Floquet multipliers' largest modulus of the orbit z at (Ω, α).
  double MaxMultiplier(const Eigen::VectorXd& z, double omega, double alpha, int steps) const;
  HbmPoint Describe(const Eigen::VectorXd& z, double omega, double alpha, int floquet_steps) const;
  // Moves coefficients to H' harmonics (zero-padded or truncated).
  Eigen::VectorXd Resize(const Eigen::VectorXd& z, int h_new) const;

 private:
  int Index(int dof, int coeff) const { return dof * per_dof_ + coeff; }
  HbmOptions o_;
  int h_, dofs_, per_dof_, n_, nt_;
  double k_lin_, eps_;
  Eigen::Matrix2d c_, k_;  // damping and stiffness (top-left 1x1 for one DOF)
};

// The one-harmonic, zero-mean balance in closed form: the corrected counterpart of the paper's Eq. 9
// (which has sign and factor slips), for the stand-alone and the coupled oscillator. With complex
// amplitudes y = Re(Y e^{iΩτ}), F = −iαΩ², the linear resonator eliminates as Y_r = (F + cY_m)/d,
// c = λ² + iη_rΩ, d = λ² − Ω² + iη_rΩ, leaving (B + ¾ε q²) Y_m = F (1 + φc/d) with
// B = k_lin − Ω² + iηΩ − φcΩ²/d (φ = 0 without resonator): a cubic in q² = |Y_m|². Returns every
// positive real amplitude q, ascending.
std::vector<double> Eq9Amplitudes(ModelKind model, const NondimParams& p, double alpha, double omega);

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_HBM_H_
