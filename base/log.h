// Structured event logs for the service processes (coordinator, worker): one line per event on
// stderr, as text ("2026-11-22T19:03:01.123Z info lease.expired sweep=ab12 job=7 worker=n1:402") or as
// JSON objects (--log-format json: {"ts":...,"level":"info","event":"lease.expired","sweep":"ab12",...}).
// spdlog writes the lines (thread-safe sink, levels, UTC timestamps); this header fixes the vocabulary:
// an event name and typed fields. Every string field is cleaned (control bytes escaped, bounded), so
// a hostile worker name cannot forge a log line. Tokens are never passed here.
#ifndef BISTABLE_BASE_LOG_H_
#define BISTABLE_BASE_LOG_H_

#include <initializer_list>
#include <string>
#include <string_view>
#include <variant>

#include "base/status.h"

namespace bistable::log {

enum class Level { kDebug, kInfo, kWarn, kError, kOff };
enum class Format { kText, kJson };

// Parses "debug|info|warn|error|off" and "text|json" (field names the flag in errors).
StatusOr<Level> ParseLevel(const std::string& s, const std::string& field = "log-level");
StatusOr<Format> ParseFormat(const std::string& s, const std::string& field = "log-format");

// Sets the process's logger: level and format, on stderr. Without a call: info, text.
void Configure(Level level, Format format);
bool Enabled(Level level);

struct Field {
  using Value = std::variant<std::string_view, long long, double, bool>;
  Field(std::string_view k, std::string_view v) : key(k), value(v) {}
  Field(std::string_view k, const std::string& v) : key(k), value(std::string_view(v)) {}
  Field(std::string_view k, const char* v) : key(k), value(std::string_view(v)) {}
  Field(std::string_view k, bool v) : key(k), value(v) {}
  Field(std::string_view k, int v) : key(k), value(static_cast<long long>(v)) {}
  Field(std::string_view k, long v) : key(k), value(static_cast<long long>(v)) {}
  Field(std::string_view k, long long v) : key(k), value(v) {}
  Field(std::string_view k, unsigned long v) : key(k), value(static_cast<long long>(v)) {}
  Field(std::string_view k, double v) : key(k), value(v) {}
  std::string_view key;
  Value value;
};

// One event: `event` is a fixed dotted name from the code ("sweep.published"), fields in order.
void Event(Level level, std::string_view event, std::initializer_list<Field> fields = {});

// The line Event writes, without timestamp and level (tests check the rendering).
std::string Render(Format format, std::string_view event, std::initializer_list<Field> fields);

}  // namespace bistable::log

#endif  // BISTABLE_BASE_LOG_H_
