// JSON text from a file or a peer, before it is parsed: how deep it nests. nlohmann's parser (and the
// destructor of what it builds) recurses once per level, so a hostile file of a million '[' would run it off
// the stack; readers check the depth first and refuse past their limit (limits::kMaxModelJsonDepth).
#ifndef BISTABLE_BASE_JSON_TEXT_H_
#define BISTABLE_BASE_JSON_TEXT_H_

#include <algorithm>
#include <string_view>

namespace bistable {

// The deepest nesting of [ and { outside strings.
inline int JsonNestingDepth(std::string_view text) {
  int depth = 0, deepest = 0;
  bool in_string = false, escaped = false;
  for (char ch : text) {
    if (in_string) {
      if (escaped)
        escaped = false;
      else if (ch == '\\')
        escaped = true;
      else if (ch == '"')
        in_string = false;
      continue;
    }
    if (ch == '"')
      in_string = true;
    else if (ch == '[' || ch == '{')
      deepest = std::max(deepest, ++depth);
    else if (ch == ']' || ch == '}')
      --depth;
  }
  return deepest;
}

}  // namespace bistable

#endif  // BISTABLE_BASE_JSON_TEXT_H_
