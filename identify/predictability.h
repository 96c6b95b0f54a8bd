// Can a record's long simulation be meaningful? (issue 37: the objective chosen from the records.)
//
// On a record whose orbit snaps between wells chaotically, even the true model simulated from the measured
// start with the measured input misses the record by tens of percent: after the first crossings of the hump
// the orbit depends on the noise in the start state and in the recorded input. A fit of the whole simulation
// then fits the chaos, not the vector field, and the trace blames the model for it. Whether that is so is a
// property of the record under a model near the truth, measured by a twin experiment:
//
//   the model is simulated over the whole record from the measured start, and again (a) from starts moved
//   by the output's noise level (±σ in position; σ_v = σ 2π f_c / √3 in velocity, f_c the derivative cutoff)
//   and (b) with the recorded input's noise drawn again (σ_in, NoiseLevel of the input: the record was driven
//   by the true input, every simulation by the measured one). The largest twin difference, as an NRMSE of the
//   output (the fit's normalisation), is the chaos floor: what the simulation misses by noise alone. Its
//   first time above kDivergedShare of the output's RMS (running window 0.25 s) is the prediction horizon.
//   Perturbing only the start is not enough: dissipation forgets it during the chirp's calm start, long
//   before the orbit turns chaotic; the input's noise acts all along, as it does on the record.
//
// The long simulation is meaningful when the chaos floor stays below kMeaningfulFloor (percent); then the
// record is fitted on its whole simulation (the time objective). The floor is only as good as the model it
// runs, and chaos is fragile in parameters: on a coupled null record the declared model fitted on 0.1 s
// horizons was within noise of the truth on short horizons (0.28 % at 0.05 s; the main body's static
// friction 1.83 N against 1.2), yet not chaotic (floor 0.86 %) where the truth is (112 %). Its own long
// simulation gave it away: it missed the record by 110 %. So with `require_followed` (the decision with
// the short-horizon fit) the model must also follow the record over its whole length — its long simulation
// error below the same kMeaningfulFloor — for the long simulation to be fitted; a model that does not
// follow it is either far from the truth's basin of the long simulation error or understates its chaos,
// and multiple shooting is right for both. Otherwise by multiple shooting (fit.h,
// Objective::kShooting: segments from re-estimated states — the states are unknowns, so their noise does not
// bias θ as restarts from measured states do) on segments of fit_horizon_s: the longest (from 4 samples up to
// the fit's --horizon) over which the model restarted from the same states, driven by the input and by the
// input drawn again, stays within kShortDivergence % (what remains of chaos in a segment whose start is
// fitted is the input's noise). Well changes of the measured record (the main body's relative coordinate
// crossing between the model's wells, hysteresis half a well) are reported as evidence beside it.
//
// Twin records (TwinRecords) carry the same idea into the trace and the whiteness test: the fitted model
// recorded again as the record was — what its residual looks like when nothing is missing.
#ifndef BISTABLE_IDENTIFY_PREDICTABILITY_H_
#define BISTABLE_IDENTIFY_PREDICTABILITY_H_

#include <cmath>
#include <string>
#include <vector>

#include "identify/model.h"

