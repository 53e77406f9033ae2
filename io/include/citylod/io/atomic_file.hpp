// Atomic file output: write to "<path>.tmp.<pid>", then rename over <path>.
// A reader never sees a half-written file; a killed run leaves at most a
// stale *.tmp.* file, never a truncated output.
#pragma once

#include <cstdio>
#include <string>
#include <string_view>

namespace citylod::io {

/// Writes `bytes` to `path` atomically (temp file + fsync-less rename).
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
  /// Flushes, closes and renames the temp file onto the final path.
  void commit();

  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return tmp_; }

 private:
  std::string path_;
  std::string tmp_;
  std::FILE* file_ = nullptr;
  bool committed_ = false;
};

}  // namespace citylod::io
