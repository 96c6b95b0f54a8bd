// The one place a sweep's publication is started: a background thread that runs its owner's step for one
// sweep at a time, in the order they were asked for. The step publishes the sweep's map, or, for a refined
// sweep whose round is stored, plans the next round (server/sweep_coordinator.h). The report completing a
// sweep asks for it without waiting (Post); a caller that wants the outcome (the embedded run, a submit of
// a sweep found wholly stored) asks and waits (Run). A sweep asked for again while its step waits in the
// queue is not stepped twice: the waiting callers share that step's outcome. Issue 40: the coordinator's
// publisher, as leveldb's DBImpl hands background work to Env::Schedule.
#ifndef BISTABLE_SERVER_PUBLISHER_H_
#define BISTABLE_SERVER_PUBLISHER_H_

#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "base/status.h"
#include "engine/sweep_spec.h"
#include "storage/index_db.h"
#include "storage/map_file.h"
#include "storage/result_writer.h"

namespace bistable {

class Publisher {
 public:
  using Step = std::function<StatusOr<std::string>(const std::string& sweep_id)>;
  // `step` runs on the publisher's thread only; `failed` hears of every step that failed with a code
  // other than FailedPrecondition (a sweep cancelled or refining meanwhile: nothing to say) and that no
  // caller waited for.
  Publisher(Step step, std::function<void(const std::string& sweep_id, const Status&)> failed);
  // Runs the steps still queued, then stops the thread (Close).
  ~Publisher();
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  // Queues a step of `sweep_id` (unless one is queued and not started yet) and returns.
  void Post(const std::string& sweep_id);
  // Queues a step of `sweep_id` as Post does and waits for its outcome. FailedPrecondition once closed.
  // Not from the step itself (the thread would wait for itself).
  StatusOr<std::string> Run(const std::string& sweep_id);
  // Runs the queued steps, then stops the thread; later requests are refused. Idempotent.
  void Close();

  long steps() const;    // steps run since start (tests)
  long waiting() const;  // callers waiting in Run (tests)

 private:
  struct Request {
    std::string sweep_id;
    bool awaited = false;
    bool finished = false;
    StatusOr<std::string> outcome = Status::FailedPrecondition("not run");
  };
  std::shared_ptr<Request> QueueLocked(const std::string& sweep_id);
  void Loop();

  Step step_;
  std::function<void(const std::string&, const Status&)> failed_;
  mutable std::mutex mu_;
  std::condition_variable queued_cv_;  // a request was queued, or closing
  std::condition_variable done_cv_;    // a request finished
  std::deque<std::shared_ptr<Request>> queue_;
  bool closing_ = false;
  long steps_ = 0;
  long waiting_ = 0;
  std::thread thread_;  // last: started after, and joined before, what it uses
};

// What a publication writes: a sweep's map from its stored records, then its index row. The coordinator
// reads it under its lock; PublishMap runs without that lock.
struct MapPublication {
  SweepSpec spec;
  std::vector<std::string> keys;  // content keys of the items (a refined sweep: of `points`)
  std::vector<long> points;       // a refined sweep's computed grid points, ascending; empty otherwise
  SweepRow row;                   // the sweep's row as it stands
  double started = 0;             // when the sweep started (unix seconds)
  std::string path;               // the map file to write (atomically: beside, then renamed)
  std::string data_dir;           // the row's file is relative to it
  MapOrigin origin = {};          // provenance beyond the spec (a map merged from shards: `bistable merge`)
  // What the caller says of it (the coordinator's log and warnings).
  struct Outcome {
    bool incomplete = false;       // some item is missing or failed its checksum: plan the sweep again
    long corrupt = 0;              // stored results that failed their checksum
    Status folded = Status::Ok();  // moving the staged records into the keyed cache (beside the writing)
  };
};
// Gathers the records through their checksums (the staged ones folded into the cache on a second thread
// meanwhile), writes the map file (a refined sweep's finest grid filled in: engine/refine.h), and indexes
// it with its map rows (shape and range of every stored metric) in one transaction; returns the row as
// published (state done, `clock()` its finish). `before_index_row` runs between the file and the row (tests).
StatusOr<SweepRow> PublishMap(const MapPublication& m, ResultWriter& writer, const std::function<double()>& clock,
                              const std::function<void()>& before_index_row, MapPublication::Outcome* said);

}  // namespace bistable

#endif  // BISTABLE_SERVER_PUBLISHER_H_
