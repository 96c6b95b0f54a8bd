#include "server/sweep_coordinator.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "storage/map_file.h"

namespace bistable {
namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace

StatusOr<std::unique_ptr<SweepCoordinator>> SweepCoordinator::Open(const std::string& data_dir) {
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(data_dir) / "sweeps", ec);
  if (ec) return Status::IoError("data", "cannot create data directory '" + data_dir + "': " + ec.message());
  if (::access(data_dir.c_str(), W_OK) != 0)
    return Status::IoError("data", "data directory '" + data_dir + "' is not writable");
  auto db = IndexDb::Open((std::filesystem::path(data_dir) / "index.sqlite").string());
  if (!db.ok()) return db.status();
  return std::unique_ptr<SweepCoordinator>(new SweepCoordinator(data_dir, std::move(db.value())));
}

std::string SweepCoordinator::MapPath(const std::string& id) const {
  return (std::filesystem::path(data_dir_) / "sweeps" / (id + ".h5")).string();
}

std::vector<std::string> SweepCoordinator::KeysFor(const std::vector<WorkItem>& items) const {
  std::vector<std::string> keys;
  keys.reserve(items.size());
  const int nic = spec_.ic_count();
  for (const WorkItem& it : items) keys.push_back(keys_[it.point * nic + it.ic]);
  return keys;
}

StatusOr<SweepPlan> SweepCoordinator::Submit(const SweepSpec& spec, long job_items) {
  std::lock_guard<std::mutex> lock(mu_);
  spec_ = spec;
  SweepPlan plan;
  plan.id = spec.Id();
  const int nic = spec.ic_count();
  plan.items_total = spec.points() * nic;
  auto existing = db_->GetSweep(plan.id);
  if (!existing.ok()) return existing.status();
  row_ = existing.value() ? *existing.value() : SweepRow{};
  if (row_.status == "done" && !row_.file.empty() &&
      std::filesystem::exists(std::filesystem::path(data_dir_) / row_.file)) {
    plan.already_published = true;
    plan.items_cached = plan.items_total;
    items_done_ = items_cached_ = plan.items_total;
    return plan;
  }
  std::vector<WorkItem> all;
  all.reserve(plan.items_total);
  keys_.clear();
  keys_.reserve(plan.items_total);
  for (long p = 0; p < spec.points(); ++p)
    for (int i = 0; i < nic; ++i) all.push_back({p, i}), keys_.push_back(spec.ItemKey(p, i));
  const std::vector<std::string>& keys = keys_;
  auto cached = db_->LookupPoints(keys, PointRecord::Size(spec.base.metrics.turning_points));
  if (!cached.ok()) return cached.status();
  std::vector<WorkItem> missing;
  for (size_t i = 0; i < all.size(); ++i)
    if (!cached->count(keys[i])) missing.push_back(all[i]);
  plan.items_cached = plan.items_total - static_cast<long>(missing.size());
  queue_.clear();
  if (spec.continuation.enabled()) {
    // Chains run whole and in order (each point starts where the previous ended): a chain with any
    // missing item is recomputed entirely; jobs hold whole chains.
    std::vector<bool> is_missing(all.size(), false);
    for (const WorkItem& w : missing) is_missing[w.point * nic + w.ic] = true;
    Job j;
    for (const auto& chain : spec.ContinuationChains()) {
      bool any = false;
      for (const WorkItem& w : chain) any |= is_missing[w.point * nic + w.ic];
      if (!any) continue;
      j.items.insert(j.items.end(), chain.begin(), chain.end());
      if (static_cast<long>(j.items.size()) >= job_items) {
        j.id = static_cast<long>(queue_.size());
        queue_.push_back(std::move(j));
        j = Job{};
      }
    }
    if (!j.items.empty()) j.id = static_cast<long>(queue_.size()), queue_.push_back(std::move(j));
    long queued = 0;
    for (const Job& q : queue_) queued += static_cast<long>(q.items.size());
    plan.items_cached = plan.items_total - queued;  // items of partly stored chains are recomputed
  } else {
    for (size_t start = 0; start < missing.size(); start += job_items) {
      Job j;
      j.id = static_cast<long>(queue_.size());
      j.items.assign(missing.begin() + start, missing.begin() + std::min(missing.size(), start + job_items));
      queue_.push_back(std::move(j));
    }
  }
  plan.jobs = static_cast<long>(queue_.size());
  reported_.assign(queue_.size(), false);
  next_job_ = 0;
  items_cached_ = items_done_ = plan.items_cached;
  stopped_ = false;
  started_ = Now();
  row_.id = plan.id;
  row_.name = spec.name;
  row_.model = spec.ModelLabel();
  row_.spec = spec.source;
  row_.status = "running";
  row_.points_total = plan.items_total;
  row_.points_done = items_done_;
  row_.file = "";
  if (row_.created == 0) row_.created = started_;
  row_.finished = 0;
  BISTABLE_RETURN_IF_ERROR(db_->UpsertSweep(row_));
  return plan;
}

