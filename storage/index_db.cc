#include "storage/index_db.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/stat.h>
#include <unistd.h>

#define XXH_INLINE_ALL
#include <xxhash.h>

#include <algorithm>
#include <cstring>
#include <functional>

#include "storage/data_dir.h"

namespace bistable {
namespace {

#define SWEEP_COLUMNS "id,name,model,spec,status,points_total,points_done,file,created,finished,seconds,owner"

// Checksum of a stored result: XXH3-64 over its key and its values' bytes, so a flipped byte in
// either (or a record moved to another key) is caught when read back.
uint64_t RecordSum(const char* key, size_t key_len, const double* v, size_t n) {
  XXH3_state_t st;
  XXH3_64bits_reset(&st);
  XXH3_64bits_update(&st, key, key_len);
  XXH3_64bits_update(&st, v, n * sizeof(double));
  return XXH3_64bits_digest(&st);
}

// RAII prepared statement.
class Stmt {
 public:
  Stmt(sqlite3* db, const char* sql) { rc_ = sqlite3_prepare_v2(db, sql, -1, &s_, nullptr); }
  ~Stmt() { sqlite3_finalize(s_); }
  bool ok() const { return rc_ == SQLITE_OK; }
  sqlite3_stmt* get() { return s_; }
  void Text(int i, const std::string& v) {
    sqlite3_bind_text(s_, i, v.c_str(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
  }
  void Int(int i, long v) { sqlite3_bind_int64(s_, i, v); }
  void Real(int i, double v) { sqlite3_bind_double(s_, i, v); }
  std::string ColText(int i) {
    const unsigned char* t = sqlite3_column_text(s_, i);
    return t ? reinterpret_cast<const char*>(t) : "";
  }

 private:
  sqlite3_stmt* s_ = nullptr;
  int rc_;
};

// A transaction that rolls back unless committed: every multi-statement write is all or nothing.
class Transaction {
 public:
  Transaction(sqlite3* db, const char* begin) : db_(db) {
    ok_ = sqlite3_exec(db, begin, nullptr, nullptr, nullptr) == SQLITE_OK;
  }
  ~Transaction() {
    if (ok_ && !done_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  bool ok() const { return ok_; }
  bool Commit() { return done_ = sqlite3_exec(db_, "COMMIT", nullptr, nullptr, nullptr) == SQLITE_OK; }

 private:
  sqlite3* db_;
  bool ok_ = false, done_ = false;
};

constexpr const char* kSchema = R"sql(
CREATE TABLE IF NOT EXISTS sweeps(
  id TEXT PRIMARY KEY, name TEXT, model TEXT, spec TEXT, status TEXT,
  points_total INTEGER, points_done INTEGER, file TEXT, created REAL, finished REAL, seconds REAL);
CREATE TABLE IF NOT EXISTS points(
  key TEXT PRIMARY KEY, record BLOB NOT NULL, created REAL) WITHOUT ROWID;
CREATE TABLE IF NOT EXISTS maps(
  sweep_id TEXT NOT NULL, metric TEXT NOT NULL, file TEXT NOT NULL, shape TEXT, min REAL, max REAL,
  PRIMARY KEY(sweep_id, metric));
CREATE TABLE IF NOT EXISTS meta(k TEXT PRIMARY KEY, v TEXT);
CREATE TABLE IF NOT EXISTS results(
  seq INTEGER PRIMARY KEY, sweep_id TEXT NOT NULL, width INTEGER NOT NULL, keys TEXT NOT NULL, records BLOB NOT NULL);
INSERT OR IGNORE INTO meta VALUES('schema', '1');
)sql";

// Schema 2: sweeps.owner (who submitted), results.sum (checksum of the staged row), and point records
// followed by an 8-byte checksum (records of schema 1, without one, read as missing and are recomputed).
constexpr const char* kMigrate2 = R"sql(
ALTER TABLE sweeps ADD COLUMN owner TEXT NOT NULL DEFAULT '';
ALTER TABLE results ADD COLUMN sum INTEGER;
UPDATE meta SET v = '2' WHERE k = 'schema';
)sql";

SweepRow ReadSweep(Stmt& s) {
  SweepRow r;
  r.id = s.ColText(0);
  r.name = s.ColText(1);
  r.model = s.ColText(2);
  r.spec = s.ColText(3);
  r.state = ParseSweepState(s.ColText(4)).value_or(SweepState::kFailed);  // an unknown name: not resumed
  r.items_total = sqlite3_column_int64(s.get(), 5);
  r.items_done = sqlite3_column_int64(s.get(), 6);
  r.file = s.ColText(7);
  r.created = sqlite3_column_double(s.get(), 8);
  r.finished = sqlite3_column_double(s.get(), 9);
  r.seconds = sqlite3_column_double(s.get(), 10);
  r.owner = s.ColText(11);
  return r;
}

}  // namespace

IndexDb::~IndexDb() {
  for (auto& [sql, st] : cached_) sqlite3_finalize(st);
  sqlite3_close(db_);
}

sqlite3_stmt* IndexDb::Cached(const char* sql) {
  sqlite3_stmt*& st = cached_[sql];
  if (!st && sqlite3_prepare_v3(db_, sql, -1, SQLITE_PREPARE_PERSISTENT, &st, nullptr) != SQLITE_OK) {
    sqlite3_finalize(st);
    st = nullptr;
    return nullptr;
  }
  sqlite3_reset(st);
  sqlite3_clear_bindings(st);
  return st;
}

Status IndexDb::Error(const std::string& what) {
  const int code = sqlite3_errcode(db_);
  std::string why = sqlite3_errmsg(db_);
  if (code == SQLITE_FULL) why = "disk full: " + why;
  return Status::IoError("index", what + ": " + why);
}

Status IndexDb::Exec(const std::string& sql) {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    std::string msg = err ? err : "?";
    sqlite3_free(err);
    return Status::IoError("index", msg);
  }
  return Status::Ok();
}

StatusOr<std::unique_ptr<IndexDb>> IndexDb::Open(const std::string& path) {
  // A new index is created here with kDataFileMode (SQLite would take 0644; its WAL and shared-memory
  // files take the index's mode); SQLite reads an empty file as an empty database.
  if (const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, static_cast<mode_t>(kDataFileMode));
      fd >= 0)
    ::close(fd);
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr) !=
      SQLITE_OK) {
    std::string why = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    return Status::IoError("data", "cannot open index '" + path + "': " + why);
  }
  std::unique_ptr<IndexDb> idx(new IndexDb(db));
  sqlite3_busy_timeout(db, 10000);
  // WAL with synchronous=NORMAL: a committed transaction survives a crash of the process (kill -9); a
  // checkpoint every 10,000 pages (~40 MB) instead of 1,000 keeps fsyncs off the report path.
  for (const char* pragma : {"PRAGMA journal_mode=WAL", "PRAGMA synchronous=NORMAL", "PRAGMA foreign_keys=ON",
                             "PRAGMA wal_autocheckpoint=10000"}) {
    Status st = idx->Exec(pragma);
    if (!st.ok()) return Status::IoError("data", "index '" + path + "': " + st.message());
  }
  Status st = idx->Exec(kSchema);
  if (!st.ok()) return Status::IoError("data", "index '" + path + "': " + st.message());
  std::string schema;
  {
    Stmt v(db, "SELECT v FROM meta WHERE k = 'schema'");
    if (v.ok() && sqlite3_step(v.get()) == SQLITE_ROW) schema = v.ColText(0);
  }
  if (schema == "1") {
    Transaction tx(db, "BEGIN IMMEDIATE");
    st = tx.ok() ? idx->Exec(kMigrate2) : Status::IoError("index", "cannot begin the schema migration");
    if (!st.ok() || !tx.Commit())
      return Status::IoError("data", "index '" + path + "': migrating to schema 2: " + st.message());
  } else if (schema != "2") {
    return Status::IoError(
        "data", "index '" + path + "' has schema '" + schema + "', this program reads schema 2 (newer program?)");
  }
  return idx;
}

