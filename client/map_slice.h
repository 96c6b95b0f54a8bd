// Slicing a stored map: fix some dimensions (--at alpha=1,eta=0.1,ic=0), keep one or two free axes.
#ifndef BISTABLE_CLIENT_MAP_SLICE_H_
#define BISTABLE_CLIENT_MAP_SLICE_H_

#include <map>
#include <string>
#include <vector>

#include "client/plot.h"
#include "storage/map_file.h"

namespace bistable {

struct Slice {
  std::string metric, unit;
  std::vector<Axis> free;               // in axis order
  std::map<std::string, double> fixed;  // dimension name → value (ic as an index)
  std::vector<double> values;           // row-major over `free`
};

// Parses "alpha=1,eta=0.1".
StatusOr<std::map<std::string, double>> ParseAt(const std::string& text);

// Fixes the named dimensions (values must be on the axis, to 1e-9 relative), dimensions of length 1
// and the ic dimension (default ic = 0); what is left are the free axes (at most max_free).
StatusOr<Slice> SliceMap(const MapArray& m, const std::map<std::string, double>& at, int max_free);

// The discrete legend of an integer metric (engine/metric_catalog.h's FindMetric(metric)->integer):
// its named codes (MetricCategories, and period's 0 "none found"; motion's three kinds always, so colours mean the same
// in every figure) and every other whole value present, by number. Empty (a continuous scale) for other metrics, or
// when more than 16 distinct values are present. Named codes of a code metric (colours and legend); file_categories
// name the codes of a dataset the catalog does not know (a basin map's attractor ids, from its flag_meanings).
std::vector<PlotData::Code> MetricCodes(const std::string& metric, const std::vector<double>& values,
                                        const std::vector<std::pair<int, std::string>>& file_categories = {});

// A figure of a slice of `m` (SliceMap with `at`): axes with units, codes for integer metrics, and,
// for a curve of a continuation map whose `direction` dimension `at` leaves free, the up and down
// sweeps as two series. Title: "<prefix>: <metric>" and the fixed dimensions that have a choice
// (numbers to 4 significant digits, directions by name).
StatusOr<PlotData> MapFigure(const MapArray& m, std::map<std::string, double> at, const std::string& title_prefix);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MAP_SLICE_H_
