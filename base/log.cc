#include "base/log.h"

#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>

#include <spdlog/sinks/stdout_sinks.h>
#include <spdlog/spdlog.h>

namespace bistable::log {
namespace {

constexpr size_t kMaxFieldBytes = 512;  // a longer value is cut (names, reasons, addresses)

struct State {
  std::mutex mu;
  Format format = Format::kText;
  std::shared_ptr<spdlog::logger> logger;
};

State& S() {
  static State* s = [] {
    auto* st = new State;
    st->logger = std::make_shared<spdlog::logger>("bistable", std::make_shared<spdlog::sinks::stderr_sink_mt>());
    st->logger->set_pattern("%Y-%m-%dT%H:%M:%S.%eZ %l %v", spdlog::pattern_time_type::utc);
    st->logger->set_level(spdlog::level::info);
    st->logger->flush_on(spdlog::level::trace);  // every line reaches the collector at once
    return st;
  }();
  return *s;
}

spdlog::level::level_enum ToSpd(Level l) {
  switch (l) {
    case Level::kDebug:
      return spdlog::level::debug;
    case Level::kInfo:
      return spdlog::level::info;
    case Level::kWarn:
      return spdlog::level::warn;
    case Level::kError:
      return spdlog::level::err;
    case Level::kOff:
      return spdlog::level::off;
  }
  return spdlog::level::info;
}

// `v` quoted, with \" and \\ escaped and other bytes outside printable ASCII as \xNN (text) or \u00NN
// (JSON: valid even for invalid UTF-8), cut at kMaxFieldBytes.
void AppendQuoted(std::string& out, std::string_view v, bool json) {
  out += '"';
  size_t n = 0;
  for (unsigned char c : v) {
    if (++n > kMaxFieldBytes) {
      out += "...";
      break;
    }
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20 || c >= 0x7f) {
      char b[8];
      std::snprintf(b, sizeof b, json ? "\\u%04x" : "\\x%02x", c);
      out += b;
    } else {
      out += static_cast<char>(c);
    }
  }
  out += '"';
}

// Text: bare when the value is a plain token, else quoted.
void AppendText(std::string& out, std::string_view v) {
  bool plain = !v.empty() && v.size() <= kMaxFieldBytes;
  for (unsigned char c : v)
    if (c <= 0x20 || c >= 0x7f || c == '"' || c == '\\' || c == '=') plain = false;
  if (plain)
    out += v;
  else
    AppendQuoted(out, v, false);
}

void AppendJson(std::string& out, std::string_view v) { AppendQuoted(out, v, true); }

void AppendNumber(std::string& out, double v, bool json) {
  if (!std::isfinite(v)) {
    out += json ? "null" : (std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf"));
    return;
  }
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  out += b;
}

}  // namespace

StatusOr<Level> ParseLevel(const std::string& s, const std::string& field) {
  if (s == "debug") return Level::kDebug;
  if (s == "info") return Level::kInfo;
  if (s == "warn") return Level::kWarn;
  if (s == "error") return Level::kError;
  if (s == "off") return Level::kOff;
  return Status::InvalidArgument(field, field + " must be one of debug, info, warn, error, off");
}

StatusOr<Format> ParseFormat(const std::string& s, const std::string& field) {
  if (s == "text") return Format::kText;
  if (s == "json") return Format::kJson;
  return Status::InvalidArgument(field, field + " must be text or json");
}

void Configure(Level level, Format format) {
  State& s = S();
  std::lock_guard<std::mutex> lock(s.mu);
  s.format = format;
  s.logger->set_level(ToSpd(level));
  if (format == Format::kJson)
    s.logger->set_pattern(R"({"ts":"%Y-%m-%dT%H:%M:%S.%eZ","level":"%l",%v})", spdlog::pattern_time_type::utc);
  else
    s.logger->set_pattern("%Y-%m-%dT%H:%M:%S.%eZ %l %v", spdlog::pattern_time_type::utc);
}

bool Enabled(Level level) { return S().logger->should_log(ToSpd(level)); }

std::string Render(Format format, std::string_view event, std::initializer_list<Field> fields) {
  const bool json = format == Format::kJson;
  std::string out;
  out.reserve(128);
  if (json) {
    out += "\"event\":";
    AppendJson(out, event);
  } else {
    out += event;
  }
  for (const Field& f : fields) {
    if (json) {
      out += ',';
      AppendJson(out, f.key);
      out += ':';
    } else {
      out += ' ';
      out += f.key;
      out += '=';
    }
    std::visit(
        [&](const auto& v) {
          using T = std::decay_t<decltype(v)>;
          if constexpr (std::is_same_v<T, std::string_view>) {
            json ? AppendJson(out, v) : AppendText(out, v);
          } else if constexpr (std::is_same_v<T, bool>) {
            out += v ? "true" : "false";
          } else if constexpr (std::is_same_v<T, long long>) {
            out += std::to_string(v);
          } else {
            AppendNumber(out, v, json);
          }
        },
        f.value);
  }
  return out;
}

void Event(Level level, std::string_view event, std::initializer_list<Field> fields) {
  State& s = S();
  if (!s.logger->should_log(ToSpd(level))) return;
  Format format;
  {
    std::lock_guard<std::mutex> lock(s.mu);
    format = s.format;
  }
  const std::string line = Render(format, event, fields);
  s.logger->log(ToSpd(level), "{}", line);
}

}  // namespace bistable::log
