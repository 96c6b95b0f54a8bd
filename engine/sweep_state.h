// The life of a sweep, in one vocabulary for the index, the coordinator, the wire and the CLI.
//   queued → running → done | failed;  any active state → cancelled (by a client) or interrupted
//   (an embedded run stopped by Ctrl-C); a restarted coordinator resumes queued, running and
//   interrupted sweeps. The index stores the names below; the wire carries them as strings.
#ifndef BISTABLE_ENGINE_SWEEP_STATE_H_
#define BISTABLE_ENGINE_SWEEP_STATE_H_

#include <optional>
#include <string>
#include <string_view>

namespace bistable {

enum class SweepState { kQueued, kRunning, kDone, kFailed, kCancelled, kInterrupted };

constexpr const char* SweepStateName(SweepState s) {
  switch (s) {
    case SweepState::kQueued:
      return "queued";
    case SweepState::kRunning:
      return "running";
    case SweepState::kDone:
      return "done";
    case SweepState::kFailed:
      return "failed";
    case SweepState::kCancelled:
      return "cancelled";
    case SweepState::kInterrupted:
      return "interrupted";
  }
  return "failed";
}

constexpr std::optional<SweepState> ParseSweepState(std::string_view name) {
  for (SweepState s : {SweepState::kQueued, SweepState::kRunning, SweepState::kDone, SweepState::kFailed,
                       SweepState::kCancelled, SweepState::kInterrupted})
    if (name == SweepStateName(s)) return s;
  return std::nullopt;
}

// Done, failed or cancelled: nothing will change without a new submit.
constexpr bool IsFinal(SweepState s) {
  return s == SweepState::kDone || s == SweepState::kFailed || s == SweepState::kCancelled;
}

// What a coordinator tells about a sweep (status, listings; the wire's SweepStatus).
struct SweepInfo {
  std::string id, name, model, owner;
  SweepState state = SweepState::kQueued;
  long items_total = 0, items_done = 0, items_cached = 0;
  int workers = 0;      // workers holding a lease of this sweep now
  double seconds = 0;   // since submission (or total, when done)
  std::string file;     // published map, relative to the data dir
  std::string error;    // last storage / publication failure ("" once a report is stored again)
  double created = 0;   // unix seconds: first submitted
  double finished = 0;  // unix seconds: published (0 until done)
};

// What a coordinator tells about a worker (`bistable workers`; the wire's WorkerStatus).
struct WorkerInfo {
  std::string name;
  double last_seen = 0;  // unix seconds
  int leases = 0;        // leases held now
  long items_done = 0;   // items reported and stored
};

}  // namespace bistable

#endif  // BISTABLE_ENGINE_SWEEP_STATE_H_