namespace bistable {

inline constexpr double kMeaningfulFloor = 5.0;  // % chaos floor below which the long simulation is fitted
inline constexpr double kDivergedShare = 0.1;    // twins apart by this share of the output's RMS: diverged
inline constexpr double kShortDivergence = 1.0;  // % twin difference a short horizon may reach
inline constexpr int kTwins = 4;                 // twin records calibrating the trace and the whiteness test

struct Predictability {
  std::string record;
  double duration_s = 0;
  double chaos_floor = NAN;       // % NRMSE between the model's simulation and its twins (the largest)
  double horizon_s = NAN;         // first time the twins are kDivergedShare apart (the record's length if never)
  int well_changes = -1;          // of the measured record (−1: the model has no two wells)
  double long_error = NAN;        // % NRMSE of the model's own long simulation against the record (main output)
  bool followed = true;           // long_error < kMeaningfulFloor (asked for with require_followed only)
  bool long_meaningful = true;    // chaos_floor < kMeaningfulFloor, followed, and the simulations did not diverge
  double fit_horizon_s = 0;       // 0: the whole simulation is fitted; > 0: restarts every fit_horizon_s
  double short_divergence = NAN;  // % twin difference at fit_horizon_s (restarted twins a noise apart)
  double noise = NAN, input_noise = NAN;  // σ of the output and of the input used for the twins
  std::string reason;                     // one sentence for reports
};

// The twin experiment on one record with the model m at th; `max_horizon_s`: the short horizon used when the
// long simulation is not meaningful (the fit's --horizon). `require_followed`: the model must also follow the
// record (long_error < kMeaningfulFloor) for its long simulation to count as meaningful.
Predictability TestPredictability(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                                  const Setup& setup, double max_horizon_s, bool require_followed = false);

// The drive's frequency [Hz]: the input's power-weighted mean frequency (a sine's own; a chirp's band centre
// by its power). NaN for a constant input.
double DriveFrequency(const PreparedRecord& r);

// % NRMSE of the main output of one record simulated with restarts from the measured state every horizon_s
// (0: the whole simulation): the error over a stated horizon, comparable before and after a fit and between
// models. The restart states are the band-limited ones (BandLimitedRestarts) whatever the record's own.
double HorizonError(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r, const Setup& setup,
                    double horizon_s);

// Twin records of the fitted model (m, th): each record's output simulated over its whole length from its
// measured start, driven by its measured input, then recorded as the measurement was — white noise of the
// record's own output noise level (NoiseLevel) on every output and of its input noise level on the input —
// and prepared like it (same setup, derivative cutoff, weights, horizon). On them nothing is missing by
// construction: what a candidate explains of their residual is what it explains of noise, chaos and errors
// in the variables alone — the null distribution of the trace on records that snap between wells, where the
// short-horizon residual is far from white even for the true model. Empty when a record's output form cannot
// be recorded again (a velocity output in the relative frame, a force input) or the simulation diverges.
//
// The twins' output noise is the smaller of two upper bounds of the record's: NoiseLevel of the measured output
// (its band above the derivative cutoff holds the noise and whatever the response has there) and NoiseLevel of
// the model's residual on the record — over segments of `shooting_horizon_s` from fitted states for a record
// fitted on short horizons (> 0, chaotic or horizon_s > 0), else over its whole simulation. A chaotic output is
// broadband: its own level read 0.0557 and 0.0625 mm for 0.05 mm of noise, twins that noisy were whiter than the
// record (predictable share 0.26 and 0.19 against 0.37), and two null records were called `unexplained`.
//
// kResidualBlocks (the bootstrap's twins, identify/bootstrap.h): each output's error is instead the record's own
// residual against the model (the same simulation as above: whole, or over segments from fitted states),
// resampled in blocks of twice its correlation time — where the model lacks something, the twins carry that
// misfit as error, at its level and correlation, and not only the sensor's noise.
// `first`: the index of the first twin made (twin k's noise depends on k alone: twins first … first + twins − 1 are
// those of a call that made them all).
enum class TwinNoise { kNoiseLevel, kResidualBlocks };
std::vector<std::vector<PreparedRecord>> TwinRecords(const IdentModel& m, const std::vector<double>& th,
                                                     const std::vector<PreparedRecord>& recs, const Setup& setup,
                                                     int twins, double shooting_horizon_s = 0,
                                                     TwinNoise kind = TwinNoise::kNoiseLevel, int first = 0);

// Changes of well of a relative displacement series y between wells at ±well (hysteresis: a change counts
// when y passes the other well's half depth, ∓well/2).
int CountWellChanges(const std::vector<double>& y, double well);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_PREDICTABILITY_H_
