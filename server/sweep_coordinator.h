// The coordinator of sweeps over one data directory: plans a sweep against the point cache, hands
// out jobs (contiguous runs of missing items), persists each reported job durably in one
// transaction, and publishes the HDF5 map once every item is stored. The embedded `bistable run`
// drives it with in-process worker threads; the gRPC service (issue 4) will drive the same class.
// Thread-safe: every public method may be called from any thread.
#ifndef BISTABLE_SERVER_SWEEP_COORDINATOR_H_
#define BISTABLE_SERVER_SWEEP_COORDINATOR_H_

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "engine/sweep_spec.h"
#include "storage/index_db.h"
#include "engine/metric_catalog.h"

namespace bistable {

struct Job {
  long id = 0;
  std::vector<WorkItem> items;
};

struct SweepPlan {
  std::string id;
  long items_total = 0;    // grid points × initial conditions
  long items_cached = 0;   // already stored under their content key (reused, not recomputed)
  long jobs = 0;
  bool already_published = false;  // done before, map file present: nothing to do
};

struct SweepProgress {
  long items_total = 0, items_done = 0, items_cached = 0;
};

class SweepCoordinator {
 public:
  // Opens <data>/index.sqlite and <data>/sweeps/, creating them; the message names the directory
  // when it cannot be written.
  static StatusOr<std::unique_ptr<SweepCoordinator>> Open(const std::string& data_dir);

  // Registers the sweep (id = hash of its canonical spec), looks every item up in the point cache and
  // queues the missing ones as jobs of about `job_items` items.
  StatusOr<SweepPlan> Submit(const SweepSpec& spec, long job_items);
  // The next queued job, or nullopt when none is left (or after Stop()).
  std::optional<Job> Lease();
  // Stores a job's records (one transaction). A job reported twice is acknowledged and not stored again.
  Status Report(long job_id, const std::vector<PointRecord>& records);
  // Gathers every record from the cache, writes the map file atomically and marks the sweep done.
  // Returns the map file's path.
  StatusOr<std::string> Publish();
  // Marks the sweep interrupted (finished jobs stay stored; a rerun resumes).
  Status MarkInterrupted();
  void Stop();

  SweepProgress progress() const;
  const std::string& data_dir() const { return data_dir_; }
  const SweepSpec& spec() const { return spec_; }
  std::string MapPath(const std::string& id) const;

 private:
  SweepCoordinator(std::string dir, std::unique_ptr<IndexDb> db) : data_dir_(std::move(dir)), db_(std::move(db)) {}
  std::vector<std::string> KeysFor(const std::vector<WorkItem>& items) const;

  mutable std::mutex mu_;
  std::string data_dir_;
  std::unique_ptr<IndexDb> db_;
  SweepSpec spec_;
  SweepRow row_;
  std::vector<std::string> keys_;  // content key of item point·ic_count + ic
  std::vector<Job> queue_;
  size_t next_job_ = 0;
  std::vector<bool> reported_;
  long items_done_ = 0, items_cached_ = 0;
  bool stopped_ = false;
  double started_ = 0;
};

}  // namespace bistable

#endif  // BISTABLE_SERVER_SWEEP_COORDINATOR_H_
