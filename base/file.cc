#include "base/file.h"

#include <filesystem>
#include <fstream>
#include <iterator>

namespace bistable {

StatusOr<std::string> ReadTextFile(const std::string& path, const std::string& field, size_t max_bytes) {
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(st))
    return Status::InvalidArgument(field, "cannot read " + field + " file '" + path + "': no such file");
  if (!std::filesystem::is_regular_file(st))
    return Status::InvalidArgument(field, field + " file '" + path + "' is not a regular file");
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > max_bytes)
    return Status::InvalidArgument(field, field + " file '" + path + "' is " + std::to_string(size) +
                                              " bytes, over the limit of " + std::to_string(max_bytes));
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::InvalidArgument(field, "cannot read " + field + " file '" + path + "'");
  std::string text(std::istreambuf_iterator<char>(in), {});
  if (text.size() > max_bytes)
    return Status::InvalidArgument(field, field + " file '" + path + "' is over the limit of " + std::to_string(max_bytes) + " bytes");
  return text;
}

}  // namespace bistable
