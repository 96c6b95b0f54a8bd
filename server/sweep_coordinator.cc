#include "server/sweep_coordinator.h"

#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <limits>

#include "base/file.h"
#include "base/limits.h"
#include "base/log.h"
#include "base/sha256.h"
#include "engine/evaluate.h"
#include "engine/sweep_kind.h"
#include "storage/data_dir.h"

namespace bistable {
namespace {

double Now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

double SteadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

void SweepCoordinator::Log(log::Level level, std::string_view event, std::initializer_list<log::Field> fields) const {
  if (opt_.log) log::Event(level, event, fields);
}

void SweepCoordinator::Repaired(std::string_view event, const std::string& message) const {
  Log(log::Level::kWarn, event, {{"message", message}});
  if (opt_.warn) opt_.warn(message);
}

void SweepCoordinator::ChecksumFailed(const std::string& sweep, long items, const char* action) const {
  Log(log::Level::kWarn, "sweep.checksum_failed", {{"sweep", sweep}, {"items", items}, {"action", action}});
  if (opt_.warn)
    opt_.warn(std::to_string(items) + " stored results of sweep " + sweep + " failed their checksum in '" +
              (std::filesystem::path(data_dir_) / "index.sqlite").string() + "': computed again");
}

SweepCoordinator::SweepCoordinator(std::string dir, std::unique_ptr<IndexDb> db, Options opt)
    : data_dir_(std::move(dir)),
      opt_(std::move(opt)),
      // Checkpoints off the report path (measured: docs/scaling.md): a second connection checkpoints in the
      // background; the writer's own automatic checkpoint stays as a safety net at ~400 MB of WAL.
      writer_(std::make_unique<ResultWriter>(
          std::move(db), (std::filesystem::path(data_dir_) / "index.sqlite").string(), ResultWriter::Options{})),
      leases_([this] { return Monotonic(); }, opt_.lease_seconds),
      publisher_(std::make_unique<Publisher>(
          [this](const std::string& id) { return PublishStep(id); },
          [this](const std::string& id, const Status& st) {
            Log(log::Level::kError, "sweep.publish_failed", {{"sweep", id}, {"reason", st.ToString()}});
          })) {}

SweepCoordinator::~SweepCoordinator() {
  publisher_->Close();  // finishes queued publications first, while every part it uses is still here
}

double SweepCoordinator::Clock() const { return opt_.clock ? opt_.clock() : Now(); }

double SweepCoordinator::Monotonic() const {
  return opt_.monotonic ? opt_.monotonic() : opt_.clock ? opt_.clock() : SteadyNow();
}

StatusOr<std::unique_ptr<SweepCoordinator>> SweepCoordinator::Open(const std::string& data_dir, Options opt) {
  // Results are the owner's (and a group's): the directory and sweeps/ are created 0750, the index and the
  // maps 0640 (docs/operations.md, "One data directory"); a directory that exists keeps its mode.
  BISTABLE_RETURN_IF_ERROR(MakeDirectory(data_dir, kDataDirectoryMode, "data"));
  BISTABLE_RETURN_IF_ERROR(
      MakeDirectory((std::filesystem::path(data_dir) / "sweeps").string(), kDataDirectoryMode, "data"));
  if (::access(data_dir.c_str(), W_OK) != 0)
    return Status::IoError("data", "data directory '" + data_dir + "' is not writable");
  std::vector<std::string> repairs;
  auto db = OpenDataIndex(data_dir, &repairs);
  if (!db.ok()) return db.status();
  std::unique_ptr<SweepCoordinator> c(new SweepCoordinator(data_dir, std::move(db.value()), opt));
  for (const std::string& r : repairs) c->Repaired("data.repaired", r);
  if (!opt.resume) return c;
  // Resume every unfinished sweep: plan it again against the point cache.
  auto rows = c->Db()->ListSweeps();
  if (!rows.ok()) return rows.status();
  // A sweep stored everything but has no map (killed between the last report and the publication)
  // is published by Submit, since no report will come to trigger it.
  for (const SweepRow& r : *rows) {
    if (r.state != SweepState::kRunning && r.state != SweepState::kInterrupted && r.state != SweepState::kQueued)
      continue;
    auto spec = ParseSweepSpec(r.spec, "sweep " + r.id);
    if (!spec.ok() || spec->Id() != r.id) {
      SweepRow failed = r;
      failed.state = SweepState::kFailed;
      c->Db()->UpsertSweep(failed);
      continue;
    }
    // Accepted before the restart: resumed beyond the active-sweep limits (which only stop new submits).
    auto plan = c->SubmitImpl(*spec, JobItems(*spec, 2.0, 64), r.owner.empty() ? "local" : r.owner, /*limits=*/false);
    if (!plan.ok()) {
      c->Log(log::Level::kError, "sweep.resume_failed", {{"sweep", r.id}, {"reason", plan.status().ToString()}});
      SweepRow failed = r;
      failed.state = SweepState::kFailed;
      c->Db()->UpsertSweep(failed);
    }
  }
  return c;
}

std::string SweepCoordinator::MapPath(const std::string& id) const {
  return (std::filesystem::path(data_dir_) / "sweeps" / (id + ".h5")).string();
}

std::optional<SweepPlan> SweepCoordinator::ActivePlanLocked(const std::string& id) const {
  auto it = sweeps_.find(id);
  if (it == sweeps_.end() || it->second.cancelled || it->second.row.state == SweepState::kFailed) return std::nullopt;
  SweepPlan plan;
  plan.id = id;
  plan.items_total = it->second.row.items_total;
  plan.items_cached = it->second.plan.items_cached();
  plan.jobs = it->second.plan.jobs();
  plan.already_published = it->second.row.state == SweepState::kDone;
  return plan;
}

StatusOr<SweepPlan> SweepCoordinator::SubmitImpl(const SweepSpec& spec, long job_items, const std::string& owner,
                                                 bool enforce_limits) {
  const std::string id = spec.Id();
  const long items = std::clamp<long>(job_items, 1, limits::kMaxJobItems);
  {
    std::unique_lock<std::mutex> lock(mu_);
    // One planning per sweep at a time: a concurrent submit of the same spec waits for it.
    plan_cv_.wait(lock, [&] { return !planning_.count(id); });
    if (auto active = ActivePlanLocked(id)) return *active;
    // Sweeps installed and sweeps being planned (outside the lock) both count: the slot is reserved
    // here, under mu_, before planning starts, and given back if the plan fails (issue 39: ten
    // concurrent submits of one token were all accepted while the first ones were still planning).
    int mine = 0, all = 0;
    for (const auto& [sid, s] : sweeps_) {
      if (s.cancelled || s.row.state == SweepState::kDone || s.row.state == SweepState::kFailed) continue;
      ++all;
      if (s.row.owner == owner) ++mine;
    }
    for (const auto& [pid, p] : planning_) {
      if (!p.reserves_slot) continue;  // a replan: its sweep is counted above
      ++all;
      if (p.owner == owner) ++mine;
    }
    if (enforce_limits && mine >= limits::kMaxActiveSweepsPerOwner)
      return Status::FailedPrecondition("'" + owner + "' has " + std::to_string(mine) +
                                        " sweeps queued, running or being planned, the limit per owner is " +
                                        std::to_string(limits::kMaxActiveSweepsPerOwner) +
                                        "; wait for one or cancel one");
    if (enforce_limits && all >= limits::kMaxActiveSweeps)
      return Status::FailedPrecondition("the coordinator holds " + std::to_string(all) +
                                        " sweeps queued, running or being planned, its limit is " +
                                        std::to_string(limits::kMaxActiveSweeps));
    planning_[id] = Planning{owner, true};
  }
  const auto plan_start = std::chrono::steady_clock::now();
  auto built = BuildPlan(spec, items);  // outside mu_: leases, reports and status calls go on
  std::unique_lock<std::mutex> lock(mu_);
  planning_.erase(id);
  plan_cv_.notify_all();
  if (!built.ok()) return built.status();
  built.value().sweep.job_items = items;
  auto plan = InstallLocked(std::move(*built), owner);
  lock.unlock();
  if (plan.ok())
    Log(log::Level::kInfo, "sweep.planned",
        {{"sweep", plan->id},
         {"name", spec.name},
         {"owner", owner},
         {"items", plan->items_total},
         {"cached", plan->items_cached},
         {"jobs", plan->jobs},
         {"published", plan->already_published},
         {"plan_ms",
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - plan_start).count()}});
  if (plan.ok() && plan->jobs == 0 && !plan->already_published)  // everything cached: publish now
    if (auto path = Publish(plan->id); !path.ok()) return path.status();
  return plan;
}

StatusOr<SweepCoordinator::Planned> SweepCoordinator::BuildPlan(const SweepSpec& spec, long job_items,
                                                                RefineCarry carry) {
  Planned out;
  SweepPlan& plan = out.plan;
  Sweep& s = out.sweep;
  plan.id = spec.Id();
  auto existing = Db()->GetSweep(plan.id);
  if (!existing.ok()) return existing.status();
  s.spec = spec;
  s.spec_key = Sha256Hex(spec.source);
  s.row = existing.value() && existing.value()->id == plan.id ? *existing.value() : SweepRow{};
  if (s.row.state == SweepState::kDone && !s.row.file.empty() &&
      std::filesystem::exists(std::filesystem::path(data_dir_) / s.row.file)) {
    // Published: served as it is if the file is whole. A damaged one (truncated, overwritten) is moved aside
    // and the sweep planned again: its stored points go into a new map, the rest are computed.
    const std::string file = (std::filesystem::path(data_dir_) / s.row.file).string();
    Status whole = CheckMapFile(file, plan.id);
    if (whole.ok()) {
      long total = 0;
      if (__builtin_mul_overflow(spec.points(), static_cast<long>(spec.ic_count()), &total))
        return Status::InvalidArgument("axes", "points x initial conditions overflows");
      plan.already_published = true;
      plan.items_total = plan.items_cached = total;
      s.plan = JobPlan::Published(total);
      return out;
    }
    auto aside = MoveAside(file);
    if (!aside.ok()) return aside.status();
    Repaired("map.corrupt", whole.message() + ": moved aside to '" + *aside + "'; sweep " + plan.id +
                                " is planned again and its map written anew");
    s.row.state = SweepState::kQueued;
    s.row.file.clear();
  }
  // The plan looks its keys up in batches, each under the index lock on its own, so reports of other
  // sweeps commit in between.
  const size_t width = PointRecord::Size(spec.base.metrics.turning_points, spec.base.metrics.poincare_points);
  long corrupt_total = 0;
  auto built = JobPlan::Build(
      spec, job_items,
      [&](const std::vector<std::string>& keys) {
        long corrupt = 0;
        auto found = Db()->LookupPoints(keys, width, &corrupt);
        corrupt_total += corrupt;
        return found;
      },
      std::move(carry));
  if (!built.ok()) return built.status();
  if (corrupt_total > 0) ChecksumFailed(plan.id, corrupt_total, "recompute");
  s.plan = std::move(built).value();
  plan.items_total = s.plan.items_total();
  plan.items_cached = s.plan.items_cached();
  plan.jobs = s.plan.jobs();
  return out;
}

StatusOr<SweepPlan> SweepCoordinator::InstallLocked(Planned p, const std::string& owner) {
  Sweep& s = p.sweep;
  const SweepPlan& plan = p.plan;
  s.seq = next_seq_++;
  s.generation = ++generation_counter_;
  RevokeLeasesLocked(plan.id);  // leases of an earlier plan of this sweep are void
  if (plan.already_published) {
    sweeps_[plan.id] = std::move(s);
    return plan;
  }
  // A plan that replaces a running plan of the sweep (a refinement round, a replan) keeps its start time.
  auto prev = sweeps_.find(plan.id);
  s.started = prev != sweeps_.end() && !prev->second.cancelled && prev->second.row.state == SweepState::kRunning &&
                      prev->second.started > 0
                  ? prev->second.started
                  : Clock();
  s.row.id = plan.id;
  s.row.name = s.spec.name;
  s.row.model = s.spec.ModelLabel();
  s.row.spec = s.spec.source;
  s.row.state = SweepState::kRunning;
  s.row.items_total = plan.items_total;
  s.row.items_done = s.plan.items_done();
  s.row.file = "";
  s.row.owner = owner;
  if (s.row.created == 0) s.row.created = s.started;
  s.row.finished = 0;
  BISTABLE_RETURN_IF_ERROR(Db()->UpsertSweep(s.row));
  stopped_ = false;
  sweeps_[plan.id] = std::move(s);
  return plan;
}

Status SweepCoordinator::Replan(const std::string& id) {
  SweepSpec spec;
  std::string owner;
  unsigned long long generation = 0;
  long job_items = 0;
  RefineCarry carry;
  {
    std::unique_lock<std::mutex> lock(mu_);
    plan_cv_.wait(lock, [&] { return !planning_.count(id); });  // one planning per sweep at a time
    auto it = sweeps_.find(id);
    if (it == sweeps_.end() || it->second.cancelled) return Status::Ok();
    spec = it->second.spec;
    owner = it->second.row.owner;
    job_items = it->second.job_items;
    carry = it->second.plan.Carry();  // a refined sweep continues its walk: only the new round is looked up
    generation = it->second.generation = ++generation_counter_;  // reports of the old plan store, but count nowhere
    it->second.plan.ClearQueue();                                // and nothing is leased while the new one is built
    RevokeLeasesLocked(id);
    planning_[id] = Planning{owner, false};
  }
  auto built = BuildPlan(spec, job_items > 0 ? job_items : JobItems(spec, 2.0, 64), std::move(carry));
  std::unique_lock<std::mutex> lock(mu_);
  planning_.erase(id);
  plan_cv_.notify_all();
  if (!built.ok()) return built.status();
  // Cancelled, interrupted or planned again while this plan was built (outside the lock): the newer
  // decision stands and this plan is dropped (installing it would bring a cancelled sweep back).
  if (auto it = sweeps_.find(id); it == sweeps_.end() || it->second.cancelled || it->second.generation != generation ||
                                  it->second.row.state == SweepState::kInterrupted ||
                                  it->second.row.state == SweepState::kFailed)
    return Status::Ok();
  built.value().sweep.job_items = job_items;
  auto plan = InstallLocked(std::move(*built), owner);
  if (!plan.ok()) return plan.status();
  const JobPlan& installed = sweeps_.at(id).plan;
  if (KindOf(spec).InRounds())
    Log(log::Level::kInfo, "sweep.refined",
        {{"sweep", id},
         {"round", installed.refine_round()},
         {"items", plan->items_total - plan->items_cached},
         {"planned", plan->items_total},
         {"complete", installed.refine_complete()}});
  else
    Log(log::Level::kInfo, "sweep.replanned", {{"sweep", id}, {"items", plan->items_total - plan->items_cached}});
  if (plan->jobs == 0) publisher_->Post(id);
  return Status::Ok();
}

void SweepCoordinator::RevokeLeasesLocked(const std::string& sweep_id) {
  for (const LeaseState& l : leases_.Revoke(sweep_id)) LeaseEndedLocked(l.worker);
}

void SweepCoordinator::FreePlan(Sweep& s) {
  s.plan.Free();
  ::malloc_trim(0);  // a cancelled 4 M-item plan is hundreds of MB: give them back
}

void SweepCoordinator::TouchWorkerLocked(const std::string& worker, double now) {
  auto it = workers_.find(worker);
  if (it == workers_.end()) {
    if (workers_.size() >= limits::kMaxWorkers) {
      // Forget the longest-idle worker without leases; if every one holds a lease, do not record this one.
      auto oldest = workers_.end();
      for (auto w = workers_.begin(); w != workers_.end(); ++w)
        if (w->second.leases == 0 && (oldest == workers_.end() || w->second.last_seen < oldest->second.last_seen))
          oldest = w;
      if (oldest == workers_.end()) return;
      workers_.erase(oldest);
    }
    it = workers_.emplace(worker, WorkerInfo{}).first;
    it->second.name = worker;
    Log(log::Level::kInfo, "worker.joined", {{"worker", worker}, {"workers", workers_.size()}});
  }
  it->second.last_seen = now;
}

void SweepCoordinator::LeaseEndedLocked(const std::string& worker) {
  if (auto w = workers_.find(worker); w != workers_.end() && w->second.leases > 0) --w->second.leases;
}

void SweepCoordinator::RequeueExpiredLocked() {
  const double mono = leases_.Now();
  for (const LeaseState& l : leases_.TakeExpired()) {
    ++stats_.leases_expired;
    Log(log::Level::kWarn, "lease.expired",
        {{"sweep", l.sweep_id},
         {"job", l.job_ids.front()},
         {"jobs", l.job_ids.size()},
         {"worker", l.worker},
         {"overdue_s", mono - l.deadline},
         {"action", "requeue"}});
    RequeueLocked(l);
    if (auto w = workers_.find(l.worker); w != workers_.end() && w->second.leases == 0)
      Log(log::Level::kWarn, "worker.lost", {{"worker", l.worker}, {"last_seen_s", Clock() - w->second.last_seen}});
  }
}

void SweepCoordinator::RequeueLocked(const LeaseState& l) {
  auto s = sweeps_.find(l.sweep_id);
  if (s != sweeps_.end() && !s->second.cancelled && s->second.generation == l.generation)
    s->second.plan.Requeue(l.job_ids);
  LeaseEndedLocked(l.worker);
}

std::optional<LeaseGrant> SweepCoordinator::Lease(const std::string& worker, const std::string& only_sweep,
                                                  int max_jobs, const std::string& identity) {
  std::lock_guard<std::mutex> lock(mu_);
  const double now = Clock();
  TouchWorkerLocked(worker, now);
  if (stopped_) return std::nullopt;
  RequeueExpiredLocked();
  Sweep* best = nullptr;
  for (auto& [id, s] : sweeps_)
    if (!s.cancelled && s.plan.queued() > 0 && (!best || s.seq < best->seq) && (only_sweep.empty() || id == only_sweep))
      best = &s;
  if (!best) return std::nullopt;
  std::vector<long> jobs = best->plan.Take(max_jobs, limits::kMaxJobItems);
  best->any_leased = true;
  LeaseGrant g{"", best->row.id, best->spec_key, jobs[0], static_cast<int>(jobs.size()), best->plan.ItemsFor(jobs), 0};
  g.lease_id = leases_.Grant({g.sweep_id, worker, identity, jobs, best->generation, 0});
  g.deadline = now + opt_.lease_seconds;  // the wire's wall time; the table keeps its own on the monotonic clock
  if (auto w = workers_.find(worker); w != workers_.end()) ++w->second.leases;
  ++stats_.leases_granted;
  Log(log::Level::kDebug, "lease.granted",
      {{"sweep", g.sweep_id}, {"job", g.job_id}, {"jobs", g.jobs}, {"worker", worker}, {"items", g.items.size()}});
  return g;
}

Status SweepCoordinator::Extend(const std::string& lease_id, const std::string& identity) {
  std::lock_guard<std::mutex> lock(mu_);
  BISTABLE_RETURN_IF_ERROR(leases_.Extend(lease_id, identity));
  if (const LeaseState* l = leases_.Find(lease_id)) TouchWorkerLocked(l->worker, Clock());
  return Status::Ok();
}

Status SweepCoordinator::Report(const std::string& lease_id, const std::vector<PointRecord>& records,
                                const std::string& identity) {
  const size_t width = records.empty() ? 0 : records[0].v.size();
  std::vector<double> flat;
  flat.reserve(records.size() * width);
  for (const PointRecord& r : records) {
    if (r.v.size() != width)
      return Status::InvalidArgument("records", "records of different widths (" + std::to_string(r.v.size()) + " and " +
                                                    std::to_string(width) + ")");
    flat.insert(flat.end(), r.v.begin(), r.v.end());
  }
  return Report(lease_id, width, flat.data(), flat.size(), identity);
}

namespace {
Status NotTheLeaseHolder() {
  return Status::PermissionDenied(
      "the lease was granted to another identity (token): only its holder may extend, report or release it");
}
}  // namespace

Status SweepCoordinator::Report(const std::string& lease_id, size_t width, const double* values, size_t n_values,
                                const std::string& identity) {
  // The record layout is checked first, without the lock: the width must be that of some layout
  // and every value in its metric's domain (forged or corrupt numbers never reach the cache). The
  // sweep's exact layout (turning points, section points) is compared under the lock below.
  BISTABLE_RETURN_IF_ERROR(CheckAnyRecordWidth(width));
  if (n_values % width != 0)
    return Status::InvalidArgument(
        "values", std::to_string(n_values) + " values do not split into records of width " + std::to_string(width));
  const size_t n_records = n_values / width;
  // Every value's domain, and the one copy of the values, outside the coordinator's lock: concurrent
  // reports check and copy in parallel; under the lock only the lease and the keys are looked at.
  for (size_t i = 0; i < n_records; ++i)
    if (Status st = CheckAnyRecord(values + i * width, width); !st.ok())
      return Status::InvalidArgument("values", "record " + std::to_string(i) + ": " + st.message());
  IndexDb::JobResults rows;
  rows.width = width;
  rows.values.assign(values, values + n_values);
  LeaseState lease;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (leases_.Committing(lease_id))  // a retry racing its own first attempt: answer once it is stored
      return Status::IoError("coordinator", "the report of lease '" + lease_id + "' is being stored; retry");
    const LeaseState* l = leases_.Find(lease_id);
    if (!l) {
      if (leases_.Finished(lease_id)) {  // a retried report: already stored
        ++stats_.reports_duplicate;
        return Status::Ok();
      }
      return Status::NotFound(
          "lease is unknown (never granted, revoked by a cancel or a new plan, or granted before a "
          "coordinator restart)");
    }
    // One worker token cannot report (in-range, forged) values for another's job: they would serve every
    // later sweep through the content cache (issue 39).
    if (l->identity != identity) return NotTheLeaseHolder();
    if (leases_.Expired(*l)) {
      RequeueExpiredLocked();
      return Status::FailedPrecondition("lease '" + lease_id + "' expired before its report; its job was requeued");
    }
    auto sit = sweeps_.find(l->sweep_id);
    if (sit == sweeps_.end() || sit->second.cancelled || sit->second.generation != l->generation ||
        !sit->second.plan.Holds(l->job_ids)) {
      LeaseEndedLocked(l->worker);
      leases_.Take(lease_id);
      return Status::FailedPrecondition("lease '" + lease_id +
                                        "' belongs to a cancelled or replaced plan of its sweep");
    }
    Sweep& s = sit->second;
    const size_t lease_items = static_cast<size_t>(s.plan.ItemsOf(l->job_ids));
    if (n_records != lease_items)
      return Status::InvalidArgument("values", "the lease's job has " + std::to_string(lease_items) +
                                                   " items, the report has " + std::to_string(n_records) + " records");
    const size_t expected = PointRecord::Size(s.spec.base.metrics.turning_points, s.spec.base.metrics.poincare_points);
    if (width != expected)
      return Status::InvalidArgument("record_width", "record_width = " + std::to_string(width) +
                                                         " violates record_width = " + std::to_string(expected) +
                                                         " (this sweep's layout)");
    lease = *leases_.Take(lease_id);
    if (s.plan.AllDone(lease.job_ids)) {  // other leases of these jobs were stored first
      ++stats_.reports_duplicate;
      LeaseEndedLocked(lease.worker);
      TouchWorkerLocked(lease.worker, Clock());
      leases_.Finish(lease_id, s.row.id);
      return Status::Ok();
    }
    rows.sweep_id = s.row.id;
    rows.keys = s.plan.KeysFor(lease.job_ids);
    leases_.BeginCommit(lease_id, lease);  // not active while stored: it cannot expire or be requeued meanwhile
  }
  const long n = static_cast<long>(n_records);
  const auto store_start = std::chrono::steady_clock::now();
  const Status stored = writer_->Commit(std::move(rows));  // without mu_: reports batch up here
  const double store_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - store_start).count();
  std::lock_guard<std::mutex> lock(mu_);
  auto sit = sweeps_.find(lease.sweep_id);
  const bool current = sit != sweeps_.end() && !sit->second.cancelled && sit->second.generation == lease.generation;
  if (!stored.ok()) {
    // Nothing stored: the worker may retry while the lease lasts (if its plan is still current).
    leases_.EndCommit(lease_id, /*restore=*/current);
    ++stats_.reports_failed;
    Log(log::Level::kError, "report.store_failed",
        {{"sweep", lease.sweep_id},
         {"job", lease.job_ids.front()},
         {"worker", lease.worker},
         {"reason", stored.ToString()}});
    if (sit != sweeps_.end()) sit->second.error = "storing results failed: " + stored.ToString();
    return stored;
  }
  leases_.EndCommit(lease_id, /*restore=*/false);
  const double now = Clock();
  if (auto w = workers_.find(lease.worker); w != workers_.end()) {
    if (w->second.leases > 0) --w->second.leases;
    w->second.last_seen = now;
  }
  leases_.Finish(lease_id, lease.sweep_id);
  // Stored under the right content keys either way; counted only in the plan it was leased from.
  if (!current) return Status::Ok();
  Sweep& s = sit->second;
  s.error.clear();
  const long counted = s.plan.Complete(lease.job_ids);  // two leases of one job stored at once count once
  if (counted > 0) {
    stats_.items_stored += counted;
    ++stats_.reports_stored;
    if (auto w = workers_.find(lease.worker); w != workers_.end()) w->second.items_done += counted;
    Log(log::Level::kDebug, "report.stored",
        {{"sweep", lease.sweep_id},
         {"job", lease.job_ids.front()},
         {"jobs", lease.job_ids.size()},
         {"worker", lease.worker},
         {"items", n},
         {"store_ms", store_ms}});
  }
  // Publish (or plan a refined sweep's next round) off the report path: the report is acknowledged once its
  // rows are durable, and the map (seconds of HDF5 writing for a large grid) is written by the publisher.
  if (s.plan.next() != JobPlan::Next::kCompute && s.row.state != SweepState::kDone) publisher_->Post(s.row.id);
  return Status::Ok();
}

