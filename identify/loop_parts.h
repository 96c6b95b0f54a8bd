// Internal to identify/loop.cc and identify/objective_choice.cc: what both steps of the loop use. Not part of
// identify's interface (loop.h, identify.h).
#ifndef BISTABLE_IDENTIFY_LOOP_PARTS_H_
#define BISTABLE_IDENTIFY_LOOP_PARTS_H_

#include <vector>

#include "identify/model.h"
#include "identify/record.h"

namespace bistable {

// Parameter scales for the fits: the value, 3σ, or — for a parameter at zero (clipped to its bound, or not yet
// estimated) — 5 % of the value whose force equals the RMS inertial force along the records.
std::vector<double> ScaleOf(const IdentModel& m, const std::vector<double>& th, const std::vector<double>& sigma,
                            const std::vector<PreparedRecord>& recs, const Setup& setup);
// Physically signed as fitted: a piezo coupling takes energy from the beam (a c > 0).
bool Physical(const IdentModel& m, const std::vector<double>& th);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_LOOP_PARTS_H_
