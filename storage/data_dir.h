// What a data directory (<data>/index.sqlite, <data>/sweeps/<id>.h5) is made of on disk: the permission
// bits its parts are created with.
#ifndef BISTABLE_STORAGE_DATA_DIR_H_
#define BISTABLE_STORAGE_DATA_DIR_H_

namespace bistable {

// Less the umask: the directory and sweeps/ 0750, the index (with its WAL and shared-memory files, which
// SQLite creates with the index's mode) and the maps 0640 — the owner writes, a group may read (operators,
// a Kubernetes fsGroup), other users see nothing. A directory that exists keeps its mode.
inline constexpr unsigned kDataDirectoryMode = 0750;
inline constexpr unsigned kDataFileMode = 0640;

}  // namespace bistable

#endif  // BISTABLE_STORAGE_DATA_DIR_H_