Status SweepCoordinator::Release(const std::string& lease_id, const std::string& identity) {
  std::lock_guard<std::mutex> lock(mu_);
  const LeaseState* l = leases_.Find(lease_id);
  if (!l) return Status::NotFound("lease is unknown");
  if (l->identity != identity) return NotTheLeaseHolder();
  ++stats_.leases_released;
  Log(log::Level::kInfo, "lease.released",
      {{"sweep", l->sweep_id},
       {"job", l->job_ids.front()},
       {"jobs", l->job_ids.size()},
       {"worker", l->worker},
       {"action", "requeue"}});
  RequeueLocked(*leases_.Take(lease_id));
  return Status::Ok();
}

Status SweepCoordinator::Cancel(const std::string& sweep_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) return Status::NotFound("no active sweep '" + sweep_id + "'");
  if (it->second.row.state == SweepState::kDone)
    return Status::FailedPrecondition("sweep '" + sweep_id + "' is already done");
  if (it->second.publishing)  // its index row would say done after the cancel said cancelled
    return Status::FailedPrecondition("sweep '" + sweep_id +
                                      "' is complete and its map is being published; it cannot be cancelled");
  it->second.cancelled = true;
  Log(log::Level::kInfo, "sweep.cancelled", {{"sweep", sweep_id}, {"items_done", it->second.plan.items_done()}});
  RevokeLeasesLocked(sweep_id);  // a report of this plan is refused from now on
  const Status st = MarkLocked(it->second, SweepState::kCancelled);
  FreePlan(it->second);
  return st;
}

