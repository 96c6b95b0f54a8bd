// Measured time histories for identification (issue 5): CSV with a header, a time column [s], one
// input and one or two outputs, mapped to SI by kind and scale. Several records in one file are
// split where the time restarts (e.g. the harvester's steady-sine file) or where group columns change.
// Every value is checked: a bad cell names its row and column; a missing column suggests the nearest.
#ifndef BISTABLE_IDENTIFY_RECORD_H_
#define BISTABLE_IDENTIFY_RECORD_H_

#include <string>
#include <vector>

#include "base/status.h"

namespace bistable {

enum class InputKind {
  kBaseDisplacement,  // x0 [m]
  kBaseAcceleration,  // a0 [m/s²]
  kForce,             // u [N] (or a force analogue, e.g. the Silverbox voltage)
};
enum class OutputKind {
  kDisplacement,  // x [m], absolute displacement of the main mass
  kVelocity,      // x' [m/s]
  kAnalogue,      // a measured analogue of displacement (e.g. a voltage), unscaled
};

struct ColumnMap {
  std::string time = "t";
  std::string input = "x0";
  InputKind input_kind = InputKind::kBaseDisplacement;
  double input_scale = 1.0;     // multiply to get SI (e.g. 9.81 for acceleration in g)
  std::string output = "x";
  OutputKind output_kind = OutputKind::kDisplacement;
  double output_scale = 1.0;    // e.g. 0.1 for the harvester's laser volts → m/s
  std::string resonator;        // optional column: resonator absolute displacement xr [m]
  std::vector<std::string> group;  // optional columns whose change starts a new record
};

struct Record {
  std::string name;             // file name, with "#k" for the k-th record of a file
  double dt = 0;                // sampling interval [s] (uniform)
  std::vector<double> t, input, output, resonator;  // SI after scaling; resonator may be empty
  std::vector<double> group_values;                 // values of the group columns for this record
};

// Loads every record of a CSV file. Errors: unreadable file, missing columns (nearest suggested),
// non-numeric or non-finite cells (row and column), time not increasing, non-uniform sampling.
StatusOr<std::vector<Record>> LoadRecords(const std::string& path, const ColumnMap& columns);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_RECORD_H_
