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

/// Streaming variant for large outputs:
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
};

/// fsync(2) of a directory (its entries: renames, new files). Throws IoError.
void fsync_directory(const std::string& dir);

/// fsyncs every regular file and directory under `dir` (itself included). Throws IoError.
void fsync_tree(const std::string& dir);

/// Switches the complete directory `stage` in as `target` and removes the
/// previous one: fsync_tree(stage), then one atomic exchange of the two names
/// (renameat2 RENAME_EXCHANGE; a plain rename when `target` does not exist),
/// fsync of the parent, then the previous directory (now named `stage`) is
/// removed. On a file system without RENAME_EXCHANGE: target -> "<target>.old",
/// stage -> target (a reader of that instant finds "<target>.old"; recover
/// with recover_directory()). Throws IoError.
void publish_directory(const std::string& stage, const std::string& target);

/// After a publication killed between the fallback's two renames: moves
/// "<target>.old" back to `target` when `target` is missing. True if it did.
bool recover_directory(const std::string& target);

/// For crash tests only: called with the name of each step of a publication,
/// before it is taken: "rename <path>" (a temp file onto its path), "switch
/// <target>" (publish_directory's exchange), "clean <dir>" (removal of the
/// previous directory). A hook that ends the process there simulates a kill
/// at that point. Nothing in citylod sets it; an empty function removes it.
void set_publication_hook(std::function<void(const std::string& step)> hook);

}  // namespace citylod::io
