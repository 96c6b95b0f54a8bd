// The SQLite index of a data directory (<data>/index.sqlite, WAL mode): sweeps, their published map
// files, and the point cache (content key → PointRecord). Writes happen in transactions; a block of
// results is durable when PutPoints returns. The index names a map file only after the file has
// been completely written and renamed into place.
// Not thread-safe: one IndexDb per thread (SQLite serialises writers across connections).
#ifndef BISTABLE_STORAGE_INDEX_DB_H_
#define BISTABLE_STORAGE_INDEX_DB_H_

#include <memory>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "base/status.h"
#include "engine/metric_catalog.h"
#include "engine/sweep_state.h"

struct sqlite3;
struct sqlite3_stmt;

namespace bistable {

struct SweepRow {
  std::string id;  // 12 hex digits (hash of the canonical spec)
  std::string name;
  std::string model;
  std::string spec;                        // the TOML as given
  SweepState state = SweepState::kQueued;  // stored as its name
  long items_total = 0;                    // grid points × initial conditions (SQL columns points_total / points_done)
  long items_done = 0;
  std::string file;    // map file path relative to the data dir, "" until published
  double created = 0;  // unix seconds
  double finished = 0;
  double seconds = 0;  // wall time of the last run
  std::string owner;   // identity of the token that submitted it ("local" without tokens)
};

// One published map dataset: what `bistable sweeps --json` and clients can list without opening HDF5.
struct MapRow {
  std::string sweep_id, metric, file;
  std::string shape;        // "201x201" (axis lengths, then ic / peak dims)
  double min = 0, max = 0;  // over finite values (NaN when none)
};

class IndexDb {
 public:
  ~IndexDb();
  // Opens or creates <path>; the message names the path on failure (unwritable dir, corrupt file).
  static StatusOr<std::unique_ptr<IndexDb>> Open(const std::string& path);
  // SQLite's quick_check of the index file at `path` (every page and B-tree, not the records themselves:
  // their checksums are checked where they are read), on a connection of its own that writes nothing (no
  // checkpoint on close either), before the index is opened for use. "" when sound (or no file, or an empty
  // one: a new index), else the first problem (a file that is not a database at all included). Reads the
  // whole file (measured: 0.3 s for an index of 437 MB, 10^6 points, in the page cache).
  static StatusOr<std::string> QuickCheck(const std::string& path);
  // What could be read of a damaged index at `old_path` (opened read-only, each table read until its first
  // error), copied into this one: sweeps not published (to resume; published ones come back from their map
  // files), the point cache and staged reports (checksums come along and are verified where they are read).
  struct Salvaged {
    long sweeps = 0, points = 0, staged = 0;
  };
  StatusOr<Salvaged> SalvageFrom(const std::string& old_path);

  Status UpsertSweep(const SweepRow& row);
  // Marks a sweep published: its row (status done, file) and its map rows, in one transaction.
  Status PublishSweep(const SweepRow& row, const std::vector<MapRow>& maps);
  StatusOr<std::vector<MapRow>> ListMaps(const std::string& sweep_id);
  StatusOr<std::optional<SweepRow>> GetSweep(const std::string& id_or_prefix);
  StatusOr<std::vector<SweepRow>> ListSweeps();

  // Looks up many keys in one read transaction; the result holds the ones found with `record_size`
  // doubles whose checksum holds (a record of another layout is treated as missing and recomputed;
  // so is a corrupt one, counted in *corrupt).
  // Staged records are folded into the keyed cache first (kNow), or read where they are staged and left
  // there (kLater: the caller folds them afterwards, e.g. on another thread while it writes the map).
  enum class Fold { kNow, kLater };
  StatusOr<std::unordered_map<std::string, PointRecord>> LookupPoints(const std::vector<std::string>& keys,
                                                                      size_t record_size, long* corrupt = nullptr,
                                                                      Fold fold = Fold::kNow);
  // Stores the records of one or more reported jobs in one transaction (all or nothing) and, in the
  // same transaction, adds each job's item count to its sweep's items_done. The records are staged
  // as one appended row per job (a few pages per commit, where keyed inserts cost a page per point)
  // and folded into the keyed cache by the next LookupPoints / CachedPointCount / FoldResults.
  // A report's records as the coordinator received them: no per-item copies.
  struct JobResults {
    std::string sweep_id;
    size_t width = 0;            // doubles per record
    std::string keys;            // content keys, each ended by '\n', in record order
    std::vector<double> values;  // records × width, in the same order
  };
  Status PutPoints(const std::vector<JobResults>& jobs);
  // Moves every staged job row into the keyed point cache (sorted inserts, bounded transactions); with
  // `folded`, also hands back each folded record by key (the later one where a key repeats).
  Status FoldResults(std::unordered_map<std::string, std::vector<double>>* folded = nullptr);
  // Every staged record by key (the later one where a key repeats), checksums verified, left staged.
  Status ReadStaged(std::unordered_map<std::string, std::vector<double>>* staged);
  long CachedPointCount();
  // Staged rows dropped by FoldResults because their checksum failed, since Open.
  long corrupt_rows() const { return corrupt_rows_; }
  // WAL checkpoints off the writers' path: a second connection runs PASSIVE checkpoints (they copy
  // committed frames into the database while writers go on appending); the writer's own automatic
  // checkpoint is then only a safety net at `pages`.
  Status SetAutoCheckpoint(int pages);
  Status CheckpointPassive();
  // The connection's page cache in KiB (a checkpoint-only connection needs next to none).
  Status SetCacheKib(int kib);

 private:
  explicit IndexDb(sqlite3* db) : db_(db) {}
  // A prepared statement kept for the connection's lifetime (reset, bindings cleared); nullptr on error.
  sqlite3_stmt* Cached(const char* sql);
  // Up to `limit` staged rows after `after_seq` in staging order, split into records (a row whose
  // checksum fails is skipped whole, counted in corrupt_rows_ when `count_corrupt`); the last seq read,
  // −1 when there was none.
  struct StagedEntry {
    std::string key;
    long order;
    std::vector<double> v;
  };
  StatusOr<long> ReadStagedRows(long after_seq, int limit, bool count_corrupt, std::vector<StagedEntry>* entries);
  Status Exec(const std::string& sql);
  Status Error(const std::string& what);
  sqlite3* db_;
  long corrupt_rows_ = 0;
  std::unordered_map<const char*, sqlite3_stmt*> cached_;  // keyed by the literal's address
};

}  // namespace bistable

#endif  // BISTABLE_STORAGE_INDEX_DB_H_
