#include "citylod/io/atomic_file.hpp"

#include <fcntl.h>
#include <stdio.h>  // renameat2 (glibc >= 2.28)
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "citylod/io/error.hpp"

namespace citylod::io {

namespace fs = std::filesystem;

namespace {

std::function<void(const std::string&)>& hook() {
  static std::function<void(const std::string&)> h;
  return h;
}

void step(const std::string& name) {
  if (hook()) hook()(name);
}

void fsync_path(const std::string& path, bool directory) {
  const int fd = ::open(path.c_str(), (directory ? O_RDONLY | O_DIRECTORY : O_RDONLY) | O_CLOEXEC);
  if (fd < 0) throw IoError(path, std::string("cannot open to sync: ") + std::strerror(errno));
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  // EINVAL: a file system that cannot sync this kind of file (nothing to do)
  if (rc != 0 && err != EINVAL)
    throw IoError(path, std::string("fsync failed: ") + std::strerror(err));
}

std::string parent_of(const std::string& path) {
  const fs::path p = fs::path(path).parent_path();
  return p.empty() ? std::string(".") : p.string();
}

}  // namespace

void set_publication_hook(std::function<void(const std::string& step)> h) {
  hook() = std::move(h);
}

std::string staging_path(const std::string& path) {
  return path + ".tmp." + std::to_string(::getpid());
}

std::string staged_for(const std::string& name) {
  const std::size_t at = name.rfind(".tmp.");
  if (at == std::string::npos || at == 0 || at + 5 == name.size() ||
      name.find_first_not_of("0123456789", at + 5) != std::string::npos)
    return "";
  return name.substr(0, at);
}

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  tmp_ = staging_path(path_);
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
  bool ok = std::fflush(file_) == 0 && !std::ferror(file_);
  int err = errno;
  if (ok && ::fsync(::fileno(file_)) != 0 && errno != EINVAL) {
    ok = false;
    err = errno;
  }
  std::fclose(file_);
  file_ = nullptr;
  if (!ok) throw IoError(path_, std::string("write failed: ") + std::strerror(err));
  step("rename " + path_);
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0)
    throw IoError(path_, std::string("cannot rename temporary file: ") + std::strerror(errno));
  committed_ = true;
  fsync_path(parent_of(path_), true);
}

void atomic_write_file(const std::string& path, std::string_view bytes) {
  AtomicFile f(path);
  f.write(bytes.data(), bytes.size());
  f.commit();
}

void fsync_directory(const std::string& dir) {
  fsync_path(dir, true);
}

void fsync_tree(const std::string& dir) {
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::end(it);
       it.increment(ec)) {
    const auto st = it->symlink_status(ec);
    if (ec) break;
    if (fs::is_regular_file(st)) fsync_path(it->path().string(), false);
    if (fs::is_directory(st)) fsync_path(it->path().string(), true);
  }
  if (ec) throw IoError(dir, "cannot list for sync: " + ec.message());
  fsync_path(dir, true);
}

bool recover_directory(const std::string& target) {
  const std::string old = target + ".old";
  std::error_code ec;
  if (fs::exists(target, ec) || !fs::is_directory(old, ec)) return false;
  fs::rename(old, target, ec);
  if (ec) throw IoError(target, "cannot restore " + old + ": " + ec.message());
  fsync_path(parent_of(target), true);
  return true;
}

void publish_directory(const std::string& stage, const std::string& target) {
  fsync_tree(stage);
  const std::string parent = parent_of(target);
  std::error_code ec;
  if (!fs::exists(target, ec)) {
    step("switch " + target);
    if (std::rename(stage.c_str(), target.c_str()) != 0)
      throw IoError(target, std::string("cannot publish: ") + std::strerror(errno));
    fsync_path(parent, true);
    return;
  }
  step("switch " + target);
  if (::renameat2(AT_FDCWD, stage.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) == 0) {
    fsync_path(parent, true);
    step("clean " + stage);
    fs::remove_all(stage, ec);  // the previous directory
    return;
  }
  if (errno != EINVAL && errno != ENOSYS && errno != ENOTSUP)
    throw IoError(target, std::string("cannot publish: ") + std::strerror(errno));
  // No exchange on this file system: two renames (recover_directory() undoes a kill between).
  const std::string old = target + ".old";
  fs::remove_all(old, ec);
  if (std::rename(target.c_str(), old.c_str()) != 0)
    throw IoError(target, std::string("cannot move aside: ") + std::strerror(errno));
  step("switch " + target + " (second rename)");
  if (std::rename(stage.c_str(), target.c_str()) != 0) {
    const int err = errno;
    std::rename(old.c_str(), target.c_str());
    throw IoError(target, std::string("cannot publish: ") + std::strerror(err));
  }
  fsync_path(parent, true);
  step("clean " + old);
  fs::remove_all(old, ec);
}

}  // namespace citylod::io
