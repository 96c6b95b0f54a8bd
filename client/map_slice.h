// Slicing a stored map: fix some dimensions (--at alpha=1,eta=0.1,ic=0), keep one or two free axes.
#ifndef BISTABLE_CLIENT_MAP_SLICE_H_
#define BISTABLE_CLIENT_MAP_SLICE_H_

#include <cmath>
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

// `bistable map --at`: each value of an axis moved to the axis's nearest grid value, with a note for each value moved
// ("--at alpha=1 → nearest grid value 1.00005"). Refused (InvalidArgument "at", naming the axis's range) when
// the value lies outside the axis's range by more than half the grid step at that end. Names that are not
// axes are left to SliceMap.
StatusOr<std::vector<std::string>> SnapAtToGrid(const MapArray& m, std::map<std::string, double>* at);

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

// What a map figure says beyond the map's values (docs/figures.md): the sweep's fixed parameters
// (subtitle), its chaos threshold (the LLE map's threshold contour), and its name and id (footer).
struct MapContext {
  std::string name, id;
  std::vector<FixedParameter> fixed;
  double chaos_threshold = NAN;
  std::string items = "starts";  // what a point's items are, in the fractions' titles ("tolerance samples", ...)
};
MapContext MapContextOf(const SweepSpec& spec);
// The context of a map file: its stored spec (the root attribute "spec"); the name and id alone when
// the file has none or it does not parse.
MapContext MapContextOfFile(const std::string& map_path);

// The title of a metric's figure: its long name in words with its symbol ("Largest Lyapunov exponent"),
// enhanced text; and its colour-bar / value-axis label with the symbol and the unit in symbols
// ("FRF [dB]", "EDR_T = (W_m + W_r)/W_{in} [%]"), "" for codes that need none.
std::string MetricTitle(const std::string& metric);
std::string MetricValueLabel(const std::string& metric, const std::string& unit);

// A basin map's attractor label (flag_meanings, "A1_P1_+well_y0.418_v-0.163") in words: "period-1, +well";
// "chaotic, interwell". Labels of another form come back with spaces for underscores.
std::string AttractorName(const std::string& label);

// A basin map's attractors (the "attractor" dataset, all starts) with their names in words
// (AttractorName) and their share of the starts, largest first; -1 (diverged) when present.
struct BasinShare {
  int id;
  std::string name;
  double fraction;
};
std::vector<BasinShare> BasinShares(const MapArray& attractor);

// A figure of a slice of `m` (SliceMap with `at`): axes with units, codes for integer metrics, and,
// for a curve of a continuation map whose `direction` dimension `at` leaves free, the up and down
// sweeps as two series. Title: the metric's long name (MetricTitle); subtitle: the context's fixed
// parameters and the slice's fixed dimensions that have a choice (numbers to 4 significant digits,
// directions by name); footer: the sweep's name and id. FRF maps get the 0 dB contour, LLE maps the
// chaos threshold's, EDR maps a colour range clipped at 100 %, basin maps their attractors in words
// with basin fractions.
StatusOr<PlotData> MapFigure(const MapArray& m, std::map<std::string, double> at, const MapContext& ctx = {});

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MAP_SLICE_H_
