#include "engine/sweep_plan.h"

#include <algorithm>
#include <map>
#include <optional>

#include "base/limits.h"

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

StatusOr<JobPlan> JobPlan::Build(const SweepSpec& spec, long job_items, const PointLookup& lookup, RefineCarry carry) {
  JobPlan s;
  s.ic_count_ = spec.ic_count();
  const int nic = spec.ic_count();
  const long points = spec.points();
  long total = 0;
  if (__builtin_mul_overflow(points, static_cast<long>(nic), &total) || total > limits::kMaxSweepItems)
    return Status::InvalidArgument("axes",
                                   "points x initial conditions violates <= " + std::to_string(limits::kMaxSweepItems));
  s.items_total_ = total;
  if (spec.refine.enabled()) {
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
  s.keys_.reserve(total);
  for (long p = 0; p < points; ++p)
    for (int i = 0; i < nic; ++i) s.keys_.push_back(spec.ItemKey(p, i));
  // Looked up in batches, so the owner's reads of the cache are bounded.
  std::vector<bool> is_missing(s.keys_.size(), true);
  for (size_t b = 0; b < s.keys_.size(); b += kPlanLookupBatch) {
    const std::vector<std::string> batch(s.keys_.begin() + b,
                                         s.keys_.begin() + std::min(s.keys_.size(), b + kPlanLookupBatch));
    auto cached = lookup(batch);
    if (!cached.ok()) return cached.status();
    for (size_t i = 0; i < batch.size(); ++i)
      if (cached->count(batch[i])) is_missing[b + i] = false;
  }
  JobBuilder jobs{s.jobs_, job_items};
  if (spec.continuation.enabled()) {
    // Chains run whole and in order (each point starts where the previous ended): a chain with any
    // missing item is computed entirely.
    for (const auto& chain : spec.ContinuationChains()) {
      bool any = false;
      for (const WorkItem& w : chain) any = any || is_missing[w.point * nic + w.ic];
      if (any) jobs.Add(chain);
    }
  } else {
    for (long p = 0; p < points; ++p)
      for (int i = 0; i < nic; ++i)
        if (is_missing[p * nic + i]) jobs.Add(WorkItem{p, i});
  }
  jobs.Close();
  s.QueueAllJobs();
  long queued = 0;
  for (const Job& j : s.jobs_) queued += static_cast<long>(j.items.size());
  s.items_cached_ = s.items_done_ = total - queued;  // items of partly stored chains are recomputed
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
