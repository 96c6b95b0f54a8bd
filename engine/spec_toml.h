// The TOML text of a spec (a sweep spec, a design spec), read once: bounded in size, parsed, and a
// syntax error said with the origin, line and column. Include only where toml++ is used header-only
// (TOML_HEADER_ONLY=1: engine/, design/).
#ifndef BISTABLE_ENGINE_SPEC_TOML_H_
#define BISTABLE_ENGINE_SPEC_TOML_H_

#include <string>

#include <toml++/toml.h>

#include "base/status.h"

namespace bistable {

// "origin:line:column" of a region (just the origin when the region is unknown).
std::string TomlWhere(const toml::source_region& r, const std::string& origin);
// At most limits::kMaxSpecBytes of text, parsed; errors under the field "spec".
StatusOr<toml::table> ParseSpecToml(const std::string& text, const std::string& origin);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_SPEC_TOML_H_