StatusOr<std::string> SweepCoordinator::PublishStep(const std::string& sweep_id) {
  // One step at a time (the publisher's one thread); the coordinator's lock is held only to read the sweep
  // and to record the outcome, so leases and reports of other sweeps go on while the map is gathered and
  // written. What comes next is the plan's to say (JobPlan::next): a refined sweep whose round is stored
  // has its next round planned, and is published once no round is left.
  const std::string path = MapPath(sweep_id);
  MapPublication m;
  bool needs_plan = false;
  for (int attempt = 0;; ++attempt) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      auto it = sweeps_.find(sweep_id);
      if (it == sweeps_.end()) return Status::NotFound("no active sweep '" + sweep_id + "'");
      Sweep& s = it->second;
      if (s.row.state == SweepState::kDone && !s.row.file.empty() && std::filesystem::exists(path)) return path;
      if (s.cancelled) return Status::FailedPrecondition("sweep " + sweep_id + " was cancelled");
      needs_plan = static_cast<long>(s.plan.keys().size()) != s.row.items_total;  // freed after a publication
      const JobPlan::Next next = s.plan.next();
      const bool refining = !needs_plan && s.plan.refined() && !s.plan.refine_complete();
      if (refining && (next == JobPlan::Next::kCompute || attempt > 0))
        return Status::FailedPrecondition(
            "sweep " + sweep_id + " is refining: round " + std::to_string(s.plan.refine_round()) + " has " +
            std::to_string(s.row.items_total - s.plan.items_done()) + " items to compute");
      if (!refining) {
        m = MapPublication{s.spec, s.plan.keys(), s.plan.points(), s.row, s.started, path, data_dir_};
        if (!needs_plan && next == JobPlan::Next::kPublish) s.publishing = true;  // a cancel is refused now
        break;
      }
    }
    BISTABLE_RETURN_IF_ERROR(Replan(sweep_id));  // the next round (found stored already: the loop goes on)
  }
  if (needs_plan) {
    BISTABLE_RETURN_IF_ERROR(Replan(sweep_id));
    return Status::FailedPrecondition("sweep " + sweep_id +
                                      " lost its map file; it is being planned and published again");
  }
  const auto publish_start = std::chrono::steady_clock::now();
  MapPublication::Outcome said;
  auto published = PublishMap(
      m, *writer_, [this] { return Clock(); }, opt_.before_index_row, &said);
  if (said.corrupt > 0) ChecksumFailed(sweep_id, said.corrupt, "replan");
  if (!said.folded.ok())  // the records stay staged and are folded by a later lookup; the map is complete
    Log(log::Level::kWarn, "sweep.fold_failed", {{"sweep", sweep_id}, {"reason", said.folded.ToString()}});
  std::unique_lock<std::mutex> lock(mu_);
  Sweep& s = sweeps_.at(sweep_id);
  s.publishing = false;
  if (!published.ok()) {
    Log(log::Level::kError, "sweep.publish_failed", {{"sweep", sweep_id}, {"reason", published.status().ToString()}});
    s.error = "publication failed: " + published.status().ToString();
    // A write failure (disk full, unwritable dir) fails the sweep. Results missing at publication
    // (a stored result failed its checksum) are computed again: the sweep is planned anew.
    if (published.status().code() == Status::Code::kIoError && !s.cancelled) MarkLocked(s, SweepState::kFailed);
    if (said.incomplete && !s.cancelled) {
      lock.unlock();
      if (Status st = Replan(sweep_id); !st.ok()) return st;
    }
    return published.status();
  }
  s.row = *published;
  Log(log::Level::kInfo, "sweep.published",
      {{"sweep", sweep_id},
       {"items", s.row.items_done},
       {"file", s.row.file},
       {"seconds", s.row.seconds},
       {"publish_ms",
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - publish_start).count()}});
  FreePlan(s);  // published: keys and jobs are no longer needed
  final_cv_.notify_all();
  return path;
}

