#include "base/file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

namespace bistable {
namespace {

// `path` opened for reading and checked to be a regular file by name and again on the descriptor itself: a
// FIFO or a device swapped in between the check by name and the open would otherwise block the open, or never
// end. The open is non-blocking (a FIFO without a writer opens at once), the descriptor blocking again after.
StatusOr<int> OpenRegularFile(const std::string& path, const std::string& field, off_t* size) {
  const auto not_regular = [&] {
    return Status::InvalidArgument(field, field + " file '" + path + "' is not a regular file");
  };
  // By name first: a device or FIFO is refused without being opened (opening one can have effects: a FIFO's
  // writer is released, some devices act on open); the descriptor's check below closes the race.
  std::error_code ec;
  const auto named = std::filesystem::status(path, ec);
  if (!ec && std::filesystem::exists(named) && !std::filesystem::is_regular_file(named)) return not_regular();
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (fd < 0) {
    const int e = errno;
    return Status::InvalidArgument(
        field, "cannot read " + field + " file '" + path +
                   "': " + (e == ENOENT ? std::string("no such file") : std::string(std::strerror(e))));
  }
  struct stat st;
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    return Status::IoError(field, "cannot read " + field + " file '" + path + "': " + std::strerror(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return not_regular();
  }
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags < 0 || ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
    const int e = errno;
    ::close(fd);
    return Status::IoError(field, "cannot read " + field + " file '" + path + "': " + std::strerror(e));
  }
  if (size) *size = st.st_size;
  return fd;
}

// All of `data` to `fd` (short writes and EINTR retried); errors say "writing <what> failed".
Status WriteAll(int fd, std::string_view data, const std::string& field, const std::string& what) {
  size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Status::IoError(field, "writing " + what + " failed: " + std::strerror(n < 0 ? errno : EIO));
    done += static_cast<size_t>(n);
  }
  return Status::Ok();
}

}  // namespace

StatusOr<std::string> ReadTextFile(const std::string& path, const std::string& field, size_t max_bytes) {
  off_t size = 0;
  auto opened = OpenRegularFile(path, field, &size);
  if (!opened.ok()) return opened.status();
  const int fd = *opened;
  if (static_cast<unsigned long long>(size) > max_bytes) {
    ::close(fd);
    return Status::InvalidArgument(field, field + " file '" + path + "' is " + std::to_string(size) +
                                              " bytes, over the limit of " + std::to_string(max_bytes));
  }
  std::string text;
  char buf[1 << 16];
  for (;;) {  // the file may grow after the fstat: the limit holds on what is read
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      return Status::IoError(field, "reading " + field + " file '" + path + "' failed: " + std::strerror(e));
    }
    if (n == 0) break;
    text.append(buf, static_cast<size_t>(n));
    if (text.size() > max_bytes) {
      ::close(fd);
      return Status::InvalidArgument(
          field, field + " file '" + path + "' is over the limit of " + std::to_string(max_bytes) + " bytes");
    }
  }
  ::close(fd);
  return text;
}

Status MakeDirectory(const std::string& path, unsigned mode, const std::string& field) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path p = fs::path(path).lexically_normal();
  const fs::path dir = p.has_filename() ? p : p.parent_path();  // "data/" names "data"
  if (dir.has_parent_path()) fs::create_directories(dir.parent_path(), ec);
  if (!ec && ::mkdir(dir.c_str(), static_cast<mode_t>(mode)) != 0) {
    const int err = errno;
    if (!(err == EEXIST && fs::is_directory(dir, ec)))
      ec = std::error_code(err == EEXIST ? ENOTDIR : err, std::generic_category());
  }
  if (ec) return Status::IoError(field, "cannot create directory '" + path + "': " + ec.message());
  return Status::Ok();
}

StatusOr<std::unique_ptr<AtomicFile>> AtomicFile::Create(const std::string& path, const std::string& field) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  if (path.empty() || !p.has_filename())
    return Status::InvalidArgument(field, "output '" + path + "' does not name a file");
  const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    return Status::InvalidArgument(field, "cannot write '" + path + "': directory '" + dir.string() +
                                              (fs::exists(dir, ec) ? "' is not a directory" : "' does not exist"));
  std::string tmp;
  int fd = -1;
  std::random_device rd;
  for (int attempt = 0; attempt < 64 && fd < 0; ++attempt) {
    tmp = (dir / (".bistable-out-" + std::to_string(::getpid()) + "-" + std::to_string(rd()))).string();
    fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno != EEXIST) break;
  }
  if (fd < 0) return Status::IoError(field, "cannot create a file in '" + dir.string() + "': " + std::strerror(errno));
  return std::unique_ptr<AtomicFile>(new AtomicFile(path, tmp, field, fd));
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(tmp_.c_str());
}

Status AtomicFile::Write(std::string_view data) {
  if (fd_ < 0) return Status::IoError(field_, "writing '" + path_ + "' after it was closed");
  return WriteAll(fd_, data, field_, "'" + path_ + "'");
}

Status WriteStdout(std::string_view data, const std::string& field) {
  std::fflush(stdout);
  return WriteAll(STDOUT_FILENO, data, field, "to standard output");
}

StatusOr<std::unique_ptr<LineReader>> LineReader::Open(const std::string& path, const std::string& field,
                                                       size_t max_line_bytes) {
  auto fd = OpenRegularFile(path, field, nullptr);
  if (!fd.ok()) return fd.status();
  return std::unique_ptr<LineReader>(new LineReader(path, field, *fd, max_line_bytes));
}

LineReader::~LineReader() {
  if (fd_ >= 0) ::close(fd_);
}

StatusOr<LineReader::Result> LineReader::Next(std::string* line) {
  line->clear();
  bool any = false;  // bytes of this line seen (an empty last segment after a final "\n" is no line)
  for (;;) {
    if (pos_ < buf_.size()) {
      const size_t nl = buf_.find('\n', pos_);
      const size_t end = nl == std::string::npos ? buf_.size() : nl;
      line->append(buf_, pos_, end - pos_);
      any = true;
      pos_ = nl == std::string::npos ? buf_.size() : nl + 1;
      if (line->size() > max_) return ++line_no_, Result::kTooLong;
      if (nl != std::string::npos) return ++line_no_, Result::kLine;
    }
    if (eof_) return any ? (++line_no_, Result::kLine) : Result::kEnd;
    buf_.resize(size_t{1} << 16);
    pos_ = 0;
    ssize_t n;
    do n = ::read(fd_, buf_.data(), buf_.size());
    while (n < 0 && errno == EINTR);
    if (n < 0)
      return Status::IoError(field_, "reading " + field_ + " file '" + path_ + "' failed: " + std::strerror(errno));
    buf_.resize(static_cast<size_t>(n));
    eof_ = n == 0;
  }
}

Status AtomicFile::Commit() {
  if (fd_ < 0) return Status::IoError(field_, "'" + path_ + "' was already closed");
  const int synced = ::fsync(fd_) == 0 ? 0 : errno;
  const int closed = ::close(fd_) == 0 ? 0 : errno;
  fd_ = -1;
  if (synced || closed)
    return Status::IoError(field_, "writing '" + path_ + "' failed: " + std::strerror(synced ? synced : closed));
  if (::rename(tmp_.c_str(), path_.c_str()) != 0)
    return Status::IoError(field_, "renaming onto '" + path_ + "' failed: " + std::strerror(errno));
  committed_ = true;
  return Status::Ok();
}

}  // namespace bistable
