// The coordinator's leases: who holds which jobs of which plan until when, on an injected clock. Ids are
// unguessable (the sweep id and 128 bits of the kernel's CSPRNG); a lease is bound to the identity that
// took it; an expired lease is handed back to be requeued; a lease whose report is being stored cannot
// expire meanwhile; finished leases are remembered (a bounded number) so a retried report is answered
// once. No locks of its own: the coordinator holds it under its lock (server/sweep_coordinator.h).
#ifndef BISTABLE_SERVER_LEASE_TABLE_H_
#define BISTABLE_SERVER_LEASE_TABLE_H_

#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "base/status.h"

namespace bistable {

struct LeaseState {
  std::string sweep_id, worker;
  std::string identity;               // who leased it: only they may extend, report, release
  std::vector<long> job_ids;          // one job, or several merged
  unsigned long long generation = 0;  // the plan the jobs belong to
  double deadline = 0;                // on the table's clock
};

class LeaseTable {
 public:
  // `clock`: seconds of the clock deadlines run on (the coordinator's monotonic clock; tests step a fake
  // one). `lease_seconds`: a lease's life from its grant or its last extension.
  LeaseTable(std::function<double()> clock, double lease_seconds);

  double Now() const { return clock_(); }
  // Grants `l` (its deadline set from now) under a new id, which it returns.
  std::string Grant(LeaseState l);
  // The active (not committing, not finished) lease `id`, or nullptr.
  const LeaseState* Find(const std::string& id) const;
  bool Expired(const LeaseState& l) const { return l.deadline < clock_(); }
  // Pushes the deadline back by lease_seconds: NotFound for an unknown lease (Ok for a finished one: a
  // heartbeat racing its report), PermissionDenied for another identity's, FailedPrecondition once expired.
  Status Extend(const std::string& id, const std::string& identity);
  // Removes and returns every lease past its deadline (for the caller to requeue).
  std::vector<LeaseState> TakeExpired();
  // Removes and returns lease `id` (released, refused, or its report stored as a duplicate).
  std::optional<LeaseState> Take(const std::string& id);
  // Removes and returns every lease of a sweep (a cancel, a new plan).
  std::vector<LeaseState> Revoke(const std::string& sweep_id);
  // A report's rows are being stored: the lease leaves the active ones (it cannot expire or be requeued
  // meanwhile) until EndCommit, which makes it active again (`restore`: the store failed, the worker may
  // retry) or finished.
  void BeginCommit(const std::string& id, LeaseState l);
  bool Committing(const std::string& id) const { return committing_.count(id) > 0; }
  void EndCommit(const std::string& id, bool restore);
  // Remembers a finished lease (its report stored): a report of it again is a duplicate.
  void Finish(const std::string& id, const std::string& sweep_id);
  bool Finished(const std::string& id) const { return finished_.count(id) > 0; }
  // Sweep id → how many distinct workers hold an active lease of it.
  std::map<std::string, int> HoldersBySweep() const;
  long outstanding() const { return static_cast<long>(active_.size() + committing_.size()); }

  static constexpr size_t kRemembered = 1 << 16;  // retried reports arrive within seconds; this is hours of them

 private:
  std::function<double()> clock_;
  double lease_seconds_;
  std::map<std::string, LeaseState> active_;
  std::map<std::string, LeaseState> committing_;
  std::map<std::string, std::string> finished_;  // lease id → sweep id
  std::deque<std::string> finished_order_;       // oldest first: bounded memory
  std::random_device random_;  // the kernel's CSPRNG (getrandom): ids cannot be predicted from earlier ones
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_LEASE_TABLE_H_
