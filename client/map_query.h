// What `bistable sweeps --json` and `bistable query --json` print, as functions the CLI and the Python
// module (python/) both call: one implementation of each shape.
#ifndef BISTABLE_CLIENT_MAP_QUERY_H_
#define BISTABLE_CLIENT_MAP_QUERY_H_

#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "base/status.h"
#include "client/map_source.h"
#include "storage/index_db.h"

namespace bistable {

// The points of a map where `expr` holds (engine/query.h), over the axes and every metric the map
// stores (not the spectral peaks): {"sweep", "query", "count", "total", "fraction", "area_fraction",
// "truncated", "points": [at most max_points of {axis values..., ["ic"], each metric the query reads}]};
// count is every match, truncated says that points holds fewer (max_points cut the list). Categories
// print by name (json_out.h). Errors: an unknown sweep, a bad query (position and nearest name).
StatusOr<nlohmann::json> QueryJson(const MapSource& src, const std::string& id, const std::string& expr,
                                   size_t max_points);

// The sweeps of a data directory: [{"id", "name", "model", "status", "items_total", "items_done",
// "file", "created", "finished", "seconds", "maps": [{"metric", "shape", "min", "max"}]}]; [] when the
// directory has no index (or does not exist yet); InvalidArgument("data") when the path is not a directory.
StatusOr<nlohmann::json> LocalSweepsJson(const std::string& data_dir);
// InvalidArgument("data") when `data_dir` exists and is not a directory (a missing one is a data directory
// without sweeps yet).
Status CheckDataDirOrAbsent(const std::string& data_dir);
nlohmann::json LocalSweepsJson(IndexDb& db, const std::vector<SweepRow>& rows, const std::string& data_dir);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MAP_QUERY_H_