Status SweepCoordinator::MarkLocked(Sweep& s, SweepState state) {
  s.row.state = state;
  final_cv_.notify_all();
  s.row.items_done = s.plan.items_done();
  s.row.seconds = Clock() - s.started;
  return Db()->UpsertSweep(s.row);
}

Status SweepCoordinator::MarkInterrupted(const std::string& sweep_id) {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) return Status::NotFound("no active sweep '" + sweep_id + "'");
  return MarkLocked(it->second, SweepState::kInterrupted);
}

void SweepCoordinator::Stop() {
  std::lock_guard<std::mutex> lock(mu_);
  stopped_ = true;
}

namespace {

// A sweep that is not active in this process, as its index row says.
SweepInfo InfoOfRow(const SweepRow& r) {
  return SweepInfo{r.id, r.name, r.model,   r.owner, r.state, r.items_total, r.items_done,
                   0,    0,      r.seconds, r.file,  "",      r.created,     r.finished};
}

}  // namespace

SweepInfo SweepCoordinator::InfoLocked(const Sweep& s, const std::map<std::string, int>& holders) const {
  SweepInfo info{s.row.id,
                 s.row.name,
                 s.row.model,
                 s.row.owner,
                 s.row.state,
                 s.row.items_total,
                 s.plan.items_done(),
                 s.plan.items_cached(),
                 0,
                 s.row.state == SweepState::kDone ? s.row.seconds : Clock() - s.started,
                 s.row.file,
                 "",
                 s.row.created,
                 s.row.state == SweepState::kDone ? s.row.finished : 0.0};
  if (info.state == SweepState::kRunning && !s.any_leased && s.plan.items_done() == s.plan.items_cached())
    info.state = SweepState::kQueued;
  if (s.cancelled) info.state = SweepState::kCancelled;
  info.error = s.error;
  auto h = holders.find(s.row.id);
  info.workers = h == holders.end() ? 0 : h->second;
  return info;
}

