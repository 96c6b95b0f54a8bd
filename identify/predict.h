// Predicting records with a fitted model, nothing refitted (`bistable identify --predict`; issue 18's
// cross-check: fit on one record, predict others).
//
// The model's own properties, from its parameters alone:
//  * the static restoring force of the main body, F(y) at y' = 0 = Σ c_k y^k: linear, y², y³ and y⁵
//    stiffness and the bias (damping, drag and friction vanish at rest; the piezo's voltage decays to 0
//    at rest when b > 0, so it adds no static force);
//  * its equilibria F(y) = 0 (real roots, ascending), stable where dF/dy > 0: the wells; a bistable
//    model has a barrier (an unstable equilibrium) with a well on each side, `left` and `right`, and
//    each well's depth V(barrier) − V(well), V(y) = ∫₀^y F. With a resonator the main body's equilibria
//    are the same (at rest G(z) = 0, so F(y) = G(z) = 0);
//  * the small-orbit (linearised) frequency in each well: mechanical, sqrt(K/m)/(2π) with K = dF/dy and
//    C = dF/dy' at (y_well, 0), m the main mass; with main.piezo (w' = −b w − c y', back-force a w) the
//    linearised beam and circuit, (m s² + C s + K)(s + b) + a c s = 0, whose oscillatory pair gives the
//    coupled frequency |s|/(2π) and damping ratio −Re s/|s|; and the circuit's added stiffness and
//    damping at the mechanical frequency ω: a c ω²/(b² + ω²) and a c b/(b² + ω²).
//
// A record's response at the drive: the amplitude of a signal's component at the drive frequency
// (the input's strongest line, invariants.h ForcingFrequency), by a Hann-weighted projection.
#ifndef BISTABLE_IDENTIFY_PREDICT_H_
#define BISTABLE_IDENTIFY_PREDICT_H_

#include <string>
#include <vector>

#include "identify/invariants.h"

namespace bistable {

// Real roots of Σ coef[k] y^k (coef[0] the constant), ascending, each polished by Newton steps; a
// polynomial of degree 0 has none. Companion-matrix eigenvalues of the polynomial in y/s, s the
// roots' magnitude bound, so coefficients of very different sizes (k_lin ~ 1e3, k5 ~ 1e12) stay
// well conditioned.
std::vector<double> RealPolynomialRoots(const std::vector<double>& coef);

// The coupled beam and circuit linearised in a well: the oscillatory pair of
// (m s² + C s + K)(s + b) + a c s = 0. NaN (both) when no root is complex (overdamped).
struct LinearMode {
  double hz = NAN;             // |s| / (2π), the undamped natural frequency of the pair
  double damping_ratio = NAN;  // −Re s / |s|
};
LinearMode CoupledMode(double m, double C, double K, double a, double b, double c);

struct Equilibrium {
  double y = NAN;          // m: the main body's displacement (relative to the base under a base input)
  bool stable = false;     // dF/dy > 0
  double stiffness = NAN;  // K = dF/dy at (y, 0), N/m
  double damping = NAN;    // C = dF/dy' at (y, 0), N s/m
  double energy = NAN;     // V(y) = ∫₀^y F, J
};

struct Well {
  std::string side;  // "left", "right", or "only" (monostable)
  Equilibrium at;
  double depth = NAN;            // V(barrier) − V(well), J (NaN without a barrier)
  double small_orbit_hz = NAN;   // sqrt(K/m)/(2π): the mechanical linearised frequency
  double damping_ratio = NAN;    // C / (2 sqrt(K m)), mechanical
  bool with_circuit = false;     // main.piezo: the coupled values below are set
  LinearMode coupled;            // beam and circuit together
  double piezo_stiffness = NAN;  // the circuit's added stiffness a c ω²/(b² + ω²) at ω = 2π small_orbit_hz, N/m
  double piezo_damping = NAN;    // its added damping a c b/(b² + ω²), N s/m
};

struct ModelStatics {
  std::vector<double> force_coef;       // F(y) at rest = Σ force_coef[k] y^k, k = 0..5, N
  double mass = NAN;                    // kg
  std::vector<Equilibrium> equilibria;  // ascending
  std::vector<Well> wells;              // bistable: left, right (either side of the barrier); monostable: one
  bool bistable = false;
  Equilibrium barrier;  // bistable only
  bool piezo = false;
  double piezo_a = NAN, piezo_b = NAN, piezo_c = NAN;
};

// The statics and small-orbit frequencies of (m, th). Errors: parameters not finite, a mass ≤ 0, no
// static restoring force, or no stable equilibrium. Several barriers (a quintic with five equilibria):
// the wells either side of the barrier nearest y = 0.
StatusOr<ModelStatics> AnalyseStatics(const IdentModel& m, const std::vector<double>& th);

// Amplitude of x's component at f_hz (ToneAmplitude: a sine of amplitude A at f_hz gives ≈ A); NaN for
// an empty or non-finite signal or frequency.
double AmplitudeAt(const std::vector<double>& x, double dt, double f_hz);

// One output of a predicted record, measured against predicted.
struct OutputPrediction {
  std::string name;                                            // OutputName: velocity, voltage, ...
  double nrmse = NAN, spectral = NAN;                          // %, as Evaluate
  double amplitude_measured = NAN, amplitude_predicted = NAN;  // at the drive frequency, output unit
  double rms_measured = NAN, rms_predicted = NAN;              // about the mean, output unit
};

// Well switching of one record, by three counts (switches per second):
//  * `measured` / `predicted`: invariants.h's rule (WellsOf) — y the zero-mean relative displacement
//    of each output (MainBodyMotion), changes of well by forcing period; `hysteresis` is its band, m;
//  * `well_measured` / `well_predicted`: the same y, hysteresis `well_hysteresis` = half the model's
//    smaller barrier-to-well distance, so an orbit within one well does not count;
//  * `model`: the model's own displacement (the state, not zero-mean: its initial value plus the
//    integral of its relative velocity) across the model's barrier with the same hysteresis; with
//    `model_right_fraction` the share of the time the model spends right of the barrier.
struct SwitchCounts {
  double measured = NAN, predicted = NAN, hysteresis = NAN;
  double well_measured = NAN, well_predicted = NAN, well_hysteresis = NAN;
  double model = NAN, model_right_fraction = NAN;
};

struct RecordPrediction {
  std::string name;
  double seconds = 0;
  double forcing_hz = NAN;       // the input's strongest line
  double input_amplitude = NAN;  // the input at forcing_hz, input unit (SI)
  double start_y = NAN;          // the model's initial displacement, m
  bool diverged = false;
  std::vector<OutputPrediction> outputs;  // every measured output, main first
  double displacement_amplitude_measured = NAN, displacement_amplitude_predicted = NAN;  // y at forcing_hz, m
  double mean_displacement_measured = NAN;   // displacement outputs only (a velocity output cannot give it), m
  double mean_displacement_predicted = NAN;  // the model's own y, m
  SwitchCounts switches;
  bool chaotic = false;  // CheckChaos on this record alone
  double output_broadband = NAN;
  Invariants invariants;  // set when chaotic
};

// Simulates the record with (m, th) (r.index picks m's start offset, if any) and compares. `statics`
// from AnalyseStatics(m, th); `objective`: kFft marks every record chaotic (CheckChaos).
RecordPrediction PredictRecord(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                               const Setup& setup, const ModelStatics& statics, Objective objective);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_PREDICT_H_
