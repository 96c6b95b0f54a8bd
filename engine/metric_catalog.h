// The metrics a sweep can store: name, unit, definition (written into every map file) and how to
// read each from a PointResult. One table, so the engine, the storage and the CLI agree.
#ifndef BISTABLE_ENGINE_METRIC_CATALOG_H_
#define BISTABLE_ENGINE_METRIC_CATALOG_H_

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "dynamics/point_spec.h"

namespace bistable {

inline constexpr int kHdPeaksStored = 10;        // spectral peaks kept per point (freq, amp)
inline constexpr int kTurningPointsStored = 64;  // last turning points of y_m in the window, when requested
// Poincaré section points stored per record: `[metrics] poincare_points` (0 = none), at most
// limits::kMaxPoincarePointsStored; each point is (y_m, y_m').

struct MetricInfo {
  const char* name;
  const char* unit;
  const char* definition;
  bool integer;  // motion codes, period, termination: stored as integers
  // Domain: every stored value lies in [lo, hi] (integers: whole numbers), or is NaN where nan_ok
  // (diverged points, absent peaks). The metric code never produces anything else (PointRecord::From
  // maps an out-of-domain float to NaN), so a value outside is a corrupt or forged result.
  double lo, hi;
  bool nan_ok;
  const char* long_name;  // the quantity in words, without units (map files' CF long_name)
};

const std::vector<MetricInfo>& MetricCatalog();
// The position of a scalar metric in MetricCatalog() (and so in a PointRecord); aborts on a name that
// is not in the catalog (a programming error: names come from this file).
size_t MetricIndex(const char* name);
const MetricInfo* FindMetric(const std::string& name);
std::vector<std::string> MetricNames();

// Fixed-layout record of one (point, IC) result: the scalar metrics in MetricCatalog() order, then
// kHdPeaksStored peak frequencies and amplitudes (NaN-filled), then — only when the sweep stores
// turning points — the last kTurningPointsStored of them (NaN-filled), then — only when it stores a
// Poincaré section of n = poincare_points points — the last n section values of y_m, then of y_m' (time
// order, NaN-filled). This is what the point cache stores; layouts never share a key (the
// turning-point flag and the section's count are part of it).
struct PointRecord {
  std::vector<double> v;
  static size_t Size(bool turning_points = false, int poincare_points = 0);
  static PointRecord From(const PointResult& r, bool turning_points = false, int poincare_points = 0);
  double TurningPoint(int k) const;
  // Section point k < poincare_points of a record of that layout: y_m (component 0) or y_m' (1).
  double Poincare(int k, int component, bool turning_points, int poincare_points) const;
  double Get(size_t metric_index) const { return v[metric_index]; }
  double Get(const char* metric) const { return v[MetricIndex(metric)]; }
  double PeakFreq(int k) const;
  double PeakAmp(int k) const;
};

// Hash of the record layout: metric names in order, stored peaks and turning points, numerics version.
// Workers send it with every report; the coordinator refuses records of another layout.
uint64_t CatalogHash();

// Checks a record of `width` values (the sweep's layout: PointRecord::Size(turning_points,
// poincare_points)) against every metric's domain; the message names the metric, the value and the
// bound. The coordinator runs this on every reported record before storing it.
Status CheckRecord(const double* v, size_t width, bool turning_points, int poincare_points = 0);
// The same for a record of any layout (the sweep not known yet): `width` within the smallest and the
// largest layout (CheckAnyRecordWidth), the optional tails (turning points, section values) checked by
// their common bound.
Status CheckAnyRecordWidth(size_t width);
Status CheckAnyRecord(const double* v, size_t width);

// Motion codes stored in maps.
inline constexpr int kMotionUndefined = -1;
int MotionCode(Motion m);
const char* MotionCodesText();  // "0 intrawell, 1 interwell, 2 chaotic, -1 undefined (diverged)"

// The named categories of a code metric ("motion": MotionName of each Motion, "termination":
// TerminationName of each Termination, as stored by PointRecord::From): code and one-word name. The
// one table behind JSON names, the query language's names, plot labels and the map files' CF
// flag_values/flag_meanings. Empty for any other metric.
struct Category {
  int code;
  const char* name;
};
const std::vector<Category>& MetricCategories(const std::string& metric);
// The code of a motion name (intrawell, interwell, chaotic, undefined); false when `name` is none.
bool MotionCodeOfName(const std::string& name, int* code);
// Whether the metric's values are category codes (motion, termination), which JSON prints by name.
bool IsCategoryMetric(const std::string& metric);
// The name of a stored category code; nullptr for any other metric, NaN, or a value that is not one
// of the metric's codes.
const char* CategoryName(const std::string& metric, double code);
// The colour ("#rrggbb") figures and the dashboard give a named code: grey for nothing found (undefined, none
// found), the paper's motion colours (blue intrawell, orange interwell, red chaotic), green for ok; "" for any other
// name (the presenter picks one by position).
const char* CategoryColour(const std::string& name);
// Whether the metric's sign is its meaning (frf_db: amplified or attenuated; lle: chaotic or not): figures and
// the dashboard colour it with a diverging palette on a range symmetric about 0 (blue below, white at 0, red above).
bool DivergesAboutZero(const std::string& metric);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_METRIC_CATALOG_H_
