// Synthetic measured records made by the project's own simulator (dynamics/dimensional_model.h,
// Rosenbrock 2(3) at tight tolerance — a different integrator and formulation from the one the
// identification simulates with): the paper's rig under a chirp of the table, sampled like the
// paper's camera, with Gaussian measurement noise on the measured positions (and, when asked, on the
// recorded input), optionally with extra force terms of the effect library in the truth.
#ifndef BISTABLE_IDENTIFY_SYNTHETIC_H_
#define BISTABLE_IDENTIFY_SYNTHETIC_H_

#include <string>
#include <vector>

#include "dynamics/dimensional_model.h"
#include "dynamics/terms.h"
#include "identify/model.h"
#include "identify/record.h"

namespace bistable {

// A force term of the effect library and its parameter values (the library's order and units).
struct TermValues {
  const TermDef* term = nullptr;
  std::vector<double> values;
};

struct SyntheticOptions {
  double a0_m = 0.002;  // chirp amplitude of the table [m]
  double f_start_hz = 1, f_end_hz = 8, duration_s = 20;
  double fs_hz = 120;        // sampling rate (the paper's camera)
  double noise_m = 0.05e-3;  // standard deviation of the noise on x and x_r [m]
  unsigned seed = 1;
  double y0_m = 0;           // initial relative displacement (a well, for bistable beams)
  double input_noise_m = 0;  // standard deviation of the noise on the recorded input x0 [m]
  // Force terms of the effect library added to the rig's truth (the effect a declared model may lack).
  std::vector<TermValues> extra;
};

// "main.drag=5", "main.stiffness_y2=2e4", "res.stiffness_z3=1e6": a force term of the library (not friction,
// which the rig has on both bodies already, nor the piezo or an output term) with one value per parameter,
// ':'-separated; dissipative terms' values >= 0. Errors name the flag and the bound.
StatusOr<TermValues> ParseSyntheticExtra(const std::string& spec);
// The same from a term id and its values (the library's order and units), as a program gives them.
StatusOr<TermValues> SyntheticExtra(const std::string& term, const std::vector<double>& values);
// An extra term as ParseSyntheticExtra accepts it: a force term other than friction, one finite value
// (|value| <= 1e15) per parameter, dissipative ones >= 0 (field synthetic-extra).
Status CheckSyntheticExtra(const TermValues& extra);

// The truth as identify terms: the rig's own (main.linear, [main.stiffness_y3,] main.viscous, main.damping_y2,
// main.friction; with the resonator res.linear, res.viscous, res.damping_z2, res.friction) and the extras,
// each with its values — what a model file for `identify --predict` holds.
std::vector<TermValues> TruthTerms(const DimensionalParams& p, const std::vector<TermValues>& extra);
// The same truth as an identify model (masses and the friction law's constants from the rig).
IdentModel TruthModel(const DimensionalParams& p, const std::vector<TermValues>& extra);

// The main body's static equilibrium nearest `y_guess` [m] of the rig plus the extras (the restoring force at
// rest, k_lin y + k3 y³ + the extras' force at v = 0, is zero there): a well of the truth, where a record can
// start at rest without a transient. Newton's method from y_guess; y_guess itself when it does not converge.
double SyntheticWell(const DimensionalParams& p, const std::vector<TermValues>& extra, double y_guess);

// Columns as ColumnMap's defaults: t, x0 (the table motion, with input_noise_m of noise), x, and xr when
// the model has a resonator. The truth is the rig (DimensionalModel) plus o.extra's forces, integrated as one
// system by Rosenbrock 2(3) (the extras' slopes join its Jacobian). Records of a failed integration come back as an
// error.
StatusOr<Record> MakeSyntheticRecord(const DimensionalParams& p, const SyntheticOptions& o, const std::string& name);

// Writes a record as CSV (t,x0,x[,xr]) with 10 significant digits.
Status WriteRecordCsv(const Record& r, const std::string& path);

namespace identify {

// What `identify --make-synthetic DIR` writes (issue 40: typed, as the CLI's flags and the Python module's
// keywords give it; the records and truth.json are written by client/identify_command.cc's SyntheticJson).
//   kLinear           the paper's Table 2 linear rig (no resonator) under 1 -> 8 Hz chirps of 6, 10, 14 mm, 20 s;
//   kCoupled          the Table 2 bistable beam with its resonator, one 1 -> 6 Hz chirp of 4 mm over 70 s;
//   kBistable, kBistableCoupled  the snap-through family (issue 37): the beam alone or with its resonator,
//                     one record per amplitude, the knobs below, and truth.json.
enum class SyntheticKind { kLinear, kCoupled, kBistable, kBistableCoupled };
// linear | coupled | bistable | bistable-coupled (field synthetic).
StatusOr<SyntheticKind> ParseSyntheticKind(const std::string& s);
const char* Name(SyntheticKind k);
bool IsFamily(SyntheticKind k);  // kBistable or kBistableCoupled
// The well a family's records start in (--synthetic-start).
enum class WellSide { kLeft, kRight };
// left | right (field synthetic-start).
StatusOr<WellSide> ParseWellSide(const std::string& s);
const char* Name(WellSide w);

struct MakeSyntheticOptions {
  std::string dir;                              // --make-synthetic: the directory written (created); required
  SyntheticKind kind = SyntheticKind::kLinear;  // --synthetic
  // The family's knobs (kBistable, kBistableCoupled). `amplitudes_mm` and `extra` are refused with the other
  // kinds, the rest ignored there.
  std::vector<double> amplitudes_mm;  // --synthetic-amplitude: one record each, [0.01, 100] mm, at most 16; none: 10
  double f_start_hz = 1;              // --synthetic-f-start, [0.01, 50] Hz
  double f_end_hz = 8;                // --synthetic-f-end, [0.01, 50] Hz
  double duration_s = 30;             // --synthetic-duration, [1, 600] s
  double noise_mm = 0.05;             // --synthetic-noise on every column, the input too, [0, 10] mm
  unsigned seed = 1;                  // --synthetic-seed: the first record's noise seed (the next +1, +2, ...)
  std::vector<TermValues> extra;      // --synthetic-extra: force terms added to the truth (resonator terms:
                                      // kBistableCoupled only)
  WellSide start = WellSide::kRight;  // --synthetic-start
};

// OK, or the first option out of its bounds (field: its flag name, synthetic-amplitude; message: the bound).
Status Validate(const MakeSyntheticOptions& options);

}  // namespace identify

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_SYNTHETIC_H_
