// Times for people and scripts: a Unix time as ISO 8601 in UTC, the one format every JSON output
// (and the log lines, through spdlog's pattern) uses: 2026-11-22T21:04:05.123Z.
#ifndef BISTABLE_BASE_ISO_TIME_H_
#define BISTABLE_BASE_ISO_TIME_H_

#include <string>

namespace bistable {

// `unix_seconds` as "YYYY-MM-DDTHH:MM:SS.mmmZ" (UTC, to the nearest millisecond; the carry
// of 59.9996 s is a whole new minute); "" when it is not finite or outside years 1970..9999.
std::string IsoTimeUtc(double unix_seconds);

}  // namespace bistable

#endif  // BISTABLE_BASE_ISO_TIME_H_
