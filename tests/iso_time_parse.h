// Reading back the times the JSON outputs print (ISO 8601 UTC, "2026-11-22T21:04:05.123Z"), strictly:
// a test that parses a time this way checks the form, not only that a string is there.
#ifndef BISTABLE_TESTS_ISO_TIME_PARSE_H_
#define BISTABLE_TESTS_ISO_TIME_PARSE_H_

#include <cmath>
#include <cstdio>
#include <ctime>
#include <string>

namespace bistable_test {

// Unix seconds of "YYYY-MM-DDTHH:MM:SS.mmmZ"; NaN unless `s` is exactly that form with valid fields.
inline double ParseIsoTimeUtc(const std::string& s) {
  int y, mo, d, h, mi, sec, ms, n = 0;
  if (s.size() != 24 ||
      std::sscanf(s.c_str(), "%4d-%2d-%2dT%2d:%2d:%2d.%3dZ%n", &y, &mo, &d, &h, &mi, &sec, &ms, &n) != 7 || n != 24)
    return NAN;
  if (s[4] != '-' || s[7] != '-' || s[10] != 'T' || s[13] != ':' || s[16] != ':' || s[19] != '.') return NAN;
  if (mo < 1 || mo > 12 || d < 1 || d > 31 || h > 23 || mi > 59 || sec > 60) return NAN;
  std::tm tm{};
  tm.tm_year = y - 1900, tm.tm_mon = mo - 1, tm.tm_mday = d, tm.tm_hour = h, tm.tm_min = mi, tm.tm_sec = sec;
  return static_cast<double>(::timegm(&tm)) + ms / 1000.0;
}

}  // namespace bistable_test

#endif  // BISTABLE_TESTS_ISO_TIME_PARSE_H_
