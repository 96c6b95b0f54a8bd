#include "engine/sweep_plan.h"

#include <algorithm>
#include <map>
#include <optional>

#include "base/limits.h"
#include "engine/sweep_kind.h"

namespace bistable {

namespace {
// Cuts a plan's items into jobs of about `job_items`: a group (a continuation chain) is never split,
// so a job closes once it holds job_items or more.
struct JobBuilder {
  std::vector<Job>& jobs;
  long job_items;
  Job open{};
  void Add(const WorkItem& item) {
    open.items.push_back(item);
    if (static_cast<long>(open.items.size()) >= job_items) Close();
  }
  void Add(const std::vector<WorkItem>& group) {
    open.items.insert(open.items.end(), group.begin(), group.end());
    if (static_cast<long>(open.items.size()) >= job_items) Close();
  }
  void Close() {
    if (open.items.empty()) return;
    open.id = static_cast<long>(jobs.size());
    jobs.push_back(std::move(open));
    open = Job{};
  }
};
}  // namespace

void JobPlan::QueueAllJobs() {
  for (const Job& j : jobs_) queue_.push_back(j.id);
  job_state_.assign(jobs_.size(), JobState::kQueued);
}

JobPlan JobPlan::Published(long items_total) {
  JobPlan p;
  p.items_total_ = p.items_done_ = p.items_cached_ = items_total;
  return p;
}

namespace {
// Grid points x initial conditions, within limits::kMaxSweepItems.
StatusOr<long> ItemsTotal(const SweepSpec& spec) {
  long total = 0;
  if (__builtin_mul_overflow(spec.points(), static_cast<long>(spec.ic_count()), &total) ||
      total > limits::kMaxSweepItems)
    return Status::InvalidArgument("axes",
                                   "points x initial conditions violates <= " + std::to_string(limits::kMaxSweepItems));
  return total;
}
}  // namespace

StatusOr<Shard> ParseShard(const std::string& text) {
  const size_t slash = text.find('/');
  auto number = [](const std::string& t, long* out) {
    if (t.empty() || t.size() > 9 || t.find_first_not_of("0123456789") != std::string::npos) return false;
    *out = std::stol(t);
    return true;
  };
  long i = 0, n = 0;
  if (slash == std::string::npos || !number(text.substr(0, slash), &i) || !number(text.substr(slash + 1), &n))
    return Status::InvalidArgument("shard", "shard = '" + text +
                                                "' is not I/N (e.g. 3/8: shard 3 of 8, numbered from 0; a job "
                                                "array's task id and task count)");
  if (n < 1 || n > limits::kMaxShards)
    return Status::InvalidArgument("shard", "shard = " + text + ": N = " + std::to_string(n) +
                                                " violates 1 <= N <= " + std::to_string(limits::kMaxShards));
  if (i >= n)
    return Status::InvalidArgument("shard", "shard = " + text + ": I = " + std::to_string(i) +
                                                " violates 0 <= I < N = " + std::to_string(n) +
                                                " (shards are numbered from 0)");
  return Shard{static_cast<int>(i), static_cast<int>(n)};
}

Status CheckShardable(const SweepSpec& spec) {
  if (KindOf(spec).InRounds())
    return Status::InvalidArgument(
        "shard", "sweep " + spec.Id() + " is " + KindOf(spec).Name() +
                     " ([refine]): each round is planned from the whole previous round's results, so it "
                     "cannot be cut into independent shards; run it whole (bistable run without --shard, or "
                     "bistable submit to a coordinator)");
  return Status::Ok();
}

std::vector<long> ShardItemIndices(const SweepSpec& spec, const Shard& shard) {
  std::vector<long> out;
  const int nic = spec.ic_count();
  if (const auto chains = KindOf(spec).Chains(spec); !chains.empty()) {  // whole chains, dealt in their order
    for (size_t c = static_cast<size_t>(shard.index); c < chains.size(); c += static_cast<size_t>(shard.count))
      for (const WorkItem& w : chains[c]) out.push_back(w.point * nic + w.ic);
    std::sort(out.begin(), out.end());
    return out;
  }
  const long total = spec.points() * nic;
  for (long i = shard.index; i < total; i += shard.count) out.push_back(i);
  return out;
}

std::vector<std::string> ItemKeys(const SweepSpec& spec) {
  std::vector<std::string> keys;
  const int nic = spec.ic_count();
  keys.reserve(static_cast<size_t>(spec.points()) * static_cast<size_t>(nic));
  for (long p = 0; p < spec.points(); ++p)
    for (int i = 0; i < nic; ++i) keys.push_back(spec.ItemKey(p, i));
  return keys;
}

StatusOr<JobPlan> JobPlan::BuildShard(const SweepSpec& spec, long job_items, const PointLookup& lookup,
                                      const Shard& shard) {
  BISTABLE_RETURN_IF_ERROR(CheckShardable(spec));
  return BuildGrid(spec, job_items, lookup, &shard);
}

StatusOr<JobPlan> JobPlan::Build(const SweepSpec& spec, long job_items, const PointLookup& lookup, RefineCarry carry) {
  if (!KindOf(spec).InRounds()) return BuildGrid(spec, job_items, lookup, nullptr);
  auto total = ItemsTotal(spec);  // the grid's bound holds for a refined sweep too
  if (!total.ok()) return total.status();
  JobPlan s;
  s.ic_count_ = spec.ic_count();
  s.refined_ = true;
  std::map<long, std::string> looked_up;  // keys of the points looked up now (the current round's)
  if (!carry.planner)
    carry = RefineCarry{std::make_shared<RefinePlanner>(spec), {}, {}, false, 0, 0};  // a walk from the start
  auto step =
      carry.planner->Advance([&](const std::vector<long>& pts, std::vector<std::optional<RefineMark>>* classes) {
        classes->assign(pts.size(), std::nullopt);
        for (size_t b = 0; b < pts.size(); b += kPlanLookupBatch) {
          const size_t e = std::min(pts.size(), b + kPlanLookupBatch);
          std::vector<std::string> batch;
          batch.reserve(e - b);
          for (size_t i = b; i < e; ++i) batch.push_back(spec.ItemKey(pts[i], 0));
          auto cached = lookup(batch);
          if (!cached.ok()) return cached.status();
          for (size_t i = b; i < e; ++i) {
            if (auto it = cached->find(batch[i - b]); it != cached->end())
              (*classes)[i] = RefineClass(spec.refine, spec.base.metrics, it->second);
            looked_up[pts[i]] = std::move(batch[i - b]);
          }
        }
        return Status::Ok();
      });
  if (!step.ok()) return step.status();  // the walk is left mid-round: the next plan walks from the start
  s.refiner_ = carry.planner;
  // Every planned point's key: looked up now, or carried from the last plan (both ascending).
  s.points_ = step->points;
  s.keys_.reserve(s.points_.size());
  size_t c = 0;
  for (long p : s.points_) {
    while (c < carry.points.size() && carry.points[c] < p) ++c;
    if (auto it = looked_up.find(p); it != looked_up.end())
      s.keys_.push_back(std::move(it->second));
    else if (c < carry.points.size() && carry.points[c] == p)
      s.keys_.push_back(std::move(carry.keys[c]));
    else
      s.keys_.push_back(spec.ItemKey(p, 0));
  }
  s.refine_round_ = step->round;
  s.refine_complete_ = step->complete;
  JobBuilder jobs{s.jobs_, job_items};
  for (long p : step->missing) jobs.Add(WorkItem{p, 0});
  jobs.Close();
  s.QueueAllJobs();
  s.items_total_ = static_cast<long>(s.points_.size());  // grows round by round
  s.items_done_ = s.items_total_ - static_cast<long>(step->missing.size());
  s.refine_queued_ = static_cast<long>(step->missing.size());
  // Reused from the cache: at the first plan, what was stored; later rounds add what they found stored
  // beyond the items this plan's owner computed for the round before (carry.computed).
  const long found = static_cast<long>(looked_up.size()) - static_cast<long>(step->missing.size());
  s.items_cached_ = carry.continued ? carry.cached + found - carry.computed : s.items_done_;
  return s;
}

StatusOr<JobPlan> JobPlan::BuildGrid(const SweepSpec& spec, long job_items, const PointLookup& lookup,
                                     const Shard* shard) {
  auto total = ItemsTotal(spec);
  if (!total.ok()) return total.status();
  JobPlan s;
  s.ic_count_ = spec.ic_count();
  s.keys_ = ItemKeys(spec);
  // The items this plan holds (every item, or the shard's), looked up in batches so the owner's reads of
  // the cache are bounded; items it does not hold are neither missing nor counted.
  std::vector<long> shard_items;
  if (shard) shard_items = ShardItemIndices(spec, *shard);
  const long held = shard ? static_cast<long>(shard_items.size()) : *total;
  auto item = [&](long k) { return shard ? shard_items[k] : k; };
  std::vector<bool> is_missing(s.keys_.size(), false);
  for (long b = 0; b < held; b += static_cast<long>(kPlanLookupBatch)) {
    const long e = std::min(held, b + static_cast<long>(kPlanLookupBatch));
    std::vector<std::string> batch;
    batch.reserve(e - b);
    for (long k = b; k < e; ++k) batch.push_back(s.keys_[item(k)]);
    auto cached = lookup(batch);
    if (!cached.ok()) return cached.status();
    for (long k = b; k < e; ++k)
      if (!cached->count(batch[k - b])) is_missing[item(k)] = true;
  }
  const int nic = s.ic_count_;
  JobBuilder jobs{s.jobs_, job_items};
  if (const auto chains = KindOf(spec).Chains(spec); !chains.empty()) {
    // Chains run whole and in order (each point starts where the previous ended): a chain with any
    // missing item is computed entirely.
    for (const auto& chain : chains) {
      bool any = false;
      for (const WorkItem& w : chain) any = any || is_missing[w.point * nic + w.ic];
      if (any) jobs.Add(chain);
    }
  } else {
    for (long p = 0; p < spec.points(); ++p)
      for (int i = 0; i < nic; ++i)
        if (is_missing[p * nic + i]) jobs.Add(WorkItem{p, i});
  }
  jobs.Close();
  s.QueueAllJobs();
  long queued = 0;
  for (const Job& j : s.jobs_) queued += static_cast<long>(j.items.size());
  s.items_total_ = held;
  s.items_cached_ = s.items_done_ = held - queued;  // items of partly stored chains are recomputed
  return s;
}

JobPlan::Next JobPlan::next() const {
  if (items_done_ < items_total_) return Next::kCompute;
  if (refined_ && !refine_complete_) return Next::kNextRound;
  return Next::kPublish;
}

RefineCarry JobPlan::Carry() const {
  if (!refiner_ || refine_complete_) return {};
  return RefineCarry{refiner_, points_, keys_, true, items_cached_, refine_queued_};
}

std::vector<long> JobPlan::Take(int max_jobs, long max_items) {
  std::vector<long> out;
  if (queue_.empty()) return out;
  out.push_back(queue_.front());
  queue_.pop_front();
  long items = static_cast<long>(jobs_[out[0]].items.size());
  while (static_cast<int>(out.size()) < max_jobs && !queue_.empty() &&
         items + static_cast<long>(jobs_[queue_.front()].items.size()) <= max_items) {
    out.push_back(queue_.front());
    items += static_cast<long>(jobs_[out.back()].items.size());
    queue_.pop_front();
  }
  for (long j : out) job_state_[j] = JobState::kLeased;
  return out;
}

void JobPlan::Requeue(const std::vector<long>& job_ids) {
  for (auto j = job_ids.rbegin(); j != job_ids.rend(); ++j)  // back at the front, in their order
    if (*j >= 0 && *j < static_cast<long>(job_state_.size()) && job_state_[*j] == JobState::kLeased) {
      job_state_[*j] = JobState::kQueued;
      queue_.push_front(*j);
    }
}

bool JobPlan::Holds(const std::vector<long>& job_ids) const {
  for (long j : job_ids)
    if (j < 0 || j >= static_cast<long>(jobs_.size())) return false;
  return true;
}

bool JobPlan::AllDone(const std::vector<long>& job_ids) const {
  for (long j : job_ids)
    if (job_state_[j] != JobState::kDone) return false;
  return true;
}

long JobPlan::ItemsOf(const std::vector<long>& job_ids) const {
  long n = 0;
  for (long j : job_ids) n += static_cast<long>(jobs_[j].items.size());
  return n;
}

std::vector<WorkItem> JobPlan::ItemsFor(const std::vector<long>& job_ids) const {
  std::vector<WorkItem> out;
  out.reserve(ItemsOf(job_ids));
  for (long j : job_ids) out.insert(out.end(), jobs_[j].items.begin(), jobs_[j].items.end());
  return out;
}

const std::string& JobPlan::KeyOf(const WorkItem& w) const {
  if (points_.empty()) return keys_[w.point * ic_count_ + w.ic];
  return keys_[std::lower_bound(points_.begin(), points_.end(), w.point) - points_.begin()];
}

std::string JobPlan::KeysFor(const std::vector<long>& job_ids) const {
  std::string out;
  out.reserve(ItemsOf(job_ids) * (keys_.empty() ? 0 : keys_[0].size() + 1));
  for (long j : job_ids)
    for (const WorkItem& w : jobs_[j].items) {
      out += KeyOf(w);
      out += '\n';
    }
  return out;
}

long JobPlan::Complete(const std::vector<long>& job_ids) {
  long counted = 0;  // two leases of one job stored at once count once
  for (long j : job_ids) {
    if (job_state_[j] == JobState::kDone) continue;
    job_state_[j] = JobState::kDone;
    counted += static_cast<long>(jobs_[j].items.size());
  }
  items_done_ += counted;
  return counted;
}

void JobPlan::Free() {
  std::vector<std::string>().swap(keys_);
  std::vector<long>().swap(points_);
  refiner_.reset();
  std::vector<Job>().swap(jobs_);
  std::vector<JobState>().swap(job_state_);
  std::deque<long>().swap(queue_);
}

}  // namespace bistable
