// Suggestions for misspelt names, in one format for every message that lists a vocabulary:
//   unknown key 'alpah'; did you mean 'alpha'? (allowed: alpha, omega, ...)
#ifndef BISTABLE_BASE_NAMES_H_
#define BISTABLE_BASE_NAMES_H_

#include <cstddef>
#include <string>
#include <vector>

namespace bistable {

// The candidate `word` most likely meant: the only one it is a prefix of, else the closest by edit
// distance within a third of the longer length (+1); "" when none is close.
std::string NearestName(const std::string& word, const std::vector<std::string>& candidates);

// "unknown <what> '<word>'; did you mean '<nearest>'? (allowed: a, b, c)". Every name is shown with
// control bytes as \xNN and cut at 80 bytes (the word, and a vocabulary read from a file, may come from
// anyone); at most kMaxNamesListed names are listed ("..., ... (N more)").
inline constexpr size_t kMaxNamesListed = 64;
std::string UnknownNameMessage(const std::string& what, const std::string& word,
                               const std::vector<std::string>& allowed);

// `s` for a message: control bytes, DEL and backslash as \xNN, at most `max_bytes` (then "...").
std::string Printable(const std::string& s, size_t max_bytes = 80);

}  // namespace bistable

#endif  // BISTABLE_BASE_NAMES_H_
