#include "server/sweep_coordinator.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "storage/map_file.h"

namespace bistable {
namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Items per job for about `seconds` of work on one core (≈ 15 M lane-steps/s with metrics),
// a multiple of 8 lanes, in [8, 4096].
long DefaultJobItems(const SweepSpec& spec, double seconds) {
  const double steps = spec.base.integration.t_end / spec.base.integration.dt;
  const double per_item = steps / 1.5e7 * (spec.UsesKernel() ? 1.0 : 8.0);
  long n = static_cast<long>(seconds / std::max(per_item, 1e-9));
  n = std::clamp<long>(n, 8, 4096);
  return (n / 8) * 8;
}

}  // namespace

StatusOr<std::unique_ptr<SweepCoordinator>> SweepCoordinator::Open(const std::string& data_dir, Options opt) {
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(data_dir) / "sweeps", ec);
  if (ec) return Status::IoError("data", "cannot create data directory '" + data_dir + "': " + ec.message());
  if (::access(data_dir.c_str(), W_OK) != 0)
    return Status::IoError("data", "data directory '" + data_dir + "' is not writable");
  auto db = IndexDb::Open((std::filesystem::path(data_dir) / "index.sqlite").string());
  if (!db.ok()) return db.status();
  std::unique_ptr<SweepCoordinator> c(new SweepCoordinator(data_dir, std::move(db.value()), opt));
  if (!opt.resume) return c;
  // Resume every unfinished sweep: plan it again against the point cache.
  auto rows = c->Db()->ListSweeps();
  if (!rows.ok()) return rows.status();
  std::vector<std::string> complete;
  std::unique_lock<std::mutex> lock(c->mu_);
  for (const SweepRow& r : *rows) {
    if (r.status != "running" && r.status != "interrupted" && r.status != "queued") continue;
    auto spec = ParseSweepSpec(r.spec, "sweep " + r.id);
    if (!spec.ok() || spec->Id() != r.id) {
      SweepRow failed = r;
      failed.status = "failed";
      c->Db()->UpsertSweep(failed);
      continue;
    }
    auto plan = c->SubmitLocked(*spec, DefaultJobItems(*spec, 2.0));
    if (!plan.ok()) return plan.status();
    if (plan->jobs == 0 && !plan->already_published) complete.push_back(plan->id);
  }
  lock.unlock();
  // Every item stored but no map (killed between the last report and the publication): publish now,
  // since no report will come to trigger it.
  for (const std::string& id : complete)
    if (auto path = c->Publish(id); !path.ok()) return path.status();
  return c;
}

std::string SweepCoordinator::MapPath(const std::string& id) const {
  return (std::filesystem::path(data_dir_) / "sweeps" / (id + ".h5")).string();
}

StatusOr<SweepPlan> SweepCoordinator::Submit(const SweepSpec& spec, long job_items) {
  std::unique_lock<std::mutex> lock(mu_);
  auto plan = SubmitLocked(spec, job_items);
  lock.unlock();
  if (plan.ok() && plan->jobs == 0 && !plan->already_published)  // everything cached: publish now
    if (auto path = Publish(plan->id); !path.ok()) return path.status();
  return plan;
}

