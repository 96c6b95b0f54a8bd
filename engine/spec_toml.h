// The TOML text of a spec (a sweep spec, a design spec), read once: bounded in size, parsed, and a
// syntax error said with the origin, line and column. Include only where toml++ is used header-only
// (TOML_HEADER_ONLY=1: engine/, design/).
#ifndef BISTABLE_ENGINE_SPEC_TOML_H_
#define BISTABLE_ENGINE_SPEC_TOML_H_

#include <string>
#include <vector>

#include <toml++/toml.h>

#include "base/status.h"

namespace bistable {

// "origin:line:column" of a region (just the origin when the region is unknown).
std::string TomlWhere(const toml::source_region& r, const std::string& origin);
// At most limits::kMaxSpecBytes of text, parsed; errors under the field "spec".
StatusOr<toml::table> ParseSpecToml(const std::string& text, const std::string& origin);

// The readers of a spec's values; every error names the field ("params.eta") and the rule.
// An unknown key (the nearest known one suggested), or an unknown value of a vocabulary.
Status Unknown(const std::string& field, const std::string& key, const std::vector<std::string>& allowed);
Status UnknownValue(const std::string& field, const std::string& value, const std::vector<std::string>& allowed);
// Every key of `t` is one of `allowed`.
Status CheckKeys(const toml::table& t, const std::string& field, const std::vector<std::string>& allowed);
StatusOr<double> Number(const toml::node& n, const std::string& field);
StatusOr<std::string> String(const toml::node& n, const std::string& field);
// t[key] into *out when present (a number; integers convert).
Status ReadNumber(const toml::table& t, const std::string& key, const std::string& field, double* out);
// An integer setting in [lo, hi]: TOML integers are 64-bit; nothing is narrowed silently.
Status ReadInt(const toml::table& t, const std::string& key, const std::string& field, int* out, long lo, long hi);
// Text for humans (names, origins): bounded, and no control characters (they would rewrite a terminal or a
// log line when printed).
Status CheckPlainText(const std::string& field, const std::string& s, size_t max_bytes);
StatusOr<std::vector<double>> NumberArray(const toml::node& n, const std::string& field);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_SPEC_TOML_H_
