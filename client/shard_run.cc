#include "client/shard_run.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>

#include <nlohmann/json.hpp>

#include "base/file.h"
#include "base/limits.h"
#include "base/version.h"
#include "client/embedded_run.h"
#include "client/progress.h"
#include "dynamics/cancel.h"
#include "engine/evaluate.h"
#include "engine/metric_catalog.h"
#include "server/publisher.h"
#include "storage/data_dir.h"
#include "storage/index_db.h"
#include "storage/result_writer.h"
#include "worker/pull_loop.h"

namespace bistable {
namespace {

namespace fs = std::filesystem;

constexpr const char* kManifest = "shard.json";
constexpr const char* kStoreKind = "bistable-sweep shard store";

double Now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

// The record layout's hash (engine/metric_catalog.h), as the manifest keeps it.
std::string LayoutHex() {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(CatalogHash()));
  return buf;
}

size_t RecordWidth(const SweepSpec& spec) {
  return PointRecord::Size(spec.base.metrics.turning_points, spec.base.metrics.poincare_points);
}

Status WriteManifest(const std::string& store, const SweepSpec& spec, const Shard& shard, long items, bool complete) {
  const nlohmann::json j = {{"kind", kStoreKind},
                            {"sweep_id", spec.Id()},
                            {"name", spec.name},
                            {"shard", shard.index},
                            {"shards", shard.count},
                            {"items", items},
                            {"state", complete ? "complete" : "running"},
                            {"numerics_version", kNumericsVersion},
                            {"record_layout", LayoutHex()},
                            {"software_version", kSoftwareVersion},
                            {"spec", spec.source}};
  auto f = AtomicFile::Create((fs::path(store) / kManifest).string(), "shard");
  if (!f.ok()) return f.status();
  BISTABLE_RETURN_IF_ERROR((*f)->Write(j.dump(2) + "\n"));
  return (*f)->Commit();
}

// One shard's jobs for the pull loops of RunPullThreads: leased from the shard's plan, stored in its store by
// group commit. Thread-safe.
class ShardJobSource : public JobSource {
 public:
  ShardJobSource(JobPlan plan, std::shared_ptr<const SweepSpec> spec, ResultWriter& writer)
      : plan_(std::move(plan)), spec_(std::move(spec)), writer_(writer), width_(RecordWidth(*spec_)) {}

  StatusOr<std::optional<LeasedJob>> Lease() override {
    std::lock_guard<std::mutex> lock(mu_);
    if (halted_) return std::optional<LeasedJob>();
    const std::vector<long> ids = plan_.Take(1, limits::kMaxJobItems);
    if (ids.empty()) return std::optional<LeasedJob>();
    return std::optional<LeasedJob>(LeasedJob{std::to_string(ids[0]), spec_, plan_.ItemsFor(ids)});
  }
  void Heartbeat(const LeasedJob&) override {}
  Status Report(const LeasedJob& job, const std::vector<PointRecord>& records, std::optional<LeasedJob>*) override {
    const std::vector<long> ids = {std::stol(job.lease_id)};
    IndexDb::JobResults rows;
    rows.sweep_id = spec_->Id();
    rows.width = width_;
    rows.values.reserve(records.size() * width_);
    for (const PointRecord& r : records) {  // every value in its metric's domain, as a coordinator checks a report
      if (r.v.size() != width_)
        return Status::Internal("a record of " + std::to_string(r.v.size()) + " values, the sweep's have " +
                                std::to_string(width_));
      BISTABLE_RETURN_IF_ERROR(CheckAnyRecord(r.v.data(), r.v.size()));
      rows.values.insert(rows.values.end(), r.v.begin(), r.v.end());
    }
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (static_cast<long>(records.size()) != plan_.ItemsOf(ids))
        return Status::Internal("job " + job.lease_id + ": " + std::to_string(records.size()) + " records for " +
                                std::to_string(plan_.ItemsOf(ids)) + " items");
      rows.keys = plan_.KeysFor(ids);
    }
    BISTABLE_RETURN_IF_ERROR(writer_.Commit(std::move(rows)));  // durable before it counts
    std::lock_guard<std::mutex> lock(mu_);
    plan_.Complete(ids);
    return Status::Ok();
  }
  Status Release(const LeasedJob& job) override {
    std::lock_guard<std::mutex> lock(mu_);
    plan_.Requeue({std::stol(job.lease_id)});
    return Status::Ok();
  }
  void Halt() {
    std::lock_guard<std::mutex> lock(mu_);
    halted_ = true;
  }
  std::pair<long, long> Done() const {
    std::lock_guard<std::mutex> lock(mu_);
    return {plan_.items_done(), plan_.items_total()};
  }

