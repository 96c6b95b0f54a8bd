// `bistable design`'s driver: the sweep runners (embedded in this process, or a coordinator) that
// run each candidate of a design search (design/) as an ordinary sweep, the maps of the best designs,
// the brute-force grid in the same run, and the report directory (report.json, candidates.csv, the
// Pareto front figure, figures of the best designs' maps).
#ifndef BISTABLE_CLIENT_DESIGN_RUN_H_
#define BISTABLE_CLIENT_DESIGN_RUN_H_

#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "base/status.h"
#include "design/design_search.h"

namespace bistable {

struct DesignRunOptions {
  std::string data = "bistable-data";           // embedded: the data directory (cache, maps); the report goes under it
  std::string out;                              // report directory ("" = <data>/designs/<design id>)
  std::string coordinator, token_file, tls_ca;  // coordinator non-empty: candidates run there
  bool insecure_remote = false;                 // the token may go in plaintext to an address that is not loopback
  int threads = 0;
  int brute_force = 0;  // N > 0: also an N per free parameter grid, timed in the same run
  bool progress = true, plots = true;
};

// Runs one sweep spec to completion and reads frf_db, motion and lle back (and, embedded, its map's path).
class DesignSweeps {
 public:
  virtual ~DesignSweeps() = default;
  virtual StatusOr<SweepOutcome> Run(const std::string& spec_toml) = 0;
  // A local copy of a published map (embedded: the map itself; remote: fetched into `dir`).
  virtual StatusOr<std::string> LocalMap(const SweepOutcome& o, const std::string& dir) = 0;
};
StatusOr<std::unique_ptr<DesignSweeps>> OpenEmbeddedSweeps(const std::string& data_dir, int threads);
StatusOr<std::unique_ptr<DesignSweeps>> OpenRemoteSweeps(const std::string& address, const std::string& token_file,
                                                         const std::string& tls_ca, bool insecure_remote = false);

// The whole `bistable design` run; returns the report (the --json document, also written to
// <out>/report.json). Cancellation: CancelledStatus() after the candidates already run are cached.
StatusOr<nlohmann::json> RunDesign(const DesignSpec& spec, const DesignRunOptions& o);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_DESIGN_RUN_H_
