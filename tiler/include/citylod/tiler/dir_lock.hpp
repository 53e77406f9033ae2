// One writer per directory. Every run that writes a directory (tile and
// rebuild: DIR and DIR/work; split and lod WORK: WORK; assemble: WORK and its
// output) holds an exclusive flock(2) on a lock file for its whole run:
//
//   DIR/.citylod.lock            for a directory written in place (DIR, WORK)
//   PARENT/.<name>.citylod.lock  for an output switched as a whole (assemble's OUT)
//
// The shards of one LOD stage (`lod WORK --shard I/N`, a Slurm array) run at
// once: each holds WORK's lock shared and its own shard lock
// (WORK/.citylod.shard-I-of-N.lock) exclusively; every other writer holds
// WORK's lock exclusively.
//
// A second run refuses at once (no waiting) with DirBusy:
//   "out: in use by another citylod run (pid 1234); wait for it or use another directory".
// The holder's pid is written into the lock file. The lock is released by the
// kernel when its holder dies (a killed run leaves at most the empty file,
// which the next run reuses); a finished run removes the file. Nested locks of
// one process are counted (run_city() locks WORK, then the LOD stage locks it
// again); the forked LOD worker inherits its parent's lock and dies with it.
// A directory the process may not write (read-only) is not locked: only read there.
#pragma once

#include <stdexcept>
#include <string>

namespace citylod::tiler {

/// Another process holds the lock. what(): "<dir>: in use by another citylod run (pid N); ...".
class DirBusy : public std::runtime_error {
 public:
  DirBusy(const std::string& dir, long pid);
  long pid() const { return pid_; }

 private:
  long pid_;
};

class DirLock {
 public:
  enum class Mode { exclusive, shared };
  /// Locks `dir` (a directory written in place; created when missing). Throws DirBusy.
  explicit DirLock(const std::string& dir, Mode mode = Mode::exclusive);
  /// Locks the output `out` that is replaced as a whole (the lock file sits beside it).
  static DirLock for_output(const std::string& out);
  /// The lock of one shard of the LOD stage (exclusive; `dir` must exist).
  static DirLock for_shard(const std::string& dir, int index, int count);
  ~DirLock();
  DirLock(DirLock&& o) noexcept : key_(std::move(o.key_)) { o.key_.clear(); }
  DirLock(const DirLock&) = delete;
  DirLock& operator=(const DirLock&) = delete;
  DirLock& operator=(DirLock&&) = delete;

 private:
  DirLock(const std::string& lock_file, const std::string& what, Mode mode);
  std::string key_;  ///< the lock file's path ("" when moved from)
};

}  // namespace citylod::tiler