 private:
  mutable std::mutex mu_;
  JobPlan plan_;  // under mu_
  bool halted_ = false;
  std::shared_ptr<const SweepSpec> spec_;
  ResultWriter& writer_;
  size_t width_;
};

// A store's manifest, as merge reads it.
struct StoreInfo {
  std::string path;
  Shard shard;
  long items = 0;
  bool complete = false;
  std::string sweep_id, name, numerics, layout;
};

StatusOr<StoreInfo> ReadStore(const std::string& path) {
  if (!fs::is_directory(path))
    return Status::InvalidArgument("stores", "'" + path +
                                                 "' is not a directory (a shard store is the directory "
                                                 "`bistable run SPEC --shard I/N` writes)");
  const std::string file = (fs::path(path) / kManifest).string();
  auto text = ReadTextFile(file, "stores", size_t{4} << 20);
  if (!text.ok())
    return Status::InvalidArgument("stores", "'" + path + "' is not a shard store: " + text.status().message());
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  auto text_of = [&](const char* k) { return j.contains(k) && j[k].is_string() ? j[k].get<std::string>() : ""; };
  auto int_of = [&](const char* k) { return j.contains(k) && j[k].is_number_integer() ? j[k].get<long>() : -1L; };
  StoreInfo s;
  s.path = path;
  s.sweep_id = text_of("sweep_id");
  s.name = text_of("name");
  s.numerics = text_of("numerics_version");
  s.layout = text_of("record_layout");
  s.items = int_of("items");
  s.complete = text_of("state") == "complete";
  const long index = int_of("shard"), count = int_of("shards");
  if (!j.is_object() || text_of("kind") != kStoreKind || s.sweep_id.empty() || s.numerics.empty() || count < 1 ||
      count > limits::kMaxShards || index < 0 || index >= count)
    return Status::InvalidArgument("stores", "'" + file + "' is not a shard store's manifest (kind '" + kStoreKind +
                                                 "' with sweep_id, shard, shards, numerics_version)");
  s.shard = Shard{static_cast<int>(index), static_cast<int>(count)};
  return s;
}

std::string Join(const std::vector<std::string>& parts, const std::string& sep) {
  std::string out;
  for (const std::string& p : parts) out += (out.empty() ? "" : sep) + p;
  return out;
}

Status Refused(const std::vector<std::string>& problems) {
  return Status::InvalidArgument("stores", "merge refused: " + Join(problems, "; "));
}

// The stores of a merge (MergeShards), checked: each a shard of `spec` computed with this numerics version and
// record layout, all of one shard count, each shard once, none missing. Sorted by shard; Refused (every problem
// named) otherwise.
StatusOr<std::vector<StoreInfo>> CheckStores(const SweepSpec& spec, const std::vector<std::string>& stores) {
  const std::string id = spec.Id();
  // Each store: a shard of this spec, computed with this numerics version and record layout.
  std::vector<std::string> problems;
  std::vector<StoreInfo> infos;
  for (const std::string& path : stores) {
    auto s = ReadStore(path);
    if (!s.ok()) {
      problems.push_back(s.status().message());
      continue;
    }
    if (s->sweep_id != id)
      problems.push_back("'" + path + "' is a shard of another spec: sweep " + s->sweep_id +
                         (s->name.empty() ? "" : " ('" + s->name + "')") + ", not sweep " + id +
                         (spec.name.empty() ? "" : " ('" + spec.name + "')"));
    else if (s->numerics != kNumericsVersion)
      problems.push_back("'" + path + "' was computed with numerics version " + s->numerics +
                         ", this bistable is numerics version " + kNumericsVersion + ": rerun shard " +
                         s->shard.Label() + " with this bistable");
    else if (s->layout != LayoutHex())
      problems.push_back("'" + path + "' holds records of another layout (" + s->layout + ", this bistable's is " +
                         LayoutHex() + "): rerun shard " + s->shard.Label() + " with this bistable");
    else
      infos.push_back(std::move(s).value());
  }
  if (!problems.empty()) return Refused(problems);
  // Together: one shard count, each shard once, none missing.
  std::map<int, std::vector<std::string>> counts, by_index;
  for (const StoreInfo& s : infos) counts[s.shard.count].push_back("'" + s.path + "' is " + s.shard.Label());
  if (counts.size() > 1) {
    std::vector<std::string> said;
    for (const auto& [n, paths] : counts) said.push_back(Join(paths, ", "));
    return Refused({"the stores are shards of different counts N: " + Join(said, "; ")});
  }
  const int n = infos.front().shard.count;
  for (const StoreInfo& s : infos) by_index[s.shard.index].push_back("'" + s.path + "'");
  for (const auto& [i, paths] : by_index)
    if (paths.size() > 1)
      problems.push_back("shard " + Shard{i, n}.Label() + " is given twice: " + Join(paths, " and "));
  std::vector<std::string> missing;
  for (int i = 0; i < n; ++i)
    if (!by_index.count(i)) missing.push_back(Shard{i, n}.Label());
  if (!missing.empty())
    problems.push_back(std::to_string(missing.size()) + " of " + std::to_string(n) + " shards missing: " +
                       Join(missing, ", ") + " (run `bistable run SPEC --shard I/N` for each, or name their stores)");
  if (!problems.empty()) return Refused(problems);
  std::sort(infos.begin(), infos.end(),
            [](const StoreInfo& a, const StoreInfo& b) { return a.shard.index < b.shard.index; });
  return infos;
}

