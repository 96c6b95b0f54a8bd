// Where `bistable map | query` read a published map from: a local data directory (HDF5 directly) or
// a coordinator (GetMap / ListMetrics over gRPC). Slicing, plotting and queries then run locally,
// the same code for both.
#ifndef BISTABLE_CLIENT_MAP_SOURCE_H_
#define BISTABLE_CLIENT_MAP_SOURCE_H_

#include <string>
#include <vector>

#include "proto/channel.h"
#include "storage/map_file.h"

namespace bistable {

struct MapSource {
  std::string data_dir;      // used when coordinator is empty
  std::string coordinator;   // address; non-empty selects the remote source
  std::string token_file, tls_ca;

  // Resolves a sweep id or prefix; sets *id and *name.
  StatusOr<std::vector<std::string>> Metrics(const std::string& id_or_prefix, std::string* id, std::string* name) const;
  StatusOr<MapArray> Metric(const std::string& id, const std::string& metric) const;
};

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MAP_SOURCE_H_
