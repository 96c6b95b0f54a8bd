// Reading a whole text file (specs, certificates, tokens, measured records), bounded, with the field
// that named the path in the error.
#ifndef BISTABLE_BASE_FILE_H_
#define BISTABLE_BASE_FILE_H_

#include <cstddef>
#include <string>

#include "base/status.h"

namespace bistable {

// The file's bytes; InvalidArgument naming `field` when it cannot be read, is not a regular file, or
// holds more than `max_bytes`.
StatusOr<std::string> ReadTextFile(const std::string& path, const std::string& field, size_t max_bytes = size_t{1} << 30);

}  // namespace bistable

#endif  // BISTABLE_BASE_FILE_H_