// Every item of every shard (`infos`, checked), read through its checksum (the stores are not written to), in
// batches to import; Refused where a shard is incomplete or cannot be opened.
StatusOr<std::vector<IndexDb::JobResults>> ReadShards(const SweepSpec& spec, const std::vector<StoreInfo>& infos,
                                                      const std::vector<std::string>& keys) {
  const std::string id = spec.Id();
  std::vector<std::string> problems;
  const size_t width = RecordWidth(spec);
  std::vector<IndexDb::JobResults> imports;
  for (const StoreInfo& s : infos) {
    const std::vector<long> items = ShardItemIndices(spec, s.shard);
    auto db = IndexDb::Open((fs::path(s.path) / "index.sqlite").string());
    if (!db.ok()) {
      problems.push_back("shard " + s.shard.Label() + " ('" + s.path + "'): " + db.status().message());
      continue;
    }
    long found = 0, corrupt = 0;
    for (size_t b = 0; b < items.size(); b += kPlanLookupBatch) {
      IndexDb::JobResults rows;
      rows.sweep_id = id;
      rows.width = width;
      std::vector<std::string> batch;
      for (size_t k = b; k < std::min(items.size(), b + kPlanLookupBatch); ++k) batch.push_back(keys[items[k]]);
      long bad = 0;
      auto got = (*db)->LookupPoints(batch, width, &bad, IndexDb::Fold::kLater);
      if (!got.ok()) return got.status();
      corrupt += bad;
      for (const std::string& k : batch) {
        auto it = got->find(k);
        if (it == got->end()) continue;
        ++found;
        rows.keys += k + '\n';
        rows.values.insert(rows.values.end(), it->second.v.begin(), it->second.v.end());
      }
      imports.push_back(std::move(rows));
    }
    if (found < static_cast<long>(items.size()))
      problems.push_back("shard " + s.shard.Label() + " ('" + s.path + "') is incomplete: " + std::to_string(found) +
                         " of " + std::to_string(items.size()) + " items stored" +
                         (corrupt > 0 ? " (" + std::to_string(corrupt) + " failed their checksum)" : "") +
                         (s.complete ? "" : ", its run did not finish") + "; rerun `bistable run SPEC --shard " +
                         s.shard.Label() + "` on that store to finish it");
  }
  if (!problems.empty()) return Refused(problems);
  return imports;
}

}  // namespace

std::string ShardStorePath(const std::string& data_dir, const std::string& sweep_id, const Shard& shard) {
  return (fs::path(data_dir) / "shards" /
          (sweep_id + "-" + std::to_string(shard.index) + "-of-" + std::to_string(shard.count)))
      .string();
}

