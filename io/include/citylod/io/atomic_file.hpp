// Atomic file output: write to "<path>.tmp.<pid>", fsync it, rename it over
// <path>, fsync the directory. A reader never sees a half-written file; a
// killed run (or a power cut) leaves at most a stale *.tmp.* file, never a
// truncated output.
//
// Atomic directory output (publish_directory): a complete staged directory
// replaces the target in ONE rename (renameat2 RENAME_EXCHANGE), so the
// target is at every instant the previous or the new complete directory.
#pragma once

#include <cstdio>
#include <functional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace citylod::io {

/// "<path>.tmp.<pid of this process>": where an atomic output is staged before
/// its rename (AtomicFile, and the directories staged for publication).
std::string staging_path(const std::string& path);

/// The `path` a staging name was made for ("<path>.tmp.<digits>"), or "" when
/// `name` is not one: what a killed run left.
std::string staged_for(const std::string& name);

/// Writes `bytes` to `path` atomically (temp file + fsync + rename + fsync of the directory).
/// Creates missing parent directories. Throws IoError.
void atomic_write_file(const std::string& path, std::string_view bytes);

/// Streaming variant for large outputs (inside a StagedDirectory: written in
/// place, see there):
///   AtomicFile f(path); f.write(...); ...; f.commit();
/// If commit() is never called (exception, early return), the destructor
/// removes the temp file and `path` is left untouched.
class AtomicFile {
 public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void write(const void* data, std::size_t size);
  void write(std::string_view s) { write(s.data(), s.size()); }
  /// Flushes, fsyncs, closes and renames the temp file onto the final path, then fsyncs
  /// the directory.
  void commit();

  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return tmp_; }

 private:
  std::string path_;
  std::string tmp_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
  bool in_place_ = false;  ///< under a StagedDirectory: no temp file, fsync or rename
};

/// While alive, marks `dir` as a directory staged for publish_directory: an
/// AtomicFile (or atomic_write_file) under it writes its path in place, with no
/// temp file, fsync or rename of its own. The directory is published whole, and
/// publish_directory makes its content durable with one syncfs(2) first, so a
/// file in it needs neither: a reader never sees the stage, and a killed run
/// leaves an unpublished stage, removed by the next run. One fsync per file was
/// most of the Delft tile run's I/O time (~0.4 ms each here; BENCHMARKS.md,
/// "Process start-up and I/O"). Thread-safe; guards may nest or overlap.
class StagedDirectory {
 public:
  explicit StagedDirectory(std::string dir);
  ~StagedDirectory();
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;

 private:
  std::string dir_;
};

/// syncfs(2) of the file system holding `dir`: every file written under a
/// StagedDirectory durable at once, before the directory (or what it holds) is
/// renamed into place by the caller. Throws IoError.
void sync_file_system(const std::string& dir);

/// True when `path` lies under a directory a live StagedDirectory marks.
bool in_staged_directory(const std::string& path);

/// Switches the complete directory `stage` in as `target` and removes the
/// previous one: syncfs(2) of the stage's file system (every file in the stage
/// durable at once), then one atomic exchange of the two names
/// (renameat2 RENAME_EXCHANGE; a plain rename when `target` does not exist),
/// fsync of the parent, then the previous directory (now named `stage`) is
/// removed. On a file system without RENAME_EXCHANGE: target -> "<target>.old",
/// stage -> target (a reader of that instant finds "<target>.old"; recover
/// with recover_directory()). Throws IoError.
void publish_directory(const std::string& stage, const std::string& target);

/// publish_directory of several (stage, target) pairs on one file system with
/// one syncfs(2) for all, then each exchange, then one fsync per distinct
/// parent: the same guarantees per pair, fewer waits for the disk. Throws
/// IoError at the first pair that fails (those before it are published).
void publish_directories(const std::vector<std::pair<std::string, std::string>>& pairs);

/// After a publication killed between the fallback's two renames: moves
/// "<target>.old" back to `target` when `target` is missing. True if it did.
bool recover_directory(const std::string& target);

/// For crash tests only: called with the name of each step of a publication,
/// before it is taken: "rename <path>" (a temp file onto its path), "close
/// <path>" (a file written in place in a StagedDirectory), "switch
/// <target>" (publish_directory's exchange), "clean <dir>" (removal of the
/// previous directory). A hook that ends the process there simulates a kill
/// at that point. Nothing in citylod sets it; an empty function removes it.
void set_publication_hook(std::function<void(const std::string& step)> hook);

}  // namespace citylod::io