StatusOr<std::string> IndexDb::QuickCheck(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0 || st.st_size == 0) return std::string();  // a new index
  sqlite3* db = nullptr;
  const int rc = sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_NOMUTEX, nullptr);
  struct Close {
    sqlite3* db;
    ~Close() { sqlite3_close(db); }
  } close{db};
  if (rc != SQLITE_OK)
    return Status::IoError("data", "cannot open index '" + path + "': " + (db ? sqlite3_errmsg(db) : "out of memory"));
  sqlite3_db_config(db, SQLITE_DBCONFIG_NO_CKPT_ON_CLOSE, 1, nullptr);  // the file stays as it was found
  sqlite3_busy_timeout(db, 10000);
  std::string problem;
  Stmt s(db, "PRAGMA quick_check(1)");
  const int step = s.ok() ? sqlite3_step(s.get()) : sqlite3_errcode(db);
  if (step == SQLITE_ROW) {
    problem = s.ColText(0);
    if (problem == "ok") problem.clear();
  } else {
    const int code = sqlite3_errcode(db) & 0xff;
    if (code != SQLITE_CORRUPT && code != SQLITE_NOTADB)  // busy, out of memory, I/O: not the file's damage
      return Status::IoError("data", "index '" + path + "': " + sqlite3_errmsg(db));
    problem = sqlite3_errmsg(db);
  }
  for (char& c : problem) c = c == '\n' ? ' ' : c;  // one line
  return problem;
}

