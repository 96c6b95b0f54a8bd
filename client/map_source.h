// Where `bistable map | query` read a published map from: a local data directory (HDF5 directly) or
// a coordinator (GetMap / ListMetrics over gRPC). Slicing, plotting and queries then run locally,
// the same code for both.
#ifndef BISTABLE_CLIENT_MAP_SOURCE_H_
#define BISTABLE_CLIENT_MAP_SOURCE_H_

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "proto/channel.h"
#include "proto/coordinator_client.h"
#include "storage/map_file.h"

namespace bistable {

struct MapSource {
  std::string data_dir;     // used when coordinator is empty
  std::string coordinator;  // address; non-empty selects the remote source
  std::string token_file, tls_ca;
  bool insecure_remote = false;  // the token may go in plaintext to an address that is not loopback

  // Resolves a sweep id or prefix; sets *id and *name.
  StatusOr<std::vector<std::string>> Metrics(const std::string& id_or_prefix, std::string* id, std::string* name) const;
  StatusOr<MapArray> Metric(const std::string& id, const std::string& metric) const;
};

// `out` for a fetched map: a file name, not "-" (standard output would get the bytes before their
// SHA-256 is checked; the file is renamed into place only after). InvalidArgument naming "out".
Status CheckFetchOut(const std::string& out);

// Streams a published map file from a coordinator into `out` (AtomicFile: temporary, fsync, rename; the
// stream's SHA-256 checked by CoordinatorClient::FetchMap). Stops with an error when cancellation is
// requested (dynamics/cancel.h); nothing is left at `out` then. Returns {"id", "file", "bytes", "sha256"}.
StatusOr<nlohmann::json> FetchMapFile(CoordinatorClient& c, const std::string& id, const std::string& out);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_MAP_SOURCE_H_
