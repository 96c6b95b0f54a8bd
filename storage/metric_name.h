// Checking a metric name that came from a user or a remote client before it touches a map file: it
// must be one of the metrics the map stores (a plain dataset name, never an HDF5 path such as "/",
// "..", "/axes/alpha" or an axis scale). Header-only: used by storage (ReadMapMetric, which the
// coordinator calls with a remote client's string) and by the client before it asks for a map.
#ifndef BISTABLE_STORAGE_METRIC_NAME_H_
#define BISTABLE_STORAGE_METRIC_NAME_H_

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "base/limits.h"
#include "base/names.h"
#include "base/status.h"

namespace bistable {

// A plain dataset name: not empty, at most limits::kMaxMetricNameBytes, not "." or "..", no '/', NUL,
// CR or LF — never something HDF5 could read as a path.
inline bool IsPlainMetricName(const std::string& metric) {
  return !metric.empty() && metric.size() <= limits::kMaxMetricNameBytes && metric != "." && metric != ".." &&
         metric.find_first_of(std::string("/\0\n\r", 4)) == std::string::npos;
}

// OK when `metric` is one of `stored`; else InvalidArgument naming field "metric", the nearest stored
// name and the allowed ones (`extra` lists pseudo-metrics the caller also accepts, e.g. hd_scatter).
inline Status CheckMetricName(const std::string& metric, const std::vector<std::string>& stored,
                              const std::vector<std::string>& extra = {}) {
  if (std::find(stored.begin(), stored.end(), metric) != stored.end()) return Status::Ok();
  std::vector<std::string> allowed = stored;
  allowed.insert(allowed.end(), extra.begin(), extra.end());
  if (IsPlainMetricName(metric))
    return Status::InvalidArgument("metric", UnknownNameMessage("metric", metric, allowed));
  std::string list;
  for (const auto& n : allowed) list += (list.empty() ? "" : ", ") + n;
  return Status::InvalidArgument("metric",
                                 "metric '" + Printable(metric) + "' is not a metric name (allowed: " + list + ")");
}

}  // namespace bistable

#endif  // BISTABLE_STORAGE_METRIC_NAME_H_
