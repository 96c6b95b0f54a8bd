// Measured time histories for identification (issue 5): CSV with a header, a time column, one input
// and one to three outputs (main body, resonator, piezo voltage), mapped to SI by kind, header unit and scale. Several
// records in one file are split where the time restarts (e.g. the harvester's steady-sine file) or where group columns
// change. Every value is checked: a bad cell names its row and column; a missing column suggests the nearest.
//
// What DAQ exports write is read (docs/identification.md, "Data files"): a UTF-8 BOM, CRLF line ends,
// blank lines and '#' comment lines anywhere; the separator , tab or ; (the one that splits the header
// most often); double-quoted cells ("" is a quote); in tab and ; files a decimal comma (0,25); a
// leading '+'; a unit suffix on header names ("t [ms]", "x0 (mm)"), converted to SI for the time,
// input, output and resonator columns when it is a unit of their quantity. A line is at most
// limits::kMaxDataLineBytes, a file at most limits::kMaxDataRows data rows.
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
  double input_scale = 1.0;  // multiply to get SI (e.g. 9.81 for acceleration in g); not with a header unit
  std::string output = "x";
  OutputKind output_kind = OutputKind::kDisplacement;
  double output_scale = 1.0;  // e.g. 0.1 for the harvester's laser volts → m/s
  std::string resonator;      // optional column: resonator absolute displacement xr [m]
  std::string voltage;  // optional column: a piezo voltage [V] (a second output, compared with main.piezo's state)
  double voltage_scale = 1.0;      // multiply to get volts (e.g. an amplifier's gain); not with a header unit
  std::vector<std::string> group;  // optional columns whose change starts a new record
};

struct Record {
  std::string name;                                 // file name, with "#k" for the k-th record of a file
  double dt = 0;                                    // sampling interval [s] (uniform)
  std::vector<double> t, input, output, resonator;  // SI after scaling; resonator may be empty
  std::vector<double> voltage;                      // V, or empty
  std::vector<double> group_values;                 // values of the group columns for this record
};

// Loads every record of a CSV file. Errors ("row N" is the file's line N): unreadable file, missing
// or ambiguous columns (nearest suggested), a unit of the wrong quantity (or a known unit and a scale:
// two conversions), non-numeric or non-finite cells (row and column), an unclosed quote, a line or
// row count over its bound, time not increasing, non-uniform sampling.
StatusOr<std::vector<Record>> LoadRecords(const std::string& path, const ColumnMap& columns);

}  // namespace bistable

#endif  // BISTABLE_IDENTIFY_RECORD_H_
