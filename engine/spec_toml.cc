#include "engine/spec_toml.h"

#include <algorithm>

#include "base/limits.h"
#include "base/names.h"

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

// The readers of a spec's values (sweep specs: sweep_spec_read.cc, its [terms]: sweep_spec_terms.cc).
Status Unknown(const std::string& field, const std::string& key, const std::vector<std::string>& allowed) {
  // The key as it appears in the field name is cut and escaped like the message's (a 1 MB key was echoed whole).
  const std::string shown = Printable(key, 80);
  return Status::InvalidArgument(field.empty() ? shown : field + "." + shown, UnknownNameMessage("key", key, allowed));
}

// A value outside its vocabulary (a metric name in a list, ...).
Status UnknownValue(const std::string& field, const std::string& value, const std::vector<std::string>& allowed) {
  return Status::InvalidArgument(field, UnknownNameMessage("name", value, allowed));
}

Status CheckKeys(const toml::table& t, const std::string& field, const std::vector<std::string>& allowed) {
  for (auto&& [k, v] : t) {
    (void)v;
    const std::string key(k.str());
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) return Unknown(field, key, allowed);
  }
  return Status::Ok();
}

StatusOr<double> Number(const toml::node& n, const std::string& field) {
  if (auto i = n.value<int64_t>(); i && n.is_integer()) return static_cast<double>(*i);
  if (auto d = n.value<double>()) return *d;
  return Status::InvalidArgument(field, field + " must be a number");
}

StatusOr<std::string> String(const toml::node& n, const std::string& field) {
  if (auto s = n.value<std::string>()) return *s;
  return Status::InvalidArgument(field, field + " must be a string");
}

Status ReadNumber(const toml::table& t, const std::string& key, const std::string& field, double* out) {
  if (const toml::node* n = t.get(key)) {
    auto v = Number(*n, field);
    if (!v.ok()) return v.status();
    *out = *v;
  }
  return Status::Ok();
}

// An integer setting in [lo, hi]: TOML integers are 64-bit; nothing is narrowed silently.
Status ReadInt(const toml::table& t, const std::string& key, const std::string& field, int* out, long lo, long hi) {
  if (const toml::node* n = t.get(key)) {
    if (!n->is_integer()) return Status::InvalidArgument(field, field + " must be an integer");
    const int64_t v = *n->value<int64_t>();
    if (v < lo || v > hi)
      return Status::InvalidArgument(field, field + " = " + std::to_string(v) + " violates " + field + " in [" +
                                                std::to_string(lo) + ", " + std::to_string(hi) + "]");
    *out = static_cast<int>(v);
  }
  return Status::Ok();
}

// Text for humans (names, origins): bounded, and no control characters (they would rewrite a
// terminal or a log line when printed).
Status CheckPlainText(const std::string& field, const std::string& s, size_t max_bytes) {
  if (s.size() > max_bytes)
    return Status::InvalidArgument(
        field, field + " is " + std::to_string(s.size()) + " bytes, over the limit of " + std::to_string(max_bytes));
  for (size_t i = 0; i < s.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7f)
      return Status::InvalidArgument(field, field + " holds a control character (byte " + std::to_string(c) + " at " +
                                                std::to_string(i) + "); names are plain text");
  }
  return Status::Ok();
}

StatusOr<std::vector<double>> NumberArray(const toml::node& n, const std::string& field) {
  const toml::array* a = n.as_array();
  if (!a) return Status::InvalidArgument(field, field + " must be an array of numbers");
  std::vector<double> out;
  for (size_t i = 0; i < a->size(); ++i) {
    auto v = Number((*a)[i], field + "[" + std::to_string(i) + "]");
    if (!v.ok()) return v.status();
    out.push_back(*v);
  }
  return out;
}

}  // namespace bistable
