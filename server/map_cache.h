// Published maps read once, for everyone who serves them: the gRPC service's GetMap and ListMetrics and the
// dashboard's map, query and cell routes share one MapCache (bistable-coordinator makes one for both), so a
// map viewed in the browser and fetched by `bistable map` is read from HDF5 once.
//
// Entries are keyed by the file's path and its identity (device, inode, size, modification time in ns): a
// republished map (a new file renamed into place) or a file rewritten in place has a new identity and is read
// again, and the old entry ages out. A load is kept only when the file's identity is the same after it as
// before (a file replaced during the read is served, not kept). Bounded by limits::kMaxMapCacheEntries entries
// and limits::kMaxMapCacheBytes of values, least recently used first out; a metric larger than the byte bound
// is read for its caller and not kept. Misses of one key load once however many callers ask together (single
// flight, as server/single_flight.h); errors are not kept. Thread-safe.
#ifndef BISTABLE_SERVER_MAP_CACHE_H_
#define BISTABLE_SERVER_MAP_CACHE_H_

#include <cstddef>
#include <functional>
#include <future>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "base/limits.h"
#include "base/status.h"
#include "engine/map_array.h"
#include "server/single_flight.h"

namespace bistable {

class MapCache {
 public:
  explicit MapCache(std::size_t max_entries = limits::kMaxMapCacheEntries,
                    std::size_t max_bytes = limits::kMaxMapCacheBytes)
      : max_entries_(max_entries), max_bytes_(max_bytes) {}

  // One metric of the map file at `path` (storage/map_file.h ReadMapMetric: only a metric the map lists).
  StatusOr<std::shared_ptr<const MapArray>> Metric(const std::string& path, const std::string& metric);
  // The metrics the map file at `path` stores (ListMapMetrics).
  StatusOr<std::shared_ptr<const std::vector<std::string>>> Metrics(const std::string& path);

  // Reads of map files started so far (tests, and what the cache saves).
  long loads() const;
  std::size_t entries() const;
  std::size_t bytes() const;

 private:
  // A kept value: a metric or a metric list (the other pointer empty).
  struct Value {
    std::shared_ptr<const MapArray> array;
    std::shared_ptr<const std::vector<std::string>> names;
    std::size_t bytes = 0;
  };
  StatusOr<Value> GetOrLoad(const std::string& path, const std::string& what,
                            const std::function<StatusOr<Value>()>& load);
  void PutLocked(const std::string& key, const Value& v);

  const std::size_t max_entries_, max_bytes_;
  mutable std::mutex mu_;
  std::list<std::string> lru_;  // most recently used first
  struct Entry {
    Value value;
    std::list<std::string>::iterator pos;
  };
  std::map<std::string, Entry> entries_;
  std::size_t bytes_ = 0;
  long loads_ = 0;
  SingleFlight<Value> flights_;  // after the members its loads touch
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_MAP_CACHE_H_
