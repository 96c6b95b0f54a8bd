// Content keys: XXH3-128 of a canonical text, as 32 hex digits. Stable across runs and machines
// (xxHash's output is specified), used for sweep ids and point-cache keys.
#ifndef BISTABLE_ENGINE_CONTENT_HASH_H_
#define BISTABLE_ENGINE_CONTENT_HASH_H_

#include <string>

#include "dynamics/point_spec.h"

namespace bistable {

std::string ContentHashHex(const std::string& text);
// The key of one point run: model, every parameter, α, Ω, settings, initial state, numerics version.
std::string PointKey(const PointSpec& p);

}  // namespace bistable

#endif  // BISTABLE_ENGINE_CONTENT_HASH_H_
