#include "citylod/io/atomic_file.hpp"

#include <fcntl.h>
#include <stdio.h>  // renameat2 (glibc >= 2.28)
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <system_error>
#include <vector>

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

/// The live StagedDirectory guards' directories, each with a trailing '/'.
struct Staged {
  std::mutex mu;
  std::vector<std::string> dirs;
};
Staged& staged() {
  static Staged s;
  return s;
}

std::string with_slash(std::string dir) {
  if (dir.empty() || dir.back() != '/') dir += '/';
  return dir;
}

}  // namespace

void sync_file_system(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw IoError(dir, std::string("cannot open to sync: ") + std::strerror(errno));
  const int rc = ::syncfs(fd);
  const int err = errno;
  ::close(fd);
  if (rc != 0) throw IoError(dir, std::string("sync failed: ") + std::strerror(err));
}

StagedDirectory::StagedDirectory(std::string dir)
    : dir_(with_slash(fs::path(dir).lexically_normal().string())) {
  std::lock_guard<std::mutex> lock(staged().mu);
  staged().dirs.push_back(dir_);
}

StagedDirectory::~StagedDirectory() {
  std::lock_guard<std::mutex> lock(staged().mu);
  auto& d = staged().dirs;
  const auto it = std::find(d.begin(), d.end(), dir_);
  if (it != d.end()) d.erase(it);
}

bool in_staged_directory(const std::string& path) {
  const std::string p = fs::path(path).lexically_normal().string();
  std::lock_guard<std::mutex> lock(staged().mu);
  for (const std::string& d : staged().dirs)
    if (p.size() > d.size() && p.compare(0, d.size(), d) == 0) return true;
  return false;
}

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
  in_place_ = in_staged_directory(path_);
  tmp_ = in_place_ ? path_ : staging_path(path_);
  file_ = std::fopen(tmp_.c_str(), "wb");
  if (!file_ && errno == ENOENT) {  // the directory first (most files go to one that exists)
    const std::filesystem::path parent = std::filesystem::path(path_).parent_path();
    if (!parent.empty()) {
      std::error_code ec;
      std::filesystem::create_directories(parent, ec);
      if (ec)
        throw IoError(path_, "cannot create directory " + parent.string() + ": " + ec.message());
    }
    file_ = std::fopen(tmp_.c_str(), "wb");
  }
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
  if (in_place_) {  // in a staged directory: publish_directory syncs it whole
    step("close " + path_);
    if (std::fclose(file_) != 0 && ok) {
      ok = false;
      err = errno;
    }
    file_ = nullptr;
    if (!ok) throw IoError(path_, std::string("write failed: ") + std::strerror(err));
    committed_ = true;
    return;
  }
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
  publish_directories({{stage, target}});
}

namespace {

/// One pair of publish_directories after the sync: the switch; the parent's
/// fsync is the caller's. Returns the directory to remove after that fsync
/// ("" when none).
std::string switch_directory(const std::string& stage, const std::string& target) {
  std::error_code ec;
  if (!fs::exists(target, ec)) {
    step("switch " + target);
    if (std::rename(stage.c_str(), target.c_str()) != 0)
      throw IoError(target, std::string("cannot publish: ") + std::strerror(errno));
    return "";
  }
  step("switch " + target);
  if (::renameat2(AT_FDCWD, stage.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) == 0)
    return stage;  // the previous directory
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
  return old;
}

}  // namespace

void publish_directories(const std::vector<std::pair<std::string, std::string>>& pairs) {
  if (pairs.empty()) return;
  sync_file_system(pairs.front().first);
  std::vector<std::string> parents, old;
  for (const auto& [stage, target] : pairs) {
    const std::string parent = parent_of(target);
    if (std::find(parents.begin(), parents.end(), parent) == parents.end())
      parents.push_back(parent);
    std::string gone;
    try {
      gone = switch_directory(stage, target);
    } catch (...) {
      for (const auto& p : parents) fsync_path(p, true);  // those switched before stay durable
      throw;
    }
    if (!gone.empty()) old.push_back(std::move(gone));
  }
  for (const auto& p : parents) fsync_path(p, true);
  std::error_code ec;
  for (const auto& d : old) {
    step("clean " + d);
    fs::remove_all(d, ec);
  }
}

}  // namespace citylod::io