StatusOr<SweepInfo> SweepCoordinator::Info(const std::string& sweep_id) const {
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = sweeps_.find(sweep_id);
    if (it != sweeps_.end()) return InfoLocked(it->second, leases_.HoldersBySweep());
  }
  // Not active here: the index row (read outside the coordinator's lock).
  auto row = Db()->GetSweep(sweep_id);
  if (!row.ok()) return row.status();
  if (!row.value()) return Status::NotFound("no sweep '" + sweep_id + "'");
  return InfoOfRow(*row.value());
}

StatusOr<std::vector<double>> SweepCoordinator::StoredValues(const std::string& sweep_id,
                                                             const std::string& metric) const {
  const MetricInfo* m = FindMetric(metric);
  if (!m) return Status::InvalidArgument("metric", "unknown metric");
  std::vector<std::string> keys;
  std::vector<long> points;  // a refined sweep's planned grid points (keys[i] is points[i]'s)
  long items = 0;
  size_t width = 0;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = sweeps_.find(sweep_id);
    if (it == sweeps_.end() || it->second.plan.keys().empty())
      return Status::NotFound("sweep " + sweep_id + " has no plan in memory");
    keys = it->second.plan.keys();
    points = it->second.plan.points();
    items = it->second.spec.points() * it->second.spec.ic_count();
    const MetricSettings& ms = it->second.spec.base.metrics;
    width = PointRecord::Size(ms.turning_points, ms.poincare_points);
  }
  // In batches, each its own read transaction under db_mu_: reports committing meanwhile wait for one
  // batch at most, not for the whole sweep.
  constexpr size_t kBatch = 16384;
  const size_t mi = MetricIndex(m->name);
  std::vector<double> out(points.empty() ? keys.size() : static_cast<size_t>(items),
                          std::numeric_limits<double>::quiet_NaN());
  for (size_t b = 0; b < keys.size(); b += kBatch) {
    const std::vector<std::string> batch(keys.begin() + static_cast<long>(b),
                                         keys.begin() + static_cast<long>(std::min(keys.size(), b + kBatch)));
    auto found = Db()->LookupPoints(batch, width);
    if (!found.ok()) return found.status();
    for (size_t i = b; i < b + batch.size(); ++i)
      if (auto f = found->find(keys[i]); f != found->end())
        out[points.empty() ? i : static_cast<size_t>(points[i])] = f->second.v[mi];
  }
  return out;
}

