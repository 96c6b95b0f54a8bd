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
// record is fitted on its whole simulation (the time objective). Otherwise by multiple shooting (fit.h,
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
  double chaos_floor = NAN;        // % NRMSE between the model's simulation and its twins (the largest)
  double horizon_s = NAN;          // first time the twins are kDivergedShare apart (the record's length if never)
  int well_changes = -1;           // of the measured record (−1: the model has no two wells)
  bool long_meaningful = true;     // chaos_floor < kMeaningfulFloor (and the simulations did not diverge)
  double fit_horizon_s = 0;        // 0: the whole simulation is fitted; > 0: restarts every fit_horizon_s
  double short_divergence = NAN;   // % twin difference at fit_horizon_s (restarted twins a noise apart)
  double noise = NAN, input_noise = NAN;  // σ of the output and of the input used for the twins
  std::string reason;              // one sentence for reports
};

// The twin experiment on one record with the model m at th; `max_horizon_s`: the short horizon used when the
// long simulation is not meaningful (the fit's --horizon), shortened to a third of the prediction horizon.
Predictability TestPredictability(const IdentModel& m, const std::vector<double>& th, const PreparedRecord& r,
                                  const Setup& setup, double max_horizon_s);

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
std::vector<std::vector<PreparedRecord>> TwinRecords(const IdentModel& m, const std::vector<double>& th,
                                                     const std::vector<PreparedRecord>& recs, const Setup& setup, int twins);

// Changes of well of a relative displacement series y between wells at ±well (hysteresis: a change counts
// when y passes the other well's half depth, ∓well/2).
int CountWellChanges(const std::vector<double>& y, double well);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_PREDICTABILITY_H_
