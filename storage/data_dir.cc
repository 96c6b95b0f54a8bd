#include "storage/data_dir.h"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <optional>

#include "engine/metric_catalog.h"
#include "engine/sweep_spec.h"
#include "storage/map_file.h"

namespace bistable {

namespace fs = std::filesystem;

StatusOr<std::string> MoveAside(const std::string& path) {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", &utc);
  std::string aside = path + ".corrupt-" + stamp;
  std::error_code ec;
  for (int n = 2; fs::exists(fs::symlink_status(aside, ec)); ++n)
    aside = path + ".corrupt-" + stamp + "-" + std::to_string(n);
  fs::rename(path, aside, ec);
  if (ec) return Status::IoError("data", "cannot move '" + path + "' aside to '" + aside + "': " + ec.message());
  return aside;
}

Status CheckMapFile(const std::string& path, const std::string& id) {
  auto stored = ReadMapAttribute(path, "sweep_id");
  if (!stored.ok())
    return Status::IoError("map", "map file '" + path + "' does not open as HDF5 (truncated or overwritten)");
  if (*stored != id)
    return Status::IoError("map", "map file '" + path + "' names sweep '" + stored->substr(0, 64) + "', not " + id);
  auto metrics = ListMapMetrics(path);
  if (!metrics.ok() || metrics->empty()) return Status::IoError("map", "map file '" + path + "' holds no metric");
  return Status::Ok();
}

namespace {

bool IsMapName(const std::string& name) {
  return name.size() == 15 && name.compare(12, 3, ".h5") == 0 && name.find_first_not_of("0123456789abcdef") == 12;
}

// The index row and map rows of a published map file, from the file alone.
Status IndexMapFile(IndexDb& db, const std::string& data_dir, const std::string& id, const std::string& path) {
  BISTABLE_RETURN_IF_ERROR(CheckMapFile(path, id));
  auto toml = ReadMapAttribute(path, "spec");
  if (!toml.ok()) return toml.status();
  auto spec = ParseSweepSpec(*toml, "map " + path);
  if (!spec.ok()) return Status::FailedPrecondition("its spec does not parse here (" + spec.status().ToString() + ")");
  if (spec->Id() != id)
    return Status::FailedPrecondition("its spec is sweep " + spec->Id() +
                                      " for this program (another numerics version?)");
  SweepRow row;
  row.id = id;
  row.name = spec->name;
  row.model = spec->ModelLabel();
  row.spec = spec->source;
  row.state = SweepState::kDone;
  row.items_total = row.items_done = spec->points() * spec->ic_count();
  row.file = fs::relative(path, data_dir).string();
  struct stat st {};
  row.created = row.finished = ::stat(path.c_str(), &st) == 0 ? static_cast<double>(st.st_mtime) : 0.0;
  std::vector<MapRow> maps;
  const std::string shape = MapShape(*spec);
  for (const MetricInfo& m : MetricCatalog()) {
    if (std::find(spec->metrics.begin(), spec->metrics.end(), m.name) == spec->metrics.end()) continue;
    auto a = ReadMapMetric(path, m.name);
    if (!a.ok()) return a.status();
    double lo = NAN, hi = NAN;
    for (double v : a->values) {
      if (!std::isfinite(v)) continue;
      lo = std::isnan(lo) ? v : std::min(lo, v);
      hi = std::isnan(hi) ? v : std::max(hi, v);
    }
    maps.push_back({id, m.name, row.file, shape, lo, hi});
  }
  return db.PublishSweep(row, maps);
}

}  // namespace

StatusOr<std::vector<std::string>> UnindexedMapFiles(IndexDb* db, const std::string& data_dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (auto it = fs::directory_iterator(fs::path(data_dir) / "sweeps", ec); !ec && it != fs::directory_iterator();
       it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (!IsMapName(name) || !it->is_regular_file(ec)) continue;
    if (db) {
      auto row = db->GetSweep(name.substr(0, 12));
      if (!row.ok()) return row.status();
      if (row.value() && row.value()->id == name.substr(0, 12)) continue;
    }
    out.push_back(it->path().string());
  }
  return out;
}

StatusOr<std::unique_ptr<IndexDb>> OpenDataIndex(const std::string& data_dir, std::vector<std::string>* notes) {
  const std::string index = (fs::path(data_dir) / "index.sqlite").string();
  auto problem = IndexDb::QuickCheck(index);  // before anything writes to it
  if (!problem.ok()) return problem.status();
  std::optional<IndexDb::Salvaged> salvaged;
  std::string aside;
  if (!problem->empty()) {
    auto moved = MoveAside(index);
    if (!moved.ok()) return moved.status();
    aside = *moved;
    std::error_code ec;
    for (const char* side : {"-wal", "-shm"})  // SQLite's names for them, beside the moved file
      if (fs::exists(index + side, ec)) fs::rename(index + side, aside + side, ec);
  }
  auto db = IndexDb::Open(index);
  if (!db.ok()) return db.status();
  if (!aside.empty()) {
    auto got = (*db)->SalvageFrom(aside);
    if (!got.ok()) return got.status();
    notes->push_back("index '" + index + "' is damaged (" + problem->substr(0, 200) + "): moved aside to '" + aside +
                     "'; the new index holds what could be read of it (" + std::to_string(got->sweeps) +
                     " unfinished sweeps, " + std::to_string(got->points) + " stored points, " +
                     std::to_string(got->staged) +
                     " staged reports) and the published maps of sweeps/; what is missing is computed again");
  }
  // Map files the index holds no row for: an empty, missing or rebuilt index.
  auto orphans = UnindexedMapFiles(db->get(), data_dir);
  if (!orphans.ok()) return orphans.status();
  std::vector<std::string> indexed;
  for (const std::string& path : *orphans) {
    const std::string id = fs::path(path).filename().string().substr(0, 12);
    Status st = IndexMapFile(**db, data_dir, id, path);
    if (st.ok()) {
      indexed.push_back(id);
    } else if (st.code() == Status::Code::kIoError && st.field() == "map") {  // does not open: aside, not lost
      auto aside = MoveAside(path);
      notes->push_back(st.message() +
                       (aside.ok() ? ": moved aside to '" + *aside + "'" : ": " + aside.status().message()));
    } else {
      notes->push_back("map file '" + path + "' is not indexed: " + st.message());
    }
  }
  if (!indexed.empty()) {
    std::string ids;
    for (size_t i = 0; i < indexed.size() && i < 8; ++i) ids += (i ? ", " : "") + indexed[i];
    if (indexed.size() > 8) ids += ", ...";
    notes->push_back("index '" + index + "' held no row for " + std::to_string(indexed.size()) + " map file(s) of '" +
                     (fs::path(data_dir) / "sweeps").string() +
                     "' (an empty, missing or rebuilt index): indexed them again as published sweeps (" + ids + ")");
  }
  return db;
}

}  // namespace bistable
