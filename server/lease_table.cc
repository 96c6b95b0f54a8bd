#include "server/lease_table.h"

#include <cstdio>
#include <set>

namespace bistable {

LeaseTable::LeaseTable(std::function<double()> clock, double lease_seconds)
    : clock_(std::move(clock)), lease_seconds_(lease_seconds) {}

std::string LeaseTable::Grant(LeaseState l) {
  // 128 bits from the kernel's CSPRNG: a worker that saw any number of lease ids cannot name another's
  // (the old counter and Mersenne Twister salt were predictable after 624 leases, issue 39).
  std::string id;
  do {
    id = l.sweep_id + "-";
    for (int i = 0; i < 4; ++i) {
      char b[9];
      std::snprintf(b, sizeof b, "%08x", static_cast<unsigned>(random_()));
      id += b;
    }
  } while (active_.count(id) || committing_.count(id) || finished_.count(id));
  l.deadline = clock_() + lease_seconds_;
  active_.emplace(id, std::move(l));
  return id;
}

const LeaseState* LeaseTable::Find(const std::string& id) const {
  auto it = active_.find(id);
  return it == active_.end() ? nullptr : &it->second;
}

Status LeaseTable::Extend(const std::string& id, const std::string& identity) {
  auto it = active_.find(id);
  if (it == active_.end()) return Finished(id) ? Status::Ok() : Status::NotFound("lease '" + id + "' is unknown");
  if (it->second.identity != identity)
    return Status::PermissionDenied(
        "the lease was granted to another identity (token): only its holder may extend, report or release it");
  const double now = clock_();
  if (it->second.deadline < now) return Status::FailedPrecondition("lease '" + id + "' expired; its job was requeued");
  it->second.deadline = now + lease_seconds_;
  return Status::Ok();
}

std::vector<LeaseState> LeaseTable::TakeExpired() {
  std::vector<LeaseState> out;
  const double now = clock_();
  for (auto it = active_.begin(); it != active_.end();) {
    if (it->second.deadline >= now) {
      ++it;
      continue;
    }
    out.push_back(std::move(it->second));
    it = active_.erase(it);
  }
  return out;
}

std::optional<LeaseState> LeaseTable::Take(const std::string& id) {
  auto it = active_.find(id);
  if (it == active_.end()) return std::nullopt;
  LeaseState l = std::move(it->second);
  active_.erase(it);
  return l;
}

std::vector<LeaseState> LeaseTable::Revoke(const std::string& sweep_id) {
  std::vector<LeaseState> out;
  for (auto it = active_.begin(); it != active_.end();) {
    if (it->second.sweep_id != sweep_id) {
      ++it;
      continue;
    }
    out.push_back(std::move(it->second));
    it = active_.erase(it);
  }
  return out;
}

void LeaseTable::BeginCommit(const std::string& id, LeaseState l) {
  active_.erase(id);
  committing_[id] = std::move(l);
}

void LeaseTable::EndCommit(const std::string& id, bool restore) {
  auto it = committing_.find(id);
  if (it == committing_.end()) return;
  if (restore) active_[id] = std::move(it->second);
  committing_.erase(it);
}

void LeaseTable::Finish(const std::string& id, const std::string& sweep_id) {
  if (finished_.emplace(id, sweep_id).second) finished_order_.push_back(id);
  while (finished_order_.size() > kRemembered) {
    finished_.erase(finished_order_.front());
    finished_order_.pop_front();
  }
}

std::map<std::string, int> LeaseTable::HoldersBySweep() const {
  std::map<std::string, std::set<std::string>> workers;  // sweep → the workers holding a lease of it
  for (const auto& [id, l] : active_) workers[l.sweep_id].insert(l.worker);
  std::map<std::string, int> out;
  for (const auto& [sweep, w] : workers) out[sweep] = static_cast<int>(w.size());
  return out;
}

}  // namespace bistable