std::optional<Job> SweepCoordinator::Lease() {
  std::lock_guard<std::mutex> lock(mu_);
  if (stopped_ || next_job_ >= queue_.size()) return std::nullopt;
  return queue_[next_job_++];
}

Status SweepCoordinator::Report(long job_id, const std::vector<PointRecord>& records) {
  std::lock_guard<std::mutex> lock(mu_);
  if (job_id < 0 || job_id >= static_cast<long>(queue_.size()))
    return Status::InvalidArgument("job", "job " + std::to_string(job_id) + " is not part of this sweep");
  if (reported_[job_id]) return Status::Ok();  // duplicate: acknowledged, not stored twice
  const Job& job = queue_[job_id];
  if (records.size() != job.items.size())
    return Status::InvalidArgument("records", "job " + std::to_string(job_id) + " has " + std::to_string(job.items.size()) +
                                                  " items, report has " + std::to_string(records.size()));
  const std::vector<std::string> keys = KeysFor(job.items);
  std::vector<std::pair<std::string, PointRecord>> rows;
  rows.reserve(keys.size());
  for (size_t i = 0; i < keys.size(); ++i) rows.emplace_back(keys[i], records[i]);
  BISTABLE_RETURN_IF_ERROR(db_->PutPoints(rows, row_.id, items_done_ + static_cast<long>(rows.size())));
  reported_[job_id] = true;
  items_done_ += static_cast<long>(rows.size());
  return Status::Ok();
}

StatusOr<std::string> SweepCoordinator::Publish() {
  std::lock_guard<std::mutex> lock(mu_);
  const std::string path = MapPath(row_.id);
  if (row_.status == "done" && !row_.file.empty() && std::filesystem::exists(path)) return path;
  const std::vector<std::string>& keys = keys_;
  auto found = db_->LookupPoints(keys, PointRecord::Size(spec_.base.metrics.turning_points));
  if (!found.ok()) return found.status();
  std::vector<PointRecord> records;
  records.reserve(keys.size());
  for (const std::string& k : keys) {
    auto it = found->find(k);
    if (it == found->end())
      return Status::FailedPrecondition("sweep " + row_.id + " is incomplete: " +
                                        std::to_string(keys.size() - found->size()) + " items are not stored yet");
    records.push_back(it->second);
  }
  BISTABLE_RETURN_IF_ERROR(WriteMapFile(path, spec_, records));
  SweepRow done = row_;
  done.status = "done";
  done.points_done = static_cast<long>(records.size());
  done.file = std::filesystem::relative(path, data_dir_).string();
  done.finished = Now();
  done.seconds = done.finished - started_;
  // Map rows: shape and range of every stored metric, for listings that need not open HDF5.
  std::string shape;
  for (const Axis& a : spec_.axes) shape += (shape.empty() ? "" : "x") + std::to_string(a.values.size());
  if (spec_.ic_count() > 1) shape += "x" + std::to_string(spec_.ic_count());
  std::vector<MapRow> maps;
  const auto& catalog = MetricCatalog();
  for (size_t mi = 0; mi < catalog.size(); ++mi) {
    if (std::find(spec_.metrics.begin(), spec_.metrics.end(), catalog[mi].name) == spec_.metrics.end()) continue;
    double lo = NAN, hi = NAN;
    for (const PointRecord& r : records) {
      const double v = r.Get(mi);
      if (!std::isfinite(v)) continue;
      lo = std::isnan(lo) ? v : std::min(lo, v);
      hi = std::isnan(hi) ? v : std::max(hi, v);
    }
    maps.push_back({done.id, catalog[mi].name, done.file, shape, lo, hi});
  }
  BISTABLE_RETURN_IF_ERROR(db_->PublishSweep(done, maps));
  row_ = done;
  return path;
}

Status SweepCoordinator::MarkInterrupted() {
  std::lock_guard<std::mutex> lock(mu_);
  row_.status = "interrupted";
  row_.points_done = items_done_;
  row_.seconds = Now() - started_;
  return db_->UpsertSweep(row_);
}

void SweepCoordinator::Stop() {
  std::lock_guard<std::mutex> lock(mu_);
  stopped_ = true;
}

SweepProgress SweepCoordinator::progress() const {
  std::lock_guard<std::mutex> lock(mu_);
  return {static_cast<long>(row_.points_total), items_done_, items_cached_};
}

}  // namespace bistable