StatusOr<IndexDb::Salvaged> IndexDb::SalvageFrom(const std::string& old_path) {
  Salvaged n;
  sqlite3* old = nullptr;
  if (sqlite3_open_v2(old_path.c_str(), &old, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
    sqlite3_close(old);
    return n;  // nothing can be read
  }
  struct Close {
    sqlite3* db;
    ~Close() { sqlite3_close(db); }
  } close{old};
  Transaction tx(db_, "BEGIN IMMEDIATE");
  if (!tx.ok()) return Error("begin salvage");
  // Each table row by row, until the end or its first unreadable page.
  const auto copy = [&](const char* select, const char* insert, int columns, long* count,
                        const std::function<bool(Stmt&)>& keep) -> Status {
    Stmt from(old, select);
    Stmt to(db_, insert);
    if (!from.ok()) return Status::Ok();  // the table cannot be read at all
    if (!to.ok()) return Error("prepare salvage");
    while (sqlite3_step(from.get()) == SQLITE_ROW) {
      if (keep && !keep(from)) continue;
      sqlite3_reset(to.get());
      for (int c = 0; c < columns; ++c) sqlite3_bind_value(to.get(), c + 1, sqlite3_column_value(from.get(), c));
      if (sqlite3_step(to.get()) != SQLITE_DONE) return Error("salvage a row");
      ++*count;
    }
    return Status::Ok();
  };
  BISTABLE_RETURN_IF_ERROR(copy("SELECT " SWEEP_COLUMNS " FROM sweeps",
                                "INSERT OR IGNORE INTO sweeps(" SWEEP_COLUMNS ") VALUES(?,?,?,?,?,?,?,?,?,?,?,?)", 12,
                                &n.sweeps, [](Stmt& r) { return r.ColText(4) != SweepStateName(SweepState::kDone); }));
  BISTABLE_RETURN_IF_ERROR(copy("SELECT key, record, created FROM points",
                                "INSERT OR IGNORE INTO points(key, record, created) VALUES(?,?,?)", 3, &n.points,
                                nullptr));
  BISTABLE_RETURN_IF_ERROR(copy("SELECT sweep_id, width, keys, records, sum FROM results ORDER BY seq",
                                "INSERT INTO results(sweep_id, width, keys, records, sum) VALUES(?,?,?,?,?)", 5,
                                &n.staged, nullptr));
  if (!tx.Commit()) return Error("commit salvage");
  return n;
}

Status IndexDb::SetAutoCheckpoint(int pages) { return Exec("PRAGMA wal_autocheckpoint=" + std::to_string(pages)); }

Status IndexDb::SetCacheKib(int kib) { return Exec("PRAGMA cache_size=-" + std::to_string(kib)); }

Status IndexDb::CheckpointPassive() {
  const int rc = sqlite3_wal_checkpoint_v2(db_, nullptr, SQLITE_CHECKPOINT_PASSIVE, nullptr, nullptr);
  return rc == SQLITE_OK || rc == SQLITE_BUSY ? Status::Ok() : Error("checkpoint");
}

Status IndexDb::UpsertSweep(const SweepRow& r) {
  Stmt s(db_,
         "INSERT INTO sweeps(id,name,model,spec,status,points_total,points_done,file,created,finished,seconds,owner) "
         "VALUES(?,?,?,?,?,?,?,?,?,?,?,?) ON CONFLICT(id) DO UPDATE SET name=excluded.name, status=excluded.status, "
         "points_total=excluded.points_total, points_done=excluded.points_done, file=excluded.file, "
         "finished=excluded.finished, seconds=excluded.seconds, spec=excluded.spec, owner=excluded.owner");
  if (!s.ok()) return Error("prepare sweep upsert");
  s.Text(1, r.id);
  s.Text(2, r.name);
  s.Text(3, r.model);
  s.Text(4, r.spec);
  s.Text(5, SweepStateName(r.state));
  s.Int(6, r.items_total);
  s.Int(7, r.items_done);
  s.Text(8, r.file);
  s.Real(9, r.created);
  s.Real(10, r.finished);
  s.Real(11, r.seconds);
  s.Text(12, r.owner);
  if (sqlite3_step(s.get()) != SQLITE_DONE) return Error("write sweep " + r.id);
  return Status::Ok();
}

Status IndexDb::PublishSweep(const SweepRow& row, const std::vector<MapRow>& maps) {
  Transaction tx(db_, "BEGIN IMMEDIATE");
  if (!tx.ok()) return Error("begin publication");
  BISTABLE_RETURN_IF_ERROR(UpsertSweep(row));
  Stmt del(db_, "DELETE FROM maps WHERE sweep_id = ?");
  del.Text(1, row.id);
  if (sqlite3_step(del.get()) != SQLITE_DONE) return Error("clear map rows");
  Stmt ins(db_, "INSERT INTO maps(sweep_id, metric, file, shape, min, max) VALUES(?,?,?,?,?,?)");
  if (!ins.ok()) return Error("prepare map rows");
  for (const MapRow& m : maps) {
    sqlite3_reset(ins.get());
    ins.Text(1, row.id);
    ins.Text(2, m.metric);
    ins.Text(3, m.file);
    ins.Text(4, m.shape);
    ins.Real(5, m.min);
    ins.Real(6, m.max);
    if (sqlite3_step(ins.get()) != SQLITE_DONE) return Error("write map row " + m.metric);
  }
  if (!tx.Commit()) return Error("commit publication");
  return Status::Ok();
}

StatusOr<std::vector<MapRow>> IndexDb::ListMaps(const std::string& sweep_id) {
  Stmt s(db_, "SELECT sweep_id, metric, file, shape, min, max FROM maps WHERE sweep_id = ? ORDER BY metric");
  if (!s.ok()) return Error("prepare map list");
  s.Text(1, sweep_id);
  std::vector<MapRow> rows;
  while (sqlite3_step(s.get()) == SQLITE_ROW)
    rows.push_back({s.ColText(0), s.ColText(1), s.ColText(2), s.ColText(3), sqlite3_column_double(s.get(), 4),
                    sqlite3_column_double(s.get(), 5)});
  return rows;
}

StatusOr<std::optional<SweepRow>> IndexDb::GetSweep(const std::string& id) {
  Stmt s(db_, "SELECT " SWEEP_COLUMNS
              " FROM sweeps WHERE id = ? OR substr(id, 1, length(?)) = ? ORDER BY id = ? DESC LIMIT 2");
  if (!s.ok()) return Error("prepare sweep lookup");
  s.Text(1, id);
  s.Text(2, id);
  s.Text(3, id);
  s.Text(4, id);
  std::vector<SweepRow> rows;
  while (sqlite3_step(s.get()) == SQLITE_ROW) rows.push_back(ReadSweep(s));
  if (rows.empty()) return std::optional<SweepRow>();
  if (rows.size() > 1 && rows[0].id != id)
    return Status::InvalidArgument(
        "id", "sweep id prefix '" + id + "' is ambiguous (" + rows[0].id + ", " + rows[1].id + ", ...)");
  return std::optional<SweepRow>(rows[0]);
}

StatusOr<std::vector<SweepRow>> IndexDb::ListSweeps() {
  Stmt s(db_, "SELECT " SWEEP_COLUMNS " FROM sweeps ORDER BY created");
  if (!s.ok()) return Error("prepare sweep list");
  std::vector<SweepRow> rows;
  while (sqlite3_step(s.get()) == SQLITE_ROW) rows.push_back(ReadSweep(s));
  return rows;
}

StatusOr<std::unordered_map<std::string, PointRecord>> IndexDb::LookupPoints(const std::vector<std::string>& keys,
                                                                             size_t record_size, long* corrupt,
                                                                             Fold fold) {
  // Staged records (folded just now, or read where they are staged) come from rows whose checksum was
  // verified: they are taken from memory instead of being read back by key (at publication that is
  // every computed point).
  std::unordered_map<std::string, std::vector<double>> folded;
  BISTABLE_RETURN_IF_ERROR(fold == Fold::kNow ? FoldResults(&folded) : ReadStaged(&folded));
  if (corrupt) *corrupt = 0;
  std::unordered_map<std::string, PointRecord> found;
  found.reserve(keys.size());
  std::vector<const std::string*> order;
  order.reserve(keys.size());
  for (const std::string& k : keys) {
    auto it = folded.find(k);
    if (it == folded.end()) {
      order.push_back(&k);
    } else if (it->second.size() == record_size) {  // another layout: recompute
      PointRecord r;
      r.v = std::move(it->second);
      found.emplace(k, std::move(r));
      folded.erase(it);
    }
  }
  if (order.empty()) return found;
  Transaction tx(db_, "BEGIN");  // one read snapshot for all keys
  if (!tx.ok()) return Error("begin point lookup");
  Stmt s(db_, "SELECT record FROM points WHERE key = ?");
  if (!s.ok()) return Error("prepare point lookup");
  const size_t n = record_size;
  // In key order: consecutive lookups walk the B-tree's leaves in order, each page read once (in grid
  // order they land on random pages, most of them outside the page cache).
  std::sort(order.begin(), order.end(), [](const std::string* a, const std::string* b) { return *a < *b; });
  for (const std::string* kp : order) {
    const std::string& k = *kp;
    sqlite3_reset(s.get());
    s.Text(1, k);
    if (sqlite3_step(s.get()) == SQLITE_ROW) {
      const int bytes = sqlite3_column_bytes(s.get(), 0);
      if (bytes != static_cast<int>(n * sizeof(double) + sizeof(uint64_t))) continue;  // another layout: recompute
      PointRecord r;
      r.v.resize(n);
      const auto* blob = static_cast<const unsigned char*>(sqlite3_column_blob(s.get(), 0));
      std::memcpy(r.v.data(), blob, n * sizeof(double));
      uint64_t sum = 0;
      std::memcpy(&sum, blob + n * sizeof(double), sizeof sum);
      if (sum != RecordSum(k.data(), k.size(), r.v.data(), n)) {  // corrupt: treated as missing, recomputed
        if (corrupt) ++*corrupt;
        continue;
      }
      found.emplace(k, std::move(r));
    }
  }
  sqlite3_reset(s.get());  // no statement in progress at commit
  tx.Commit();
  return found;
}

Status IndexDb::PutPoints(const std::vector<JobResults>& jobs) {
  Transaction tx(db_, "BEGIN IMMEDIATE");
  if (!tx.ok()) return Error("begin point results");
  // One appended row per job (its keys and its records as one blob): consecutive rowids fill one B-tree
  // leaf after another, so a job costs a few pages instead of one page per (randomly keyed) point.
  sqlite3_stmt* ins = Cached("INSERT INTO results(sweep_id, width, keys, records, sum) VALUES(?, ?, ?, ?, ?)");
  sqlite3_stmt* progress = Cached("UPDATE sweeps SET points_done = points_done + ? WHERE id = ?");
  if (!ins || !progress) return Error("prepare point results");
  for (const JobResults& job : jobs) {
    const size_t n = static_cast<size_t>(std::count(job.keys.begin(), job.keys.end(), '\n'));
    if (job.width == 0 || job.values.size() != n * job.width || (!job.keys.empty() && job.keys.back() != '\n'))
      return Status::InvalidArgument("records", std::to_string(n) + " keys do not match " +
                                                    std::to_string(job.values.size()) + " values of width " +
                                                    std::to_string(job.width));
    if (n > 0) {
      sqlite3_reset(ins);
      sqlite3_bind_text(ins, 1, job.sweep_id.c_str(), static_cast<int>(job.sweep_id.size()), SQLITE_STATIC);
      sqlite3_bind_int64(ins, 2, static_cast<sqlite3_int64>(job.width));
      sqlite3_bind_text(ins, 3, job.keys.c_str(), static_cast<int>(job.keys.size()), SQLITE_STATIC);
      sqlite3_bind_blob(ins, 4, job.values.data(), static_cast<int>(job.values.size() * sizeof(double)), SQLITE_STATIC);
      sqlite3_bind_int64(ins, 5,
                         static_cast<sqlite3_int64>(
                             RecordSum(job.keys.data(), job.keys.size(), job.values.data(), job.values.size())));
      if (sqlite3_step(ins) != SQLITE_DONE) return Error("store point results");
      sqlite3_reset(ins);
    }
    sqlite3_reset(progress);
    sqlite3_bind_int64(progress, 1, static_cast<sqlite3_int64>(n));
    sqlite3_bind_text(progress, 2, job.sweep_id.c_str(), static_cast<int>(job.sweep_id.size()), SQLITE_STATIC);
    if (sqlite3_step(progress) != SQLITE_DONE) return Error("update progress");
    sqlite3_reset(progress);
  }
  if (!tx.Commit()) return Error("commit point results");
  return Status::Ok();
}

StatusOr<long> IndexDb::ReadStagedRows(long after_seq, int limit, bool count_corrupt,
                                       std::vector<StagedEntry>* entries) {
  sqlite3_stmt* sel = Cached("SELECT seq, width, keys, records, sum FROM results WHERE seq > ? ORDER BY seq LIMIT ?");
  if (!sel) return Error("prepare result scan");
  sqlite3_bind_int64(sel, 1, after_seq);
  sqlite3_bind_int(sel, 2, limit);
  long last_seq = -1;
  int rc;
  while ((rc = sqlite3_step(sel)) == SQLITE_ROW) {
    last_seq = sqlite3_column_int64(sel, 0);
    const size_t width = static_cast<size_t>(sqlite3_column_int64(sel, 1));
    const char* keys = reinterpret_cast<const char*>(sqlite3_column_text(sel, 2));
    const auto* vals = static_cast<const double*>(sqlite3_column_blob(sel, 3));
    const size_t nvals = static_cast<size_t>(sqlite3_column_bytes(sel, 3)) / sizeof(double);
    const size_t key_bytes = static_cast<size_t>(sqlite3_column_bytes(sel, 2));
    // A staged row whose checksum fails is dropped whole: its points are missing and recomputed.
    if (sqlite3_column_type(sel, 4) != SQLITE_NULL &&
        static_cast<uint64_t>(sqlite3_column_int64(sel, 4)) !=
            RecordSum(keys ? keys : "", keys ? key_bytes : 0, vals, nvals)) {
      if (count_corrupt) ++corrupt_rows_;
      continue;
    }
    if (width == 0) continue;
    size_t k = 0;
    for (const char* p = keys; p && *p; ++k) {
      const char* nl = std::strchr(p, '\n');
      if (!nl || (k + 1) * width > nvals) break;  // a malformed row: stop (its points are recomputed)
      entries->push_back({std::string(p, nl), static_cast<long>(entries->size()),
                          std::vector<double>(vals + k * width, vals + (k + 1) * width)});
      p = nl + 1;
    }
  }
  sqlite3_reset(sel);
  if (rc != SQLITE_DONE) return Error("scan staged results");
  return last_seq;
}

Status IndexDb::ReadStaged(std::unordered_map<std::string, std::vector<double>>* staged) {
  Transaction tx(db_, "BEGIN");  // one read snapshot of every staged row
  if (!tx.ok()) return Error("begin reading staged results");
  std::vector<StagedEntry> entries;
  for (long seq = -1;;) {
    auto last = ReadStagedRows(seq, 4096, false, &entries);
    if (!last.ok()) return last.status();
    if (*last < 0) break;
    seq = *last;
  }
  tx.Commit();
  for (StagedEntry& e : entries) (*staged)[e.key] = std::move(e.v);  // in staging order: the later report wins
  return Status::Ok();
}

Status IndexDb::FoldResults(std::unordered_map<std::string, std::vector<double>>* folded) {
  // Moves staged job rows into the keyed point cache, a bounded batch per transaction (each batch's
  // insert and delete are atomic, so a crash in between loses and duplicates nothing). Keys are
  // inserted in sorted order, which touches each B-tree leaf once per batch.
  constexpr int kBatchRows = 512;
  while (true) {
    Transaction tx(db_, "BEGIN IMMEDIATE");
    if (!tx.ok()) return Error("begin folding results");
    std::vector<StagedEntry> entries;
    auto last = ReadStagedRows(-1, kBatchRows, true, &entries);
    if (!last.ok()) return last.status();
    const long last_seq = *last;
    if (last_seq < 0) return Status::Ok();  // nothing staged
    std::sort(entries.begin(), entries.end(), [](const StagedEntry& a, const StagedEntry& b) {
      return a.key != b.key ? a.key < b.key : a.order < b.order;
    });
    sqlite3_stmt* ins = Cached("INSERT OR REPLACE INTO points(key, record, created) VALUES(?, ?, unixepoch())");
    if (!ins) return Error("prepare point insert");
    std::vector<unsigned char> blob;
    for (StagedEntry& e : entries) {  // equal keys: the later report wins, as it did when stored directly
      const uint64_t sum = RecordSum(e.key.data(), e.key.size(), e.v.data(), e.v.size());
      blob.resize(e.v.size() * sizeof(double) + sizeof sum);
      std::memcpy(blob.data(), e.v.data(), e.v.size() * sizeof(double));
      std::memcpy(blob.data() + e.v.size() * sizeof(double), &sum, sizeof sum);
      sqlite3_reset(ins);
      sqlite3_bind_text(ins, 1, e.key.c_str(), static_cast<int>(e.key.size()), SQLITE_STATIC);
      sqlite3_bind_blob(ins, 2, blob.data(), static_cast<int>(blob.size()), SQLITE_STATIC);
      if (sqlite3_step(ins) != SQLITE_DONE) return Error("fold point results");
      if (folded) (*folded)[e.key] = std::move(e.v);
    }
    sqlite3_reset(ins);
    sqlite3_stmt* del = Cached("DELETE FROM results WHERE seq <= ?");
    if (!del) return Error("prepare result cleanup");
    sqlite3_bind_int64(del, 1, last_seq);
    if (sqlite3_step(del) != SQLITE_DONE) return Error("clear folded results");
    sqlite3_reset(del);
    if (!tx.Commit()) return Error("commit folded results");
  }
}

long IndexDb::CachedPointCount() {
  if (!FoldResults().ok()) return -1;
  Stmt s(db_, "SELECT count(*) FROM points");
  return s.ok() && sqlite3_step(s.get()) == SQLITE_ROW ? sqlite3_column_int64(s.get(), 0) : -1;
}

}  // namespace bistable
