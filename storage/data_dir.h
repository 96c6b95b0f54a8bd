// What a data directory (<data>/index.sqlite, <data>/sweeps/<id>.h5) is made of on disk: the permission
// bits its parts are created with, and its repair at start: a damaged index or map file is moved aside
// (never deleted) and what it held is made again where it can be.
#ifndef BISTABLE_STORAGE_DATA_DIR_H_
#define BISTABLE_STORAGE_DATA_DIR_H_

#include <memory>
#include <string>
#include <vector>

#include "base/status.h"
#include "storage/index_db.h"

namespace bistable {

// Less the umask: the directory and sweeps/ 0750, the index (with its WAL and shared-memory files, which
// SQLite creates with the index's mode) and the maps 0640 — the owner writes, a group may read (operators,
// a Kubernetes fsGroup), other users see nothing. A directory that exists keeps its mode.
inline constexpr unsigned kDataDirectoryMode = 0750;
inline constexpr unsigned kDataFileMode = 0640;

// Renames `path` to "<path>.corrupt-<UTC time, 20261128T022431Z>" ("-2", "-3", ... added when taken) and
// returns the new name; nothing is deleted. IoError naming both when the rename fails.
StatusOr<std::string> MoveAside(const std::string& path);

// Whether `path` can serve as sweep `id`'s published map: HDF5 opens it (a truncated or overwritten file
// fails its checks), its sweep_id attribute is `id` and it holds metric datasets. IoError naming the file
// and what is wrong otherwise.
Status CheckMapFile(const std::string& path, const std::string& id);

// The map files of <data_dir>/sweeps (<12 hex digits>.h5, regular files) that index `db` holds no sweep
// row for (every one when `db` is null: no index at all), in directory order.
StatusOr<std::vector<std::string>> UnindexedMapFiles(IndexDb* db, const std::string& data_dir);

// The index of data directory `data_dir` (which exists), opened for writing and repaired where it can be:
// - an index that is not an SQLite database, or fails SQLite's quick_check (IndexDb::QuickCheck), is moved
//   aside with its -wal and -shm files (MoveAside) and a new one is made, holding what could be read of the
//   old one (IndexDb::SalvageFrom: unfinished sweeps, the point cache, staged reports);
// - a map file of sweeps/ (<12 hex digits>.h5) that the index holds no row for — an empty (zero-length),
//   missing or rebuilt index — is indexed again as a published sweep (spec, name and model from the file's
//   attributes, its map rows from its datasets; owner unknown, ""); one that does not open is moved aside.
// Every repair is one sentence in *notes, naming the files.
StatusOr<std::unique_ptr<IndexDb>> OpenDataIndex(const std::string& data_dir, std::vector<std::string>* notes);

}  // namespace bistable

#endif  // BISTABLE_STORAGE_DATA_DIR_H_
