#include "server/publisher.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <system_error>

#include "engine/metric_catalog.h"
#include "engine/sweep_kind.h"
#include "storage/map_file.h"

namespace bistable {

Publisher::Publisher(Step step, std::function<void(const std::string&, const Status&)> failed)
    : step_(std::move(step)), failed_(std::move(failed)), thread_([this] { Loop(); }) {}

Publisher::~Publisher() { Close(); }

void Publisher::Close() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    closing_ = true;
  }
  queued_cv_.notify_all();
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

std::shared_ptr<Publisher::Request> Publisher::QueueLocked(const std::string& sweep_id) {
  for (const auto& r : queue_)  // queued, not started: its step will see everything this caller would
    if (r->sweep_id == sweep_id) return r;
  auto r = std::make_shared<Request>();
  r->sweep_id = sweep_id;
  queue_.push_back(r);
  queued_cv_.notify_one();
  return r;
}

void Publisher::Post(const std::string& sweep_id) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!closing_) QueueLocked(sweep_id);
}

StatusOr<std::string> Publisher::Run(const std::string& sweep_id) {
  std::unique_lock<std::mutex> lock(mu_);
  if (closing_) return Status::FailedPrecondition("the publisher is closing");
  std::shared_ptr<Request> r = QueueLocked(sweep_id);
  r->awaited = true;
  ++waiting_;
  done_cv_.wait(lock, [&] { return r->finished; });
  --waiting_;
  return r->outcome;
}

void Publisher::Loop() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    queued_cv_.wait(lock, [&] { return closing_ || !queue_.empty(); });
    if (queue_.empty()) return;  // closing, nothing left
    std::shared_ptr<Request> r = queue_.front();
    queue_.pop_front();
    lock.unlock();
    StatusOr<std::string> outcome = step_(r->sweep_id);
    lock.lock();
    ++steps_;
    r->outcome = std::move(outcome);
    r->finished = true;
    const bool awaited = r->awaited;
    done_cv_.notify_all();
    if (!awaited && !r->outcome.ok() && r->outcome.status().code() != Status::Code::kFailedPrecondition && failed_) {
      const Status st = r->outcome.status();
      lock.unlock();
      failed_(r->sweep_id, st);
      lock.lock();
    }
  }
}

long Publisher::steps() const {
  std::lock_guard<std::mutex> lock(mu_);
  return steps_;
}

long Publisher::waiting() const {
  std::lock_guard<std::mutex> lock(mu_);
  return waiting_;
}

StatusOr<SweepRow> PublishMap(const MapPublication& m, ResultWriter& writer, const std::function<double()>& clock,
                              const std::function<void()>& before_index_row, MapPublication::Outcome* said) {
  const SweepSpec& spec = m.spec;
  const std::vector<std::string>& keys = m.keys;
  const SweepRow& row = m.row;
  const std::string& path = m.path;
  bool* incomplete = &said->incomplete;
  // Every record is read back through its checksum: a corrupt one counts as missing. The staged
  // records are read where they are staged; moving them into the keyed point cache (SQLite inserts,
  // as long as the map's HDF5 writing) runs on a second thread beside the writing, and ends before the
  // index row: a crash in between leaves them staged, folded by the next lookup.
  long corrupt = 0;
  auto found = writer.Db()->LookupPoints(
      keys, PointRecord::Size(spec.base.metrics.turning_points, spec.base.metrics.poincare_points), &corrupt,
      IndexDb::Fold::kLater);
  if (!found.ok()) return found.status();
  Status folded = Status::Ok();
  std::thread folder;
  try {
    folder = std::thread([&writer, &folded] { folded = writer.Db()->FoldResults(); });
  } catch (const std::system_error&) {  // no thread to be had: fold here
    folded = writer.Db()->FoldResults();
  }
  struct Join {
    std::thread& t;
    ~Join() {
      if (t.joinable()) t.join();
    }
  } join{folder};
  said->corrupt = corrupt;
  std::vector<PointRecord> records;
  records.reserve(keys.size());
  for (const std::string& k : keys) {
    auto it = found->find(k);
    if (it == found->end()) {
      *incomplete = true;
      return Status::FailedPrecondition("sweep " + row.id +
                                        " is incomplete: " + std::to_string(keys.size() - found->size()) +
                                        " items are not stored (or failed their checksum)");
    }
    records.push_back(it->second);  // a copy: two items of a sweep can share a key (equal initial states)
  }
  SweepRow done = row;
  done.items_done = static_cast<long>(records.size());
  if (const SweepKind& kind = KindOf(spec); kind.InRounds()) {  // the finest grid, from the computed points
    auto refined = kind.Fill(spec, m.points, records);
    if (!refined.ok()) {
      *incomplete = refined.status().code() == Status::Code::kFailedPrecondition;
      return refined.status();
    }
    RefinedGrid grid = std::move(refined).value();
    BISTABLE_RETURN_IF_ERROR(WriteMapFile(path, spec, grid));
    records = std::move(grid.records);  // the map rows' ranges are those of the map as written
  } else {
    BISTABLE_RETURN_IF_ERROR(WriteMapFile(path, spec, records, m.origin));
  }
  done.state = SweepState::kDone;
  done.file = std::filesystem::relative(path, m.data_dir).string();
  done.finished = clock();
  done.seconds = done.finished - m.started;
  // Map rows: shape and range of every stored metric, for listings that need not open HDF5.
  const std::string shape = MapShape(spec);
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
  if (folder.joinable()) folder.join();
  if (before_index_row) before_index_row();
  said->folded = folded;  // if not ok, the records stay staged and are folded by a later lookup; the map is whole
  BISTABLE_RETURN_IF_ERROR(writer.Db()->PublishSweep(done, maps));
  return done;
}

}  // namespace bistable