StatusOr<SweepInfo> SweepCoordinator::AwaitFinal(const std::string& sweep_id, double seconds) const {
  {
    std::unique_lock<std::mutex> lock(mu_);
    final_cv_.wait_for(lock, std::chrono::duration<double>(seconds), [&] {
      auto it = sweeps_.find(sweep_id);  // a sweep this coordinator does not hold: wait the whole time
      return it != sweeps_.end() && (it->second.cancelled || IsFinal(it->second.row.state));
    });
  }
  return Info(sweep_id);
}

StatusOr<std::string> SweepCoordinator::ResolveId(const std::string& id) const {
  if (id.empty()) return Status::InvalidArgument("id", "id is empty");
  if (id.size() > limits::kMaxIdBytes)
    return Status::InvalidArgument("id", "id is " + std::to_string(id.size()) + " bytes, over the limit of " +
                                             std::to_string(limits::kMaxIdBytes));
  if (id.find_first_not_of("0123456789abcdef") != std::string::npos)
    return Status::InvalidArgument("id", "id must be lowercase hex digits (a sweep id or its prefix)");
  auto row = Db()->GetSweep(id);
  if (!row.ok()) return row.status();
  if (!row.value()) return Status::NotFound("no sweep '" + id + "'");
  return row.value()->id;
}