StatusOr<SweepPlan> SweepCoordinator::SubmitLocked(const SweepSpec& spec, long job_items) {
  SweepPlan plan;
  plan.id = spec.Id();
  const int nic = spec.ic_count();
  plan.items_total = spec.points() * nic;
  if (auto it = sweeps_.find(plan.id); it != sweeps_.end() && !it->second.cancelled) {
    // Already active: report its current plan.
    plan.items_cached = it->second.items_cached;
    plan.jobs = static_cast<long>(it->second.jobs.size());
    plan.already_published = it->second.row.status == "done";
    return plan;
  }
  auto existing = Db()->GetSweep(plan.id);
  if (!existing.ok()) return existing.status();
  Sweep s;
  s.spec = spec;
  s.row = existing.value() ? *existing.value() : SweepRow{};
  s.seq = next_seq_++;
  if (s.row.status == "done" && !s.row.file.empty() && std::filesystem::exists(std::filesystem::path(data_dir_) / s.row.file)) {
    plan.already_published = true;
    plan.items_cached = plan.items_total;
    s.items_done = s.items_cached = plan.items_total;
    sweeps_[plan.id] = std::move(s);
    return plan;
  }
  std::vector<WorkItem> all;
  all.reserve(plan.items_total);
  s.keys.reserve(plan.items_total);
  for (long p = 0; p < spec.points(); ++p)
    for (int i = 0; i < nic; ++i) all.push_back({p, i}), s.keys.push_back(spec.ItemKey(p, i));
  auto cached = Db()->LookupPoints(s.keys, PointRecord::Size(spec.base.metrics.turning_points));
  if (!cached.ok()) return cached.status();
  std::vector<WorkItem> missing;
  for (size_t i = 0; i < all.size(); ++i)
    if (!cached->count(s.keys[i])) missing.push_back(all[i]);
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
        j.id = static_cast<long>(s.jobs.size());
        s.jobs.push_back(std::move(j));
        j = Job{};
      }
    }
    if (!j.items.empty()) j.id = static_cast<long>(s.jobs.size()), s.jobs.push_back(std::move(j));
  } else {
    for (size_t start = 0; start < missing.size(); start += job_items) {
      Job j;
      j.id = static_cast<long>(s.jobs.size());
      j.items.assign(missing.begin() + start, missing.begin() + std::min(missing.size(), start + job_items));
      s.jobs.push_back(std::move(j));
    }
  }
  long queued = 0;
  for (const Job& j : s.jobs) queued += static_cast<long>(j.items.size()), s.queue.push_back(j.id);
  s.job_state.assign(s.jobs.size(), JobState::kQueued);
  plan.items_cached = plan.items_total - queued;  // items of partly stored chains are recomputed
  plan.jobs = static_cast<long>(s.jobs.size());
  s.items_cached = s.items_done = plan.items_cached;
  s.started = Now();
  s.row.id = plan.id;
  s.row.name = spec.name;
  s.row.model = spec.ModelLabel();
  s.row.spec = spec.source;
  s.row.status = "running";
  s.row.points_total = plan.items_total;
  s.row.points_done = s.items_done;
  s.row.file = "";
  if (s.row.created == 0) s.row.created = s.started;
  s.row.finished = 0;
  BISTABLE_RETURN_IF_ERROR(Db()->UpsertSweep(s.row));
  stopped_ = false;
  sweeps_[plan.id] = std::move(s);
  return plan;
}

void SweepCoordinator::RequeueExpiredLocked(double now) {
  for (auto it = leases_.begin(); it != leases_.end();) {
    if (it->second.deadline >= now) {
      ++it;
      continue;
    }
    auto s = sweeps_.find(it->second.sweep_id);
    if (s != sweeps_.end() && s->second.job_state[it->second.job_id] == JobState::kLeased) {
      s->second.job_state[it->second.job_id] = JobState::kQueued;
      s->second.queue.push_front(it->second.job_id);
    }
    if (auto w = workers_.find(it->second.worker); w != workers_.end()) --w->second.leases;
    it = leases_.erase(it);
  }
}

std::optional<LeaseGrant> SweepCoordinator::Lease(const std::string& worker, const std::string& only_sweep) {
  std::lock_guard<std::mutex> lock(mu_);
  const double now = Now();
  WorkerInfo& w = workers_[worker];
  w.name = worker;
  w.last_seen = now;
  if (stopped_) return std::nullopt;
  RequeueExpiredLocked(now);
  Sweep* best = nullptr;
  for (auto& [id, s] : sweeps_)
    if (!s.cancelled && !s.queue.empty() && (!best || s.seq < best->seq) && (only_sweep.empty() || id == only_sweep)) best = &s;
  if (!best) return std::nullopt;
  const long job = best->queue.front();
  best->queue.pop_front();
  best->job_state[job] = JobState::kLeased;
  best->any_leased = true;
  char id[48];
  std::snprintf(id, sizeof id, "%s-%llu-%08x", best->row.id.c_str(), ++lease_counter_,
                static_cast<unsigned>(lease_salt_()));
  LeaseGrant g{id, best->row.id, job, best->jobs[job].items, now + opt_.lease_seconds};
  leases_[g.lease_id] = {g.sweep_id, worker, job, g.deadline};
  ++w.leases;
  return g;
}

Status SweepCoordinator::Extend(const std::string& lease_id) {
  std::lock_guard<std::mutex> lock(mu_);
  const double now = Now();
  auto it = leases_.find(lease_id);
  if (it == leases_.end())
    return finished_leases_.count(lease_id) ? Status::Ok() : Status::NotFound("lease '" + lease_id + "' is unknown");
  if (it->second.deadline < now) return Status::FailedPrecondition("lease '" + lease_id + "' expired; its job was requeued");
  it->second.deadline = now + opt_.lease_seconds;
  workers_[it->second.worker].last_seen = now;
  return Status::Ok();
}

