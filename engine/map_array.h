// A metric of a map read back: its values over the sweep's axes with the names, units and categories a
// reader needs. Made by storage/ (ReadMapMetric, from a map file) and by proto/ (from a MapReply), read by
// the client (slices, plots, JSON) and the dashboard — a plain value type, so the wire edge need not
// depend on the storage it does not use.
#ifndef BISTABLE_ENGINE_MAP_ARRAY_H_
#define BISTABLE_ENGINE_MAP_ARRAY_H_

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "engine/sweep_spec.h"

namespace bistable {

// Values in row-major order over dims.
struct MapArray {
  std::string metric;
  std::vector<Axis> axes;    // the sweep axes (dims 0..axes-1)
  std::vector<size_t> dims;  // full shape, including ic / peak dims
  std::vector<std::string> dim_names;
  std::vector<double> values;  // integers widened to double
  std::string unit, definition;
  std::vector<std::pair<int, std::string>> categories;  // code datasets: flag_values and flag_meanings
};

}  // namespace bistable

#endif  // BISTABLE_ENGINE_MAP_ARRAY_H_