StatusOr<std::vector<SweepInfo>> SweepCoordinator::ListSweeps() const {
  // One index query and one pass over the leases, not a query and a pass per sweep under the lock.
  auto rows = Db()->ListSweeps();
  if (!rows.ok()) return rows.status();
  std::vector<SweepInfo> out;
  out.reserve(rows->size());
  std::lock_guard<std::mutex> lock(mu_);
  const std::map<std::string, int> holders = leases_.HoldersBySweep();
  for (const SweepRow& r : *rows) {
    auto it = sweeps_.find(r.id);
    out.push_back(it == sweeps_.end() ? InfoOfRow(r) : InfoLocked(it->second, holders));
  }
  return out;
}

CoordinatorStats SweepCoordinator::Stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  CoordinatorStats out = stats_;
  out.leases_outstanding = leases_.outstanding();
  for (const auto& [id, s] : sweeps_) {
    const SweepState st = s.cancelled ? SweepState::kCancelled : s.row.state;
    ++out.sweeps_by_state[static_cast<int>(st)];
    if (s.cancelled) continue;
    out.jobs_queued += static_cast<long>(s.plan.queued());
    if (st == SweepState::kRunning || st == SweepState::kQueued)
      out.items_pending += s.row.items_total - s.plan.items_done();
  }
  const double now = Clock();
  for (const auto& [name, w] : workers_) {
    out.workers.push_back(w);
    if (w.leases > 0 || now - w.last_seen < 3 * opt_.lease_seconds) ++out.workers_active;
  }
  return out;
}

