#include "citylod/io/atomic_file.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "citylod/io/error.hpp"

namespace citylod::io {

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  tmp_ = path_ + ".tmp." + std::to_string(::getpid());
  std::filesystem::path parent = std::filesystem::path(path_).parent_path();
  if (!parent.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(parent, ec);
    if (ec)
      throw IoError(path_, "cannot create directory " + parent.string() + ": " + ec.message());
  }
  file_ = std::fopen(tmp_.c_str(), "wb");
  if (!file_) throw IoError(path_, std::string("cannot create file: ") + std::strerror(errno));
}

AtomicFile::~AtomicFile() {
  if (file_) std::fclose(file_);
  if (!committed_) std::remove(tmp_.c_str());
}

void AtomicFile::write(const void* data, std::size_t size) {
  if (!file_) throw IoError(path_, "write after commit");
  if (size && std::fwrite(data, 1, size, file_) != size)
    throw IoError(path_, std::string("write failed: ") + std::strerror(errno));
}

void AtomicFile::commit() {
  if (!file_) throw IoError(path_, "commit called twice");
  const bool ok = std::fflush(file_) == 0 && !std::ferror(file_);
  const int err = errno;
  std::fclose(file_);
  file_ = nullptr;
  if (!ok) throw IoError(path_, std::string("write failed: ") + std::strerror(err));
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0)
    throw IoError(path_, std::string("cannot rename temporary file: ") + std::strerror(errno));
  committed_ = true;
}

void atomic_write_file(const std::string& path, std::string_view bytes) {
  AtomicFile f(path);
  f.write(bytes.data(), bytes.size());
  f.commit();
}

}  // namespace citylod::io
