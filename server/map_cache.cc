#include "server/map_cache.h"

#include <sys/stat.h>

#include <optional>
#include <utility>

#include "storage/map_file.h"
#include "storage/metric_name.h"

namespace bistable {
namespace {

// The file's identity: device, inode, size and modification time; nullopt when it cannot be read.
std::optional<std::string> Identity(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return std::nullopt;
  return std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino) + ":" + std::to_string(st.st_size) + ":" +
         std::to_string(st.st_mtim.tv_sec) + "." + std::to_string(st.st_mtim.tv_nsec);
}

std::size_t BytesOf(const MapArray& m) {
  std::size_t n = m.values.size() * sizeof(double) + m.metric.size() + m.unit.size() + m.definition.size();
  for (const Axis& a : m.axes) n += a.values.size() * sizeof(double) + a.name.size();
  return n;
}

}  // namespace

StatusOr<MapCache::Value> MapCache::GetOrLoad(const std::string& path, const std::string& what,
                                              const std::function<StatusOr<Value>()>& load) {
  const std::optional<std::string> before = Identity(path);
  if (!before) {  // no file (or no access): the reader names the problem; nothing to key an entry by
    {
      std::lock_guard<std::mutex> lock(mu_);
      ++loads_;
    }
    return load();
  }
  const std::string key = path + "\n" + *before + "\n" + what;
  // A hit (touched as the most recent), or nullopt.
  auto cached = [&]() -> std::optional<Value> {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = entries_.find(key);
    if (it == entries_.end()) return std::nullopt;
    lru_.splice(lru_.begin(), lru_, it->second.pos);
    return it->second.value;
  };
  if (std::optional<Value> v = cached()) return *v;
  return flights_.Do(key, [&]() -> StatusOr<Value> {
    if (std::optional<Value> v = cached()) return *v;  // landed between the miss and this flight
    {
      std::lock_guard<std::mutex> lock(mu_);
      ++loads_;
    }
    StatusOr<Value> v = load();
    // Kept only when the file read is the one keyed: a file replaced meanwhile is served, not kept.
    if (v.ok() && Identity(path) == before) {
      std::lock_guard<std::mutex> lock(mu_);
      PutLocked(key, *v);
    }
    return v;
  });
}

void MapCache::PutLocked(const std::string& key, const Value& v) {
  if (v.bytes > max_bytes_ || max_entries_ == 0) return;
  while (!lru_.empty() && (entries_.size() >= max_entries_ || bytes_ + v.bytes > max_bytes_)) {
    auto it = entries_.find(lru_.back());
    bytes_ -= it->second.value.bytes;
    entries_.erase(it);
    lru_.pop_back();
  }
  lru_.push_front(key);
  entries_.emplace(key, Entry{v, lru_.begin()});
  bytes_ += v.bytes;
}

StatusOr<std::shared_ptr<const MapArray>> MapCache::Metric(const std::string& path, const std::string& metric) {
  // The name may come from a remote client: checked against the map's (kept) list before any key is made of it
  // or the file is opened for it, with ReadMapMetric's answer.
  auto names = Metrics(path);
  if (!names.ok()) return names.status();
  BISTABLE_RETURN_IF_ERROR(CheckMetricName(metric, **names));
  auto v = GetOrLoad(path, "metric:" + metric, [&]() -> StatusOr<Value> {
    auto m = ReadMapMetric(path, metric);
    if (!m.ok()) return m.status();
    Value out;
    out.bytes = BytesOf(*m);
    out.array = std::make_shared<const MapArray>(std::move(*m));
    return out;
  });
  if (!v.ok()) return v.status();
  return v->array;
}

StatusOr<std::shared_ptr<const std::vector<std::string>>> MapCache::Metrics(const std::string& path) {
  auto v = GetOrLoad(path, "metrics", [&]() -> StatusOr<Value> {
    auto names = ListMapMetrics(path);
    if (!names.ok()) return names.status();
    Value out;
    for (const auto& n : *names) out.bytes += n.size() + sizeof(std::string);
    out.names = std::make_shared<const std::vector<std::string>>(std::move(*names));
    return out;
  });
  if (!v.ok()) return v.status();
  return v->names;
}

long MapCache::loads() const {
  std::lock_guard<std::mutex> lock(mu_);
  return loads_;
}

std::size_t MapCache::entries() const {
  std::lock_guard<std::mutex> lock(mu_);
  return entries_.size();
}

std::size_t MapCache::bytes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return bytes_;
}

}  // namespace bistable
