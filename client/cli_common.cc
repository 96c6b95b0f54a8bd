#include "client/cli_common.h"

#include <filesystem>
#include <iostream>

namespace bistable {

int Fail(const Status& st) {
  std::cerr << "error: " << st.ToString() << "\n";
  return kExitBadInput;
}

StatusOr<SweepRef> FindSweep(const std::string& data_dir, const std::string& id) {
  const auto index = std::filesystem::path(data_dir) / "index.sqlite";
  if (!std::filesystem::exists(index))
    return Status::InvalidArgument("data", "no index at '" + index.string() + "' (run a sweep first, or pass --data DIR)");
  auto db = IndexDb::Open(index.string());
  if (!db.ok()) return db.status();
  auto row = (*db)->GetSweep(id);
  if (!row.ok()) return row.status();
  if (!row.value()) return Status::InvalidArgument("id", "no sweep '" + id + "' in " + data_dir + " (see `bistable sweeps`)");
  SweepRef ref{*row.value(), ""};
  if (!ref.row.file.empty()) ref.map_path = (std::filesystem::path(data_dir) / ref.row.file).string();
  return ref;
}

}  // namespace bistable
