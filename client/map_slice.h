// Slicing a stored map: fix some dimensions (--at alpha=1,eta=0.1,ic=0), keep one or two free axes.
#ifndef BISTABLE_CLIENT_MAP_SLICE_H_
#define BISTABLE_CLIENT_MAP_SLICE_H_

#include <map>
#include <string>
#include <vector>

#include "storage/map_file.h"

namespace bistable {

struct Slice {
  std::string metric, unit;
  std::vector<Axis> free;                 // in axis order
  std::map<std::string, double> fixed;    // dimension name → value (ic as an index)
  std::vector<double> values;             // row-major over `free`
};

// Parses "alpha=1,eta=0.1".
StatusOr<std::map<std::string, double>> ParseAt(const std::string& text);

// Fixes the named dimensions (values must be on the axis, to 1e-9 relative), dimensions of length 1
// and the ic dimension (default ic = 0); what is left are the free axes (at most max_free).
StatusOr<Slice> SliceMap(const MapArray& m, const std::map<std::string, double>& at, int max_free);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MAP_SLICE_H_