Status RunShard(const SweepSpec& spec, const Shard& shard, const std::string& data_dir, int threads, long job_items,
                bool progress, ShardRunResult* out) {
  BISTABLE_RETURN_IF_ERROR(CheckShardable(spec));
  const std::string store = ShardStorePath(data_dir, spec.Id(), shard);
  out->store = store;
  BISTABLE_RETURN_IF_ERROR(MakeDirectory(store, kDataDirectoryMode, "data"));
  std::vector<std::string> repairs;  // a damaged index (a node lost mid-write) is moved aside and salvaged
  auto db = OpenDataIndex(store, &repairs);
  if (!db.ok()) return db.status();
  for (const std::string& r : repairs) std::cerr << "warning: " << r << "\n";
  ResultWriter writer(std::move(db).value(), (fs::path(store) / "index.sqlite").string(), ResultWriter::Options{});
  const size_t width = RecordWidth(spec);
  auto plan = JobPlan::BuildShard(
      spec, job_items > 0 ? job_items : JobItems(spec, 0.25),
      [&](const std::vector<std::string>& keys) { return writer.Db()->LookupPoints(keys, width); }, shard);
  if (!plan.ok()) return plan.status();
  out->items = plan->items_total();
  out->cached = plan->items_cached();
  BISTABLE_RETURN_IF_ERROR(WriteManifest(store, spec, shard, out->items, false));
  // The store's sweep row counts the shard's items as they are stored (`bistable sweeps --data STORE`).
  SweepRow row;
  row.id = spec.Id();
  row.name = spec.name;
  row.model = spec.ModelLabel();
  row.spec = spec.source;
  row.state = SweepState::kRunning;
  row.items_total = out->items;
  row.items_done = out->cached;
  row.created = Now();
  row.owner = "shard " + shard.Label();
  BISTABLE_RETURN_IF_ERROR(writer.Db()->UpsertSweep(row));
  ShardJobSource source(std::move(plan).value(), std::make_shared<const SweepSpec>(spec), writer);
  const long to_compute = out->items - out->cached;
  ProgressBar bar(to_compute, "  shard " + shard.Label() + " of sweep " + spec.Id(), progress);
  const Status st = RunPullThreads(
      source, to_compute > 0 ? threads : 0, [&] { return source.Done(); }, [&] { source.Halt(); }, nullptr,
      progress ? &bar : nullptr);
  const auto [done, total] = source.Done();
  out->computed = done - out->cached;
  row.state = st.ok() && done >= total ? SweepState::kDone : SweepState::kInterrupted;
  row.items_done = done;
  row.finished = Now();
  row.seconds = row.finished - row.created;
  if (Status marked = writer.Db()->UpsertSweep(row); !marked.ok() && st.ok()) return marked;
  if (!st.ok()) return st;
  if (done < total) return CancelledStatus();
  return WriteManifest(store, spec, shard, total, true);
}

StatusOr<MergeResult> MergeShards(const SweepSpec& spec, std::vector<std::string> stores, const std::string& data_dir) {
  BISTABLE_RETURN_IF_ERROR(CheckShardable(spec));
  const std::string id = spec.Id();
  const std::string shards_dir = (fs::path(data_dir) / "shards").string();
  if (stores.empty()) {  // every store of this sweep under <data>/shards
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(shards_dir, ec))
      if (e.is_directory() && e.path().filename().string().rfind(id + "-", 0) == 0) stores.push_back(e.path().string());
    std::sort(stores.begin(), stores.end());
    if (stores.empty())
      return Status::InvalidArgument("stores", "no shard store of sweep " + id + " under '" + shards_dir +
                                                   "': run `bistable run SPEC --shard I/N --data " + data_dir +
                                                   "` for every I first, or name the stores");
  }
  auto infos = CheckStores(spec, stores);
  if (!infos.ok()) return infos.status();
  const int n = infos->front().shard.count;
  const std::vector<std::string> keys = ItemKeys(spec);
  auto read = ReadShards(spec, *infos, keys);
  if (!read.ok()) return read.status();
  std::vector<IndexDb::JobResults> imports = std::move(read).value();

  // The map, written and indexed as the embedded run publishes it (server/publisher.h, PublishMap).
  BISTABLE_RETURN_IF_ERROR(MakeDirectory((fs::path(data_dir) / "sweeps").string(), kDataDirectoryMode, "data"));
  std::vector<std::string> repairs;
  auto db = OpenDataIndex(data_dir, &repairs);
  if (!db.ok()) return db.status();
  for (const std::string& r : repairs) std::cerr << "warning: " << r << "\n";
  ResultWriter writer(std::move(db).value(), (fs::path(data_dir) / "index.sqlite").string(), ResultWriter::Options{});
  const double started = Now();
  auto existing = writer.Db()->GetSweep(id);
  if (!existing.ok()) return existing.status();
  SweepRow row = existing.value() && existing.value()->id == id ? *existing.value() : SweepRow{};
  row.id = id;
  row.name = spec.name;
  row.model = spec.ModelLabel();
  row.spec = spec.source;
  row.state = SweepState::kRunning;
  row.items_total = static_cast<long>(keys.size());
  row.items_done = 0;
  row.file.clear();
  if (row.owner.empty()) row.owner = "local";
  if (row.created == 0) row.created = started;
  BISTABLE_RETURN_IF_ERROR(writer.Db()->UpsertSweep(row));
  for (IndexDb::JobResults& rows : imports)  // into this data directory's point cache: later runs reuse them
    BISTABLE_RETURN_IF_ERROR(writer.Commit(std::move(rows)));
  MapPublication m{spec,     keys,        {}, row, started, (fs::path(data_dir) / "sweeps" / (id + ".h5")).string(),
                   data_dir, MapOrigin{n}};
  MapPublication::Outcome said;
  auto published = PublishMap(m, writer, Now, nullptr, &said);
  if (!published.ok()) return published.status();
  if (!said.folded.ok()) std::cerr << "warning: " << said.folded.ToString() << "\n";
  return MergeResult{id, m.path, n, static_cast<long>(keys.size())};
}

}  // namespace bistable