unsigned long long SweepCoordinator::EnqueueResults(IndexDb::JobResults rows) {
  std::lock_guard<std::mutex> lock(batch_mu_);
  batch_.push_back(std::move(rows));
  return ++last_ticket_;
}

Status SweepCoordinator::AwaitCommit(unsigned long long ticket) {
  std::lock_guard<std::mutex> lock(db_mu_);
  if (ticket > committed_through_) {
    // Lead: store everything queued so far (this ticket and any that arrived while the previous
    // transaction ran) in one transaction.
    std::vector<IndexDb::JobResults> batch;
    unsigned long long last = 0;
    {
      std::lock_guard<std::mutex> b(batch_mu_);
      batch.swap(batch_);
      last = last_ticket_;
    }
    const Status st = db_->PutPoints(batch);
    if (!st.ok())
      for (unsigned long long t = committed_through_ + 1; t <= last; ++t) commit_failures_[t] = st;
    committed_through_ = last;
  }
  auto failed = commit_failures_.find(ticket);
  if (failed == commit_failures_.end()) return Status::Ok();
  Status st = failed->second;
  commit_failures_.erase(failed);
  return st;
}

Status SweepCoordinator::Report(const std::string& lease_id, const std::vector<PointRecord>& records) {
  IndexDb::JobResults rows;
  LeaseState lease;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const double now = Now();
    if (committing_.count(lease_id))  // a retry racing its own first attempt: answer once it is stored
      return Status::IoError("coordinator", "the report of lease '" + lease_id + "' is being stored; retry");
    auto it = leases_.find(lease_id);
    if (it == leases_.end()) {
      if (finished_leases_.count(lease_id)) return Status::Ok();  // a retried report: already stored
      return Status::NotFound("lease '" + lease_id + "' is unknown (never granted, or granted before a coordinator restart)");
    }
    if (it->second.deadline < now) {
      RequeueExpiredLocked(now);
      return Status::FailedPrecondition("lease '" + lease_id + "' expired before its report; its job was requeued");
    }
    auto sit = sweeps_.find(it->second.sweep_id);
    if (sit == sweeps_.end() || sit->second.cancelled) {
      leases_.erase(it);
      return Status::FailedPrecondition("sweep of lease '" + lease_id + "' was cancelled");
    }
    Sweep& s = sit->second;
    const Job& job = s.jobs[it->second.job_id];
    if (records.size() != job.items.size())
      return Status::InvalidArgument("records", "job has " + std::to_string(job.items.size()) + " items, report has " +
                                                    std::to_string(records.size()));
    const size_t width = PointRecord::Size(s.spec.base.metrics.turning_points);
    for (size_t i = 0; i < records.size(); ++i)
      if (records[i].v.size() != width)
        return Status::InvalidArgument("records", "record " + std::to_string(i) + " has " + std::to_string(records[i].v.size()) +
                                                      " values, the sweep's layout has " + std::to_string(width));
    lease = it->second;
    leases_.erase(it);
    if (s.job_state[lease.job_id] == JobState::kDone) {  // another lease of this job was stored first
      if (auto w = workers_.find(lease.worker); w != workers_.end()) --w->second.leases, w->second.last_seen = now;
      finished_leases_[lease_id] = s.row.id;
      return Status::Ok();
    }
    const int nic = s.spec.ic_count();
    rows.sweep_id = s.row.id;
    rows.items.reserve(records.size());
    for (size_t i = 0; i < records.size(); ++i)
      rows.items.emplace_back(s.keys[job.items[i].point * nic + job.items[i].ic], records[i]);
    committing_[lease_id] = lease;  // not in leases_ while stored: it cannot expire or be requeued meanwhile
  }
  const long n = static_cast<long>(rows.items.size());
  const Status stored = AwaitCommit(EnqueueResults(std::move(rows)));  // without mu_: reports batch up here
  std::lock_guard<std::mutex> lock(mu_);
  committing_.erase(lease_id);
  if (!stored.ok()) {
    leases_[lease_id] = lease;  // nothing stored: the worker may retry while the lease lasts
    return stored;
  }
  const double now = Now();
  if (auto w = workers_.find(lease.worker); w != workers_.end()) --w->second.leases, w->second.last_seen = now;
  auto sit = sweeps_.find(lease.sweep_id);
  if (sit == sweeps_.end()) return Status::Ok();
  Sweep& s = sit->second;
  finished_leases_[lease_id] = s.row.id;
  if (s.job_state[lease.job_id] != JobState::kDone) {  // two leases of one job stored at once count once
    s.job_state[lease.job_id] = JobState::kDone;
    s.items_done += n;
    workers_[lease.worker].items_done += n;
  }
  if (s.items_done >= s.row.points_total && s.row.status != "done" && !s.cancelled) {
    // Publish off the report path: the report is acknowledged once its rows are durable, and the
    // map (seconds of HDF5 writing for a large grid) is written by the publisher thread.
    std::lock_guard<std::mutex> p(publish_queue_mu_);
    publish_queue_.push_back(s.row.id);
    publish_cv_.notify_one();
  }
  return Status::Ok();
}

