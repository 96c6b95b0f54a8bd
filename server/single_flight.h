// A small expiring cache whose misses are loaded once however many callers ask at the same time
// ("single flight"): the dashboard's loaded metrics (server/dashboard.cc), where several open tabs ask
// for the same map together and each load reads a whole dataset from HDF5 under its one lock.
#ifndef BISTABLE_SERVER_SINGLE_FLIGHT_H_
#define BISTABLE_SERVER_SINGLE_FLIGHT_H_

#include <chrono>
#include <cstddef>
#include <exception>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include "base/status.h"

namespace bistable {

// Loads shared by every caller that asks for the same key while one runs ("single flight"): the caller that
// starts a load runs it, the others wait and share its result (an error too; an exception reaches every
// waiting caller). Callers that cache what they load re-check their cache inside `load` (under their own
// lock): a load that finished between their miss and their flight is then not run again.
template <class V>
class SingleFlight {
 public:
  StatusOr<V> Do(const std::string& key, const std::function<StatusOr<V>()>& load) {
    std::shared_future<StatusOr<V>> wait;
    std::promise<StatusOr<V>> mine;
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (auto f = flights_.find(key); f != flights_.end())
        wait = f->second;
      else
        flights_.emplace(key, mine.get_future().share());
    }
    if (wait.valid()) return wait.get();
    try {
      StatusOr<V> v = load();
      Land(key);
      mine.set_value(v);
      return v;
    } catch (...) {
      Land(key);
      mine.set_exception(std::current_exception());
      throw;
    }
  }

 private:
  void Land(const std::string& key) {
    std::lock_guard<std::mutex> lock(mu_);
    flights_.erase(key);
  }
  std::mutex mu_;
  std::map<std::string, std::shared_future<StatusOr<V>>> flights_;
};

template <class V>
class SingleFlightCache {
 public:
  // Entries serve for `ttl_seconds` after their load; at most `max_entries` are kept (the oldest goes first).
  SingleFlightCache(double ttl_seconds, std::size_t max_entries) : ttl_(ttl_seconds), max_(max_entries) {}

  // The value for `key`: a fresh cached one, or `load()`'s. Callers that miss while a load of the same key
  // runs wait for it and share its result (an error too); errors are not cached, so the next caller after
  // a failed load tries again. An exception from `load` reaches every waiting caller.
  StatusOr<V> GetOrLoad(const std::string& key, const std::function<StatusOr<V>()>& load) {
    if (std::optional<V> v = Fresh(key)) return *v;
    return flights_.Do(key, [&]() -> StatusOr<V> {
      if (std::optional<V> v = Fresh(key)) return *v;  // landed between the miss and this flight
      {
        std::lock_guard<std::mutex> lock(mu_);
        ++loads_;
      }
      StatusOr<V> v = load();
      if (v.ok()) {
        std::lock_guard<std::mutex> lock(mu_);
        PutLocked(key, *v);
      }
      return v;
    });
  }

  // Loads started so far (what single flight saves shows here).
  long loads() const {
    std::lock_guard<std::mutex> lock(mu_);
    return loads_;
  }

 private:
  static double Now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
  }
  std::optional<V> Fresh(const std::string& key) const {
    std::lock_guard<std::mutex> lock(mu_);
    if (auto it = entries_.find(key); it != entries_.end() && Now() - it->second.first <= ttl_)
      return it->second.second;
    return std::nullopt;
  }
  void PutLocked(const std::string& key, const V& v) {
    entries_.erase(key);
    while (!entries_.empty() && entries_.size() >= max_) {
      auto oldest = entries_.begin();
      for (auto it = entries_.begin(); it != entries_.end(); ++it)
        if (it->second.first < oldest->second.first) oldest = it;
      entries_.erase(oldest);
    }
    entries_.emplace(key, std::make_pair(Now(), v));
  }

  const double ttl_;
  const std::size_t max_;
  mutable std::mutex mu_;
  std::map<std::string, std::pair<double, V>> entries_;
  long loads_ = 0;
  SingleFlight<V> flights_;
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_SINGLE_FLIGHT_H_
