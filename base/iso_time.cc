#include "base/iso_time.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>

namespace bistable {

std::string IsoTimeUtc(double unix_seconds) {
  constexpr double kYear10000 = 253402300800.0;  // 10000-01-01T00:00:00Z
  if (!std::isfinite(unix_seconds) || unix_seconds < 0 || unix_seconds * 1000.0 >= kYear10000 * 1000.0 - 0.5) return "";
  const auto ms = std::llround(unix_seconds * 1000.0);
  const std::time_t secs = static_cast<std::time_t>(ms / 1000);
  std::tm tm{};
  if (!::gmtime_r(&secs, &tm)) return "";
  char b[96];  // room for any int in each field (7 × 11 characters): the year is < 10000, which GCC cannot see
  std::snprintf(b, sizeof b, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms % 1000));
  return b;
}

}  // namespace bistable