void SweepCoordinator::PublisherLoop() {
  while (true) {
    std::string id;
    {
      std::unique_lock<std::mutex> lock(publish_queue_mu_);
      publish_cv_.wait(lock, [&] { return closing_ || !publish_queue_.empty(); });
      if (publish_queue_.empty()) return;  // closing, nothing left
      id = publish_queue_.front();
      publish_queue_.pop_front();
    }
    auto path = Publish(id);
    if (!path.ok()) std::fprintf(stderr, "coordinator: publishing sweep %s failed: %s\n", id.c_str(), path.status().ToString().c_str());
  }
}

SweepCoordinator::~SweepCoordinator() {
  {
    std::lock_guard<std::mutex> lock(publish_queue_mu_);
    closing_ = true;
  }
  publish_cv_.notify_all();
  if (publisher_.joinable()) publisher_.join();  // finishes queued publications first
}

Status SweepCoordinator::Release(const std::string& lease_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = leases_.find(lease_id);
  if (it == leases_.end()) return Status::NotFound("lease '" + lease_id + "' is unknown");
  auto s = sweeps_.find(it->second.sweep_id);
  if (s != sweeps_.end() && s->second.job_state[it->second.job_id] == JobState::kLeased) {
    s->second.job_state[it->second.job_id] = JobState::kQueued;
    s->second.queue.push_front(it->second.job_id);
  }
  if (auto w = workers_.find(it->second.worker); w != workers_.end()) --w->second.leases;
  leases_.erase(it);
  return Status::Ok();
}

Status SweepCoordinator::Cancel(const std::string& sweep_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) return Status::NotFound("no active sweep '" + sweep_id + "'");
  if (it->second.row.status == "done") return Status::FailedPrecondition("sweep '" + sweep_id + "' is already done");
  it->second.cancelled = true;
  it->second.queue.clear();
  return MarkLocked(it->second, "cancelled");
}

StatusOr<std::string> SweepCoordinator::Publish(const std::string& sweep_id) {
  // One publication at a time; the coordinator's lock is held only to read the sweep and to record
  // the outcome, so leases and reports of other sweeps go on while the map is gathered and written.
  std::lock_guard<std::mutex> one(publish_mu_);
  SweepSpec spec;
  std::vector<std::string> keys;
  SweepRow row;
  double started = 0;
  const std::string path = MapPath(sweep_id);
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = sweeps_.find(sweep_id);
    if (it == sweeps_.end()) return Status::NotFound("no active sweep '" + sweep_id + "'");
    const Sweep& s = it->second;
    if (s.row.status == "done" && !s.row.file.empty() && std::filesystem::exists(path)) return path;
    spec = s.spec;
    keys = s.keys;
    row = s.row;
    started = s.started;
  }
  auto published = WriteAndIndexMap(spec, keys, row, started, path);
  std::lock_guard<std::mutex> lock(mu_);
  Sweep& s = sweeps_.at(sweep_id);
  if (!published.ok()) {
    // A write failure (disk full, unwritable dir) fails the sweep; an incomplete one stays as it is.
    if (published.status().code() == Status::Code::kIoError && s.row.status != "cancelled") MarkLocked(s, "failed");
    return published.status();
  }
  s.row = *published;
  final_cv_.notify_all();
  return path;
}

