// Reading a whole text file (specs, certificates, tokens), bounded, or one line at a time (measured
// records), each line bounded, with the field that named the path in the error; writing a file
// atomically (temp beside it + rename), or to standard output.
#ifndef BISTABLE_BASE_FILE_H_
#define BISTABLE_BASE_FILE_H_

#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "base/status.h"

namespace bistable {

// The file's bytes; InvalidArgument naming `field` when it is missing, cannot be opened, is not a regular
// file (checked by name and again on the opened descriptor, so a FIFO swapped in never blocks), or holds
// more than `max_bytes`; IoError when reading it fails.
StatusOr<std::string> ReadTextFile(const std::string& path, const std::string& field,
                                   size_t max_bytes = size_t{1} << 30);

// A text file read one line at a time, each line at most `max_line_bytes` long (its "\n" not counted),
// so a file without line ends never fills memory. Open fails as ReadTextFile does (missing, not a
// regular file), naming `field`.
class LineReader {
 public:
  enum class Result { kLine, kEnd, kTooLong };
  static StatusOr<std::unique_ptr<LineReader>> Open(const std::string& path, const std::string& field,
                                                    size_t max_line_bytes);
  ~LineReader();
  // kLine: *line is the next line without its "\n" (a "\r" before it is kept); kEnd: no more lines;
  // kTooLong: line line_number() holds more than max_line_bytes bytes (reading stops). A read error is
  // an IoError naming the field.
  StatusOr<Result> Next(std::string* line);
  long line_number() const { return line_no_; }  // 1-based number of the line Next returned
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

 private:
  LineReader(std::string path, std::string field, int fd, size_t max)
      : path_(std::move(path)), field_(std::move(field)), fd_(fd), max_(max) {}
  std::string path_, field_;
  int fd_ = -1;
  size_t max_ = 0;
  std::string buf_;
  size_t pos_ = 0;
  bool eof_ = false;
  long line_no_ = 0;
};

// All of `data` on standard output (stdio's buffer flushed first, so it follows what was printed);
// IoError naming `field` when the write fails (e.g. EPIPE: the reader went away).
Status WriteStdout(std::string_view data, const std::string& field);

// Creates directory `path` with permission bits `mode` (less the umask), and its missing parents as
// create_directories does; a directory that exists keeps its mode. IoError naming `field`.
Status MakeDirectory(const std::string& path, unsigned mode, const std::string& field);

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
