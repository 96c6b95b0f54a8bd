#include "base/names.h"

#include <algorithm>
#include <cstdio>

namespace bistable {

std::string NearestName(const std::string& word, const std::vector<std::string>& candidates) {
  // A unique candidate that starts with the word ("frf" → "frf_db") wins outright.
  std::string prefixed;
  int prefix_hits = 0;
  for (const std::string& c : candidates)
    if (!word.empty() && c.rfind(word, 0) == 0) prefixed = c, ++prefix_hits;
  if (prefix_hits == 1) return prefixed;
  if (word.size() > 256) return "";  // no real name is that long; spare the quadratic distance
  std::string best;
  size_t best_d = std::string::npos;
  for (const std::string& c : candidates) {
    std::vector<size_t> prev(c.size() + 1), cur(c.size() + 1);
    for (size_t j = 0; j <= c.size(); ++j) prev[j] = j;
    for (size_t i = 1; i <= word.size(); ++i) {
      cur[0] = i;
      for (size_t j = 1; j <= c.size(); ++j)
        cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, prev[j - 1] + (word[i - 1] == c[j - 1] ? 0 : 1)});
      std::swap(prev, cur);
    }
    if (prev[c.size()] < best_d && prev[c.size()] <= std::max(word.size(), c.size()) / 3 + 1)
      best_d = prev[c.size()], best = c;
  }
  return best;
}

std::string Printable(const std::string& s, size_t max_bytes) {
  std::string out;
  for (size_t i = 0; i < s.size() && i < max_bytes; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c == 0x7f || c == '\\') {
      char b[8];
      std::snprintf(b, sizeof b, "\\x%02x", c);
      out += b;
    } else {
      out += s[i];
    }
  }
  if (s.size() > max_bytes) out += "...";
  return out;
}

std::string UnknownNameMessage(const std::string& what, const std::string& word,
                               const std::vector<std::string>& allowed) {
  std::string msg = "unknown " + what + " '" + Printable(word) + "'";
  const std::string near = NearestName(word, allowed);
  if (!near.empty()) msg += "; did you mean '" + Printable(near) + "'?";
  std::string list;
  for (size_t i = 0; i < allowed.size() && i < kMaxNamesListed; ++i)
    list += (list.empty() ? "" : ", ") + Printable(allowed[i]);
  if (allowed.size() > kMaxNamesListed) list += ", ... (" + std::to_string(allowed.size() - kMaxNamesListed) + " more)";
  return msg + " (allowed: " + list + ")";
}

}  // namespace bistable
