// Synthetic measured records made by the project's own simulator (dynamics/dimensional_model.h,
// Rosenbrock 2(3) at tight tolerance — a different integrator and formulation from the one the
// identification simulates with): the paper's rig under a chirp of the table, sampled like the
// paper's camera, with Gaussian measurement noise on the measured positions.
#ifndef BISTABLE_IDENTIFY_SYNTHETIC_H_
#define BISTABLE_IDENTIFY_SYNTHETIC_H_

#include <string>

#include "dynamics/dimensional_model.h"
#include "identify/record.h"

namespace bistable {

struct SyntheticOptions {
  double a0_m = 0.002;            // chirp amplitude of the table [m]
  double f_start_hz = 1, f_end_hz = 8, duration_s = 20;
  double fs_hz = 120;             // sampling rate (the paper's camera)
  double noise_m = 0.05e-3;       // standard deviation of the noise on x and x_r [m]
  unsigned seed = 1;
  double y0_m = 0;                // initial relative displacement (a well, for bistable beams)
};

// Columns as ColumnMap's defaults: t, x0 (noise-free table motion, as commanded), x, and xr when
// the model has a resonator. Records of a failed integration come back as an error.
StatusOr<Record> MakeSyntheticRecord(const DimensionalParams& p, const SyntheticOptions& o, const std::string& name);

// Writes a record as CSV (t,x0,x[,xr]) with 10 significant digits.
Status WriteRecordCsv(const Record& r, const std::string& path);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_SYNTHETIC_H_
