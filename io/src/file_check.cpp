#include "citylod/io/file_check.hpp"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>

#include "citylod/io/error.hpp"

namespace citylod::io {

std::uint64_t regular_file_size(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT || errno == ENOTDIR) throw IoError(path, "no such file");
    throw IoError(path, std::string("cannot access: ") + std::strerror(errno));
  }
  if (S_ISDIR(st.st_mode)) throw IoError(path, "is a directory, not a file");
  if (!S_ISREG(st.st_mode))
    throw IoError(path, "is not a regular file (a FIFO, a device or a socket); not read");
  return static_cast<std::uint64_t>(st.st_size);
}

}  // namespace citylod::io
