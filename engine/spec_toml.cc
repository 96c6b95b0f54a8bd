#include "engine/spec_toml.h"

#include "base/limits.h"

namespace bistable {

std::string TomlWhere(const toml::source_region& r, const std::string& origin) {
  if (!r.begin) return origin;
  return origin + ":" + std::to_string(r.begin.line) + ":" + std::to_string(r.begin.column);
}

StatusOr<toml::table> ParseSpecToml(const std::string& text, const std::string& origin) {
  if (text.size() > limits::kMaxSpecBytes)
    return Status::InvalidArgument("spec", "spec is " + std::to_string(text.size()) + " bytes, over the limit of " +
                                               std::to_string(limits::kMaxSpecBytes));
  try {
    return toml::parse(text, origin);
  } catch (const toml::parse_error& e) {
    return Status::InvalidArgument("spec",
                                   TomlWhere(e.source(), origin) + ": malformed TOML: " + std::string(e.description()));
  }
}

}  // namespace bistable
