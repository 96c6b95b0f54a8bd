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

#include "dynamics/status.h"
#include "engine/sweep_spec.h"

namespace bistable {

// A name for an error message: control bytes and DEL as \xNN, at most 80 bytes.
inline std::string PrintableName(const std::string& s) {
  std::string out;
  for (size_t i = 0; i < s.size() && i < 80; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7f || c == '\\') {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", c);
      out += b;
    } else {
      out += static_cast<char>(c);
    }
  }
  if (s.size() > 80) out += "...";
  return out;
}

// OK when `metric` is one of `stored`; else InvalidArgument naming field "metric", the nearest stored
// name and the allowed ones (`extra` lists pseudo-metrics the caller also accepts, e.g. hd_scatter).
inline Status CheckMetricName(const std::string& metric, const std::vector<std::string>& stored,
                              const std::vector<std::string>& extra = {}) {
  if (std::find(stored.begin(), stored.end(), metric) != stored.end()) return Status::Ok();
  std::vector<std::string> allowed = stored;
  allowed.insert(allowed.end(), extra.begin(), extra.end());
  std::string list;
  for (const auto& n : allowed) list += (list.empty() ? "" : ", ") + n;
  const bool plain = !metric.empty() && metric != "." && metric != ".." &&
                     metric.find_first_of(std::string("/\0\n\r", 4)) == std::string::npos;
  const std::string near = plain ? NearestName(metric, allowed) : "";
  return Status::InvalidArgument("metric", "metric '" + PrintableName(metric) + "' is not " +
                                               (plain ? "in this map" : "a metric name") +
                                               (near.empty() ? "" : "; did you mean '" + near + "'?") +
                                               " (allowed: " + list + ")");
}

}  // namespace bistable

#endif  // BISTABLE_STORAGE_METRIC_NAME_H_