std::vector<WorkerInfo> SweepCoordinator::Workers() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<WorkerInfo> out;
  for (const auto& [name, w] : workers_) out.push_back(w);
  return out;
}

StatusOr<std::string> SweepCoordinator::SpecText(const std::string& sweep_id, std::string* spec_key) const {
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = sweeps_.find(sweep_id);
    if (it != sweeps_.end()) {
      if (spec_key) *spec_key = it->second.spec_key;
      return it->second.spec.source;
    }
  }
  // A sweep this process holds no plan of (finished before a restart, or never submitted here): the
  // spec as stored in its index row.
  auto row = Db()->GetSweep(sweep_id);
  if (!row.ok()) return row.status();
  if (!row.value() || row.value()->id != sweep_id) return Status::NotFound("no sweep '" + sweep_id + "'");
  if (spec_key) *spec_key = Sha256Hex(row.value()->spec);
  return row.value()->spec;
}

SweepProgress SweepCoordinator::progress(const std::string& sweep_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = sweeps_.find(sweep_id);
  if (it == sweeps_.end()) return {};
  const Sweep& s = it->second;
  return {s.row.items_total, s.plan.items_done(), s.plan.items_cached(),
          KindOf(s.spec).InRounds() ? s.plan.refine_round() : -1};
}

}  // namespace bistable
