// Reading a whole text file (specs, certificates, tokens, measured records), bounded, with the field
// that named the path in the error; writing a file atomically (temp beside it + rename).
#ifndef BISTABLE_BASE_FILE_H_
#define BISTABLE_BASE_FILE_H_

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "base/status.h"

namespace bistable {

// The file's bytes; InvalidArgument naming `field` when it cannot be read, is not a regular file, or
// holds more than `max_bytes`.
StatusOr<std::string> ReadTextFile(const std::string& path, const std::string& field, size_t max_bytes = size_t{1} << 30);

// A file written whole or not at all: a new temporary beside `path` (O_EXCL, never someone else's;
// mode 0666 less the umask) that Commit() syncs and renames over `path`. Destroyed uncommitted, the
// temporary is removed (an error, a cancelled transfer). Errors name `field`.
class AtomicFile {
 public:
  static StatusOr<std::unique_ptr<AtomicFile>> Create(const std::string& path, const std::string& field);
  ~AtomicFile();
  Status Write(std::string_view data);
  Status Commit();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

 private:
  AtomicFile(std::string path, std::string tmp, std::string field, int fd)
      : path_(std::move(path)), tmp_(std::move(tmp)), field_(std::move(field)), fd_(fd) {}
  std::string path_, tmp_, field_;
  int fd_ = -1;
  bool committed_ = false;
};

}  // namespace bistable

#endif  // BISTABLE_BASE_FILE_H_
