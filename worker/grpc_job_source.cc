#include "worker/grpc_job_source.h"

#include <utility>

#include "proto/convert.h"

namespace bistable {

std::shared_ptr<const SweepSpec> SpecCache::Find(const std::string& key) {
  std::lock_guard<std::mutex> lock(mu_);
  for (auto it = lru_.begin(); it != lru_.end(); ++it)
    if (it->first == key) {
      lru_.splice(lru_.begin(), lru_, it);
      return lru_.front().second;
    }
  return nullptr;
}

StatusOr<std::shared_ptr<const SweepSpec>> SpecCache::Put(const std::string& sweep_id, const std::string& toml,
                                                          const std::string& key) {
  const std::string own = SpecKey(toml);
  if (!key.empty() && key != own)
    return Status::InvalidArgument("spec", "the spec of sweep " + sweep_id + " does not have its key " + key);
  if (auto held = Find(own)) return held;
  auto spec = ParseSweepSpec(toml, "sweep " + sweep_id);  // outside the lock: a spec takes milliseconds to parse
  if (!spec.ok()) return spec.status();
  auto p = std::make_shared<const SweepSpec>(std::move(spec).value());
  std::lock_guard<std::mutex> lock(mu_);
  ++parses_;
  for (auto it = lru_.begin(); it != lru_.end(); ++it)
    if (it->first == own) {  // another loop parsed it meanwhile
      lru_.splice(lru_.begin(), lru_, it);
      return lru_.front().second;
    }
  if (capacity_ == 0) return p;
  while (lru_.size() >= capacity_) lru_.pop_back();
  lru_.emplace_front(own, p);
  return p;
}

std::vector<std::string> SpecCache::Keys() const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<std::string> keys;
  for (const auto& e : lru_) keys.push_back(e.first);
  return keys;
}

long SpecCache::parses() const {
  std::lock_guard<std::mutex> lock(mu_);
  return parses_;
}

StatusOr<std::shared_ptr<const SweepSpec>> SpecOfLease(CoordinatorClient* c, SpecCache* cache,
                                                       const CoordinatorClient::Lease& lease) {
  // The text when it came (an old coordinator sends no key: the cache keys it itself).
  if (!lease.spec_toml.empty() || lease.spec_key.empty())
    return cache->Put(lease.sweep_id, lease.spec_toml, lease.spec_key);
  if (auto held = cache->Find(lease.spec_key)) return held;
  // Named as held, but pushed out since (or a coordinator that left it out unasked): asked for once.
  auto text = c->GetSpec(lease.sweep_id);
  if (!text.ok()) return text.status();
  return cache->Put(lease.sweep_id, text->spec_toml, lease.spec_key);
}

StatusOr<std::optional<LeasedJob>> GrpcJobSource::Lease() {
  auto lease = c_->LeaseJob(name_, jobs_per_lease_, cache_->Keys());
  Count("Lease", lease.status());
  if (!lease.ok()) return lease.status();
  return ToJob(std::move(*lease));
}

void GrpcJobSource::Heartbeat(const LeasedJob& job) { Count("Heartbeat", c_->Heartbeat(job.lease_id)); }

Status GrpcJobSource::Report(const LeasedJob& job, const std::vector<PointRecord>& records,
                             std::optional<LeasedJob>* next) {
  std::optional<CoordinatorClient::Lease> following;
  const Status st = c_->Report(job.lease_id, records, next ? name_ : "", next ? &following : nullptr, jobs_per_lease_,
                               next ? cache_->Keys() : std::vector<std::string>());
  Count("Report", st);
  BISTABLE_RETURN_IF_ERROR(st);
  if (next && following) {
    auto j = ToJob(std::move(following));
    if (j.ok()) *next = std::move(*j);
  }
  return Status::Ok();
}

Status GrpcJobSource::Release(const LeasedJob& job) {
  const Status st = c_->Release(job.lease_id);
  Count("Release", st);
  return st;
}

StatusOr<std::optional<LeasedJob>> GrpcJobSource::ToJob(std::optional<CoordinatorClient::Lease> lease) {
  if (!lease) return std::optional<LeasedJob>();
  auto spec = SpecOfLease(c_, cache_, *lease);
  if (!spec.ok()) {
    (void)c_->Release(lease->lease_id);
    return Status::FailedPrecondition("cannot get or parse the spec of sweep " + lease->sweep_id +
                                      " (released): " + spec.status().ToString());
  }
  return std::optional<LeasedJob>(LeasedJob{lease->lease_id, *spec, std::move(lease->items)});
}

}  // namespace bistable
