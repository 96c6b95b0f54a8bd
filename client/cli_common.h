// Pieces every subcommand shares: the error line, the default data directory, finding a sweep's map.
#ifndef BISTABLE_CLIENT_CLI_COMMON_H_
#define BISTABLE_CLIENT_CLI_COMMON_H_

#include <string>

#include "dynamics/status.h"
#include "storage/index_db.h"

namespace bistable {

inline constexpr const char* kDefaultDataDir = "bistable-data";
inline constexpr int kExitBadInput = 2;
inline constexpr int kExitInterrupted = 130;

// Prints "error: <status>" to stderr and returns kExitBadInput.
int Fail(const Status& st);

// Opens <data>/index.sqlite (which must exist) and finds the sweep by id or unique prefix.
struct SweepRef {
  SweepRow row;
  std::string map_path;  // absolute path of the published map ("" when not published)
};
StatusOr<SweepRef> FindSweep(const std::string& data_dir, const std::string& id);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_CLI_COMMON_H_
