// Pieces every subcommand shares: the error line, the default data directory, finding a sweep's map.
#ifndef BISTABLE_CLIENT_CLI_COMMON_H_
#define BISTABLE_CLIENT_CLI_COMMON_H_

#include <map>
#include <string>

#include "base/exit_codes.h"
#include "base/status.h"
#include "storage/index_db.h"

namespace bistable {

inline constexpr const char* kDefaultDataDir = "bistable-data";

// "a=1,b=2" → {a: "1", b: "2"} (empty items skipped); an item without a name or '=' is an error
// naming `field` and the item.
StatusOr<std::map<std::string, std::string>> ParseNameValues(const std::string& text, const std::string& field);
// A finite number, or an error naming `field` and the text.
StatusOr<double> ParseFiniteNumber(const std::string& text, const std::string& field);

// Prints "error: <status>" to stderr and returns kExitError (2).
int Fail(const Status& st);

// Text to standard output when `path` is "-" (or empty), else into the file, atomically (a temporary
// beside it, renamed when complete; its directory must exist). Errors name `field`.
Status WriteTextOut(const std::string& path, const std::string& text, const std::string& field);
// `path` given to `flag` (error field `field`) may not be "-": standard output is not an option there, for
// the reason `why`; a file named "-" is ./- (never created by accident).
Status NotStdout(const std::string& path, const std::string& field, const std::string& flag, const std::string& why);

// Opens <data>/index.sqlite (which must exist) and finds the sweep by id or unique prefix.
struct SweepRef {
  SweepRow row;
  std::string map_path;  // absolute path of the published map ("" when not published)
};
StatusOr<SweepRef> FindSweep(const std::string& data_dir, const std::string& id);

}  // namespace bistable

#endif  // BISTABLE_CLIENT_CLI_COMMON_H_