StatusOr<SweepRow> SweepCoordinator::WriteAndIndexMap(const SweepSpec& spec, const std::vector<std::string>& keys,
                                                      const SweepRow& row, double started, const std::string& path) {
  auto found = Db()->LookupPoints(keys, PointRecord::Size(spec.base.metrics.turning_points));
  if (!found.ok()) return found.status();
  std::vector<PointRecord> records;
  records.reserve(keys.size());
  for (const std::string& k : keys) {
    auto it = found->find(k);
    if (it == found->end())
      return Status::FailedPrecondition("sweep " + row.id + " is incomplete: " +
                                        std::to_string(keys.size() - found->size()) + " items are not stored yet");
    records.push_back(it->second);
  }
  BISTABLE_RETURN_IF_ERROR(WriteMapFile(path, spec, records));
  SweepRow done = row;
  done.status = "done";
  done.points_done = static_cast<long>(records.size());
  done.file = std::filesystem::relative(path, data_dir_).string();
  done.finished = Now();
  done.seconds = done.finished - started;
  // Map rows: shape and range of every stored metric, for listings that need not open HDF5.
  std::string shape;
  for (const Axis& a : spec.axes) shape += (shape.empty() ? "" : "x") + std::to_string(a.values.size());
  if (spec.ic_count() > 1) shape += "x" + std::to_string(spec.ic_count());
  std::vector<MapRow> maps;
  const auto& catalog = MetricCatalog();
  for (size_t mi = 0; mi < catalog.size(); ++mi) {
    if (std::find(spec.metrics.begin(), spec.metrics.end(), catalog[mi].name) == spec.metrics.end()) continue;
    double lo = NAN, hi = NAN;
    for (const PointRecord& r : records) {
      const double v = r.Get(mi);
      if (!std::isfinite(v)) continue;
      lo = std::isnan(lo) ? v : std::min(lo, v);
      hi = std::isnan(hi) ? v : std::max(hi, v);
    }
    maps.push_back({done.id, catalog[mi].name, done.file, shape, lo, hi});
  }
  BISTABLE_RETURN_IF_ERROR(Db()->PublishSweep(done, maps));
  return done;
}

Status SweepCoordinator::MarkLocked(Sweep& s, const std::string& status) {
  s.row.status = status;
  final_cv_.notify_all();
  s.row.points_done = s.items_done;
  s.row.seconds = Now() - s.started;
  return Db()->UpsertSweep(s.row);
}

Status SweepCoordinator::MarkInterrupted(const std::string& sweep_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) return Status::NotFound("no active sweep '" + sweep_id + "'");
  return MarkLocked(it->second, "interrupted");
}

void SweepCoordinator::Stop() {
  std::lock_guard<std::mutex> lock(mu_);
  stopped_ = true;
}

StatusOr<SweepInfo> SweepCoordinator::Info(const std::string& sweep_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) {
    auto row = Db()->GetSweep(sweep_id);
    if (!row.ok()) return row.status();
    if (!row.value()) return Status::NotFound("no sweep '" + sweep_id + "'");
    const SweepRow& r = *row.value();
    return SweepInfo{r.id, r.name, r.model, r.status, r.points_total, r.points_done, 0, 0, r.seconds, r.file};
  }
  const Sweep& s = it->second;
  SweepInfo info{s.row.id, s.row.name, s.row.model, s.row.status, s.row.points_total, s.items_done, s.items_cached, 0,
                 s.row.status == "done" ? s.row.seconds : Now() - s.started, s.row.file};
  if (info.state == "running" && !s.any_leased && s.items_done == s.items_cached) info.state = "queued";
  if (s.cancelled) info.state = "cancelled";
  std::map<std::string, bool> holders;
  for (const auto& [id, l] : leases_)
    if (l.sweep_id == s.row.id) holders[l.worker] = true;
  info.workers = static_cast<int>(holders.size());
  return info;
}

StatusOr<SweepInfo> SweepCoordinator::AwaitFinal(const std::string& sweep_id, double seconds) const {
  {
    std::unique_lock<std::mutex> lock(mu_);
    final_cv_.wait_for(lock, std::chrono::duration<double>(seconds), [&] {
      auto it = sweeps_.find(sweep_id);
      return it == sweeps_.end() || it->second.cancelled || it->second.row.status == "done" || it->second.row.status == "failed";
    });
  }
  return Info(sweep_id);
}

std::vector<WorkerInfo> SweepCoordinator::Workers() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<WorkerInfo> out;
  for (const auto& [name, w] : workers_) out.push_back(w);
  return out;
}

StatusOr<std::string> SweepCoordinator::SpecText(const std::string& sweep_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) return Status::NotFound("no active sweep '" + sweep_id + "'");
  return it->second.spec.source;
}

SweepProgress SweepCoordinator::progress(const std::string& sweep_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) return {};
  return {it->second.row.points_total, it->second.items_done, it->second.items_cached};
}

}  // namespace bistable
