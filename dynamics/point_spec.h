// Options in, Summary out (after ceres Solver::Options / Summary): PointSpec says what to integrate
// and measure at one (α, Ω) point of a non-dimensional model; PointResult carries every metric of
// model.md §3. All quantities are non-dimensional (time τ = ωn t, lengths in units of δs).
#ifndef BISTABLE_DYNAMICS_POINT_SPEC_H_
#define BISTABLE_DYNAMICS_POINT_SPEC_H_

#include <array>
#include <limits>
#include <string>
#include <vector>

#include "base/status.h"

namespace bistable {

// Bumped whenever a change can alter any stored number; part of every result's provenance and content key.
inline constexpr const char* kNumericsVersion =
    "1.6.0";  // 1.3.1: diverged points' extremes and energies NaN, not 0; 1.4.0: settled labels (a mode; metrics
              // settle_time, lle_sigma, label_confidence, chaos_01); 1.5.0: the rig's (model = "dimensional") default
              // integrator is ROS34PW2 in lanes, rtol 5e-6 (was Dormand–Prince, rtol 1e-6); 1.6.0: a rig or term
              // model without a resonator starts its tangent on (y, y') (its LLE read 0), term forces in the lane
              // form (rounding), term wells sought to |q| = 1 km

// The models of the project (docs/model.md). The first four are the non-dimensional cells that a point,
// HBM, a chirp and the SIMD kernel run; series chains and the dimensional rig run in sweeps only, through
// the lane kernel (RK4, dynamics/ensemble_generic.h) or one point at a time (adaptive; engine/evaluate.cc).
enum class ModelKind {
  kStandalone,     // bistable beam alone (paper Eq. 2)
  kCoupled,        // bistable beam + linear resonator (paper Eq. 3)
  kLinear,         // linear oscillator alone (k_lin = +1, ε = 0)
  kLinearCoupled,  // linear oscillator + resonator
  kSeries,         // N cells in series (paper §6.3)
  kDimensional,    // the dimensional rig with c0 + c2 y² damping and Stribeck friction, SI units
};
const char* ModelName(ModelKind m);
// One of the four cell models (points, HBM, chirps); the message lists those four.
StatusOr<ModelKind> ParseModel(const std::string& name);
// Any of the six (sweep specs).
StatusOr<ModelKind> ParseAnyModel(const std::string& name);
bool IsCellModel(ModelKind m);
bool HasResonator(ModelKind m);
bool IsBistable(ModelKind m);

// kRosenbrock: ROS34PW2 in lanes with adaptive steps per lane (dynamics/ensemble_rosenbrock.h), for
// model = "dimensional" sweeps only (the rig's stiff friction); rtol and atol are its tolerances.
enum class IntegratorKind { kRk4, kAdaptive, kRosenbrock };
// The largest forcing phase per output step kRosenbrock covers (Ω dt ≤ 0.8 rad: at least 7.9 output
// steps per forcing period; its stage polynomials of sin and cos, ensemble_rosenbrock.h).
inline constexpr double kMaxPhasePerStep = 0.8;
const char* IntegratorName(IntegratorKind k);
StatusOr<IntegratorKind> ParseIntegrator(const std::string& name);

struct NondimParams {
  double eps = 1.0;      // ε, cubic stiffness (bistable only), > 0
  double eta = 0.1;      // η = c/(m_m ωn), main damping, ≥ 0
  double eta_r = 0.075;  // η_r = c_r/(m_r ωn), resonator damping, ≥ 0
  double phi = 2.0;      // φ = m_r/m_m, mass ratio, > 0
  double lambda = 0.8;   // λ = ω_r/ωn, resonator tuning, > 0
};

// How a point's labels are read (docs/numerics.md, "Settled labels"): kPaper from the one window
// [t_keep, t_end] (the paper's method, `reproduce paper`); kSettled from a chain of windows of
// `settle_window` τ from t_keep, extended until two consecutive windows agree (and, for chaos, λ − 2σ_λ
// exceeds the threshold), up to a cap; t_end is then unused.
enum class LabelMode { kPaper, kSettled };
const char* LabelModeName(LabelMode m);
StatusOr<LabelMode> ParseLabelMode(const std::string& name);

struct IntegrationSettings {
  IntegratorKind integrator = IntegratorKind::kRk4;
  double t_end = 500.0;   // τ at the end of the run; the run starts at τ = 0
  double t_keep = 250.0;  // steady-state window is [t_keep, t_end]
  double dt = 0.01;       // RK4 step; for the adaptive pair, the output sampling step
  double rtol = 1e-9;     // adaptive pair only: relative tolerance
  double atol = 1e-11;    // adaptive pair only: absolute tolerance
  LabelMode labels = LabelMode::kPaper;
  double settle_window = 125.0;    // kSettled: window length τ (a whole number of steps)
  int settle_min_strobes = 8;      // kSettled: a window spans at least this many forcing periods (whole windows)
  double settle_confirm = 2000.0;  // kSettled: τ after t_keep before a chaotic or quasi-periodic label is given
  double settle_cap = 6000.0;      // kSettled: τ after t_keep (at least two windows): unresolved beyond
};

struct MetricSettings {
  int renorm_every = 50;          // Benettin: renormalise the tangent every this many steps
  double chaos_threshold = 0.01;  // LLE (per unit τ) above which motion is called chaotic
  double quasi_lle = 0.003;       // settled labels: |λ| at most this with no period: quasi-periodic/marginal
  // Settled labels: chaos also needs the 0-1 test's K above this (settle.h); −1 (the default) stores K
  // without a veto — as a veto at 0.5 it cost recall and removed no transient chaos (docs/numerics.md).
  double chaos_01_min = -1.0;
  int sample_every = 5;         // window samples for spectrum / Rosenstein / trace: every k-th step
  double period_tol = 1e-3;     // stroboscopic samples closer than this (in y and y') repeat
  int max_period = 16;          // largest period n looked for
  double hd_level = 0.01;       // spectral peaks kept if amplitude ≥ hd_level × largest peak
  int hd_top_k = 10;            // at most this many peaks reported
  bool rosenstein = true;       // also estimate the LLE from sampled y_m (Rosenstein 1993)
  bool keep_samples = false;    // return the sampled window (for --trace)
  bool turning_points = false;  // sweeps: store y_m at y_m' = 0 (bifurcation diagrams)
  // Phase φ ∈ [0, 2π) of the stroboscopic samples τ_k = (φ + 2πk)/Ω: the Poincaré section and the
  // period test both use them (0: τ_k = 2πk/Ω).
  double poincare_phase = 0;
  int poincare_points = 0;  // sweeps: store the last this many section points (y_m, y_m'); 0 = none
};

struct PointSpec {
  ModelKind model = ModelKind::kCoupled;
  NondimParams params;
  double alpha = 1.0;  // α = A0/δs, base amplitude, > 0
  double omega = 1.0;  // Ω = ω0/ωn, base frequency, > 0
  // Initial state (y_m, y_m', y_r, y_r') relative to the table. Unset: at rest in the positive well
  // y_m = y_r = 1/√ε for bistable models, the origin for linear ones (model.md §1).
  bool ic_given = false;
  std::array<double, 4> ic = {0, 0, 0, 0};
  IntegrationSettings integration;
  MetricSettings metrics;
  // A term model's parameters at this point (a sweep with model = "terms": engine/sweep_spec.h's TermsConfig, in
  // TermModel::ParamNames order); empty for every other model.
  std::vector<double> theta;
};

// Checks every field; the message names the field and the bound ("alpha = -1 violates alpha > 0").
Status ValidatePointSpec(const PointSpec& spec);
// The initial state actually used (default well start when !ic_given).
std::array<double, 4> InitialState(const PointSpec& spec);
// Number of steps of size dt in [0, t] (t is validated to be a whole number of steps).
long StepsFor(double t, double dt);

// kQuasiPeriodic (no period, |λ| ≈ 0, a strobe cloud that neither shrinks nor grows) and kUnresolved (no
// label settled within the cap) come from settled labels only.
enum class Motion { kIntrawell, kInterwell, kChaotic, kUndefined, kQuasiPeriodic, kUnresolved };
const char* MotionName(Motion m);

// How an integration ended. Anything but kOk leaves metrics NaN; it is a result, not an error.
enum class Termination { kOk, kDiverged, kStepSizeUnderflow, kMaxSteps };
const char* TerminationName(Termination t);

struct HdPeak {
  double freq;  // angular frequency, rad per unit τ (comparable with Ω)
  double amp;   // amplitude of y_m at that frequency (units of δs)
};

struct PointResult {
  Termination termination = Termination::kOk;
  double frf_db = 0;  // 20 log10(max|x̂_m'| / (αΩ)), absolute velocity, over the window
  double lle = 0;     // Benettin, per unit τ, over the window (settled: over [T/2, T] since t_keep)
  // Settled labels (NaN in the paper's mode): τ at which the label settled (the run's end), the
  // block-average standard error of lle, and the label's confidence in [0.5, 1] (Φ(|λ − threshold|/σ);
  // 0 when unresolved).
  double settle_time = std::numeric_limits<double>::quiet_NaN();
  double lle_sigma = std::numeric_limits<double>::quiet_NaN();
  double label_confidence = std::numeric_limits<double>::quiet_NaN();
  double chaos_01 = std::numeric_limits<double>::quiet_NaN();  // settled: the 0-1 test's K on the strobes of [T/2, T]
  double lle_rosenstein = 0;                                   // Rosenstein on sampled y_m; NaN when not computed
  Motion motion = Motion::kUndefined;
  int period = 0;          // stroboscopic period n (1, 2, ...), 0 when none found
  int strobe_samples = 0;  // number of stroboscopic samples in the window
  // A point of the attractor's stroboscopic (Poincaré) section, the same for every start that ends on
  // the same periodic attractor: of the last `period` strobe samples the one with the smallest y_m
  // (then y_m'); the last sample when no period was found; NaN without samples or when diverged.
  double strobe_y = 0, strobe_v = 0;
  double hd_index = 0;                     // fraction of spectral power away from integer multiples of Ω
  std::vector<HdPeak> hd_peaks;            // strongest first
  double y_min = 0, y_max = 0;             // extremes of y_m over the window
  double w_in = 0;                         // ∫ max(P, 0) dτ over the window (gross injected energy)
  double w_net = 0;                        // ∫ P dτ over the window
  double w_m = 0, w_r = 0;                 // dissipated in main damper / resonator damper over the window
  double delta_e = 0;                      // E(t_end) − E(t_keep)
  double edr_b = 0, edr_r = 0, edr_t = 0;  // 100 W_m/W_in, 100 W_r/W_in, 100 (W_m+W_r)/W_in  [%]
  double energy_balance_residual = 0;      // |∫P − W_m − W_r − ΔE| / max(W_in, tiny)
  std::vector<double> turning_points;      // y_m at y_m' = 0 in the window, in time order
  // Poincaré (stroboscopic) section over the window, in time order: the state at
  // τ_k = (φ + 2πk)/Ω for k = section_k0, section_k0 + 1, … (φ = metrics.poincare_phase); y_r, y_r'
  // only for models with a resonator. Empty when the run diverged.
  long section_k0 = 0;
  std::vector<double> section_y, section_v, section_yr, section_vr;
  std::array<double, 4> final_state = {0, 0, 0, 0};  // (y_m, y_m', y_r, y_r') at t_end
  long steps = 0;                                    // integrator steps taken (accepted)
  long rhs_evals = 0;                                // right-hand-side evaluations (adaptive path)
  // Sampled window rows (τ, y_m, y_m', y_r, y_r') every sample_every steps, when keep_samples.
  std::vector<std::array<double, 5>> samples;
};

// The result of a point whose integration diverged (or that could not be evaluated): termination
// kDiverged and every real-valued metric NaN — extremes and energies included, which read 0.0 before
// (a value a real run can have). Codes stay codes (motion and period 0); final_state as given.
PointResult DivergedResult(const std::array<double, 4>& final_state = {0, 0, 0, 0});

}  // namespace bistable

#endif  // BISTABLE_DYNAMICS_POINT_SPEC_H_
