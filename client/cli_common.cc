#include "client/cli_common.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "base/file.h"

namespace bistable {

StatusOr<std::map<std::string, std::string>> ParseNameValues(const std::string& text, const std::string& field) {
  std::map<std::string, std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0)
      return Status::InvalidArgument(field, "--" + field + " item '" + item + "' violates name=value");
    out[item.substr(0, eq)] = item.substr(eq + 1);
  }
  return out;
}

StatusOr<double> ParseFiniteNumber(const std::string& text, const std::string& field) {
  char* end = nullptr;
  const double x = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(x))
    return Status::InvalidArgument(field, field + " = '" + text + "' violates a finite number");
  return x;
}

Status WriteTextOut(const std::string& path, const std::string& text, const std::string& field) {
  if (path.empty() || path == "-") return WriteStdout(text, field);
  auto f = AtomicFile::Create(path, field);
  if (!f.ok()) return f.status();
  BISTABLE_RETURN_IF_ERROR((*f)->Write(text));
  return (*f)->Commit();
}

Status NotStdout(const std::string& path, const std::string& field, const std::string& flag, const std::string& why) {
  if (path != "-") return Status::Ok();
  return Status::InvalidArgument(
      field, flag + " - (standard output) is not supported: " + why + "; give a file name (./- for a file named '-')");
}

int Fail(const Status& st) {
  std::cerr << "error: " << st.ToString() << "\n";
  return kExitError;
}

StatusOr<SweepRef> FindSweep(const std::string& data_dir, const std::string& id) {
  const auto index = std::filesystem::path(data_dir) / "index.sqlite";
  if (!std::filesystem::exists(index))
    return Status::InvalidArgument("data",
                                   "no index at '" + index.string() + "' (run a sweep first, or pass --data DIR)");
  auto db = IndexDb::Open(index.string());
  if (!db.ok()) return db.status();
  auto row = (*db)->GetSweep(id);
  if (!row.ok()) return row.status();
  if (!row.value())
    return Status::InvalidArgument("id", "no sweep '" + id + "' in " + data_dir + " (see `bistable sweeps`)");
  SweepRef ref{*row.value(), ""};
  if (!ref.row.file.empty()) ref.map_path = (std::filesystem::path(data_dir) / ref.row.file).string();
  return ref;
}

}  // namespace bistable
