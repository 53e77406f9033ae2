// One writer per directory (dir_lock.hpp): flock(2) on a lock file, counted per process.
#include "citylod/tiler/dir_lock.hpp"
#include "citylod/tiler/workdir.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <map>
#include <mutex>

#include "citylod/io/error.hpp"

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

struct Held {
  int fd = -1;
  int count = 0;
  std::string created;  ///< the directory the lock created ("" if it existed)
};

std::mutex& held_mutex() {
  static std::mutex m;
  return m;
}
std::map<std::string, Held>& held() {
  static std::map<std::string, Held> h;
  return h;
}

/// The pid written in a lock file (0 when unreadable).
long holder_pid(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  char buf[32] = {};
  const ssize_t n = ::read(fd, buf, sizeof buf - 1);
  ::close(fd);
  return n > 0 ? std::strtol(buf, nullptr, 10) : 0;
}

std::string absolute_key(const fs::path& p) {
  std::error_code ec;
  fs::path a = fs::weakly_canonical(fs::absolute(p), ec);
  return (ec ? fs::absolute(p).lexically_normal() : a).string();
}

}  // namespace

DirBusy::DirBusy(const std::string& dir, long pid)
    : std::runtime_error(dir + ": in use by another citylod run" +
                         (pid > 0 ? " (pid " + std::to_string(pid) + ")" : std::string()) +
                         "; wait for it to finish or use another directory"),
      pid_(pid) {}

DirLock::DirLock(const std::string& dir, Mode mode) : DirLock(dir_lock_path(dir), dir, mode) {}

DirLock DirLock::for_shard(const std::string& dir, int index, int count) {
  return DirLock(shard_lock_path(dir, index, count),
                 dir + " (shard " + std::to_string(index) + "/" + std::to_string(count) + ")",
                 Mode::exclusive);
}

DirLock DirLock::for_output(const std::string& out) {
  return DirLock(output_lock_path(out), out, Mode::exclusive);
}

DirLock::DirLock(const std::string& lock_file, const std::string& what, Mode mode) {
  const fs::path parent = fs::path(lock_file).parent_path();
  std::error_code ec;
  const bool existed = parent.empty() || fs::exists(parent, ec);
  if (!existed) fs::create_directories(parent, ec);
  if (ec) throw io::IoError(parent.string(), "cannot create directory: " + ec.message());
  const std::string key = absolute_key(lock_file);
  std::lock_guard<std::mutex> guard(held_mutex());
  auto it = held().find(key);
  if (it != held().end()) {  // this process holds it already (a nested stage)
    ++it->second.count;
    key_ = key;
    return;
  }
  for (int attempt = 0;; ++attempt) {
    const int fd = ::open(key.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    // A directory this process cannot write (a read-only work directory that
    // assemble only reads): nothing can be locked, and nothing of ours written there.
    if (fd < 0 && (errno == EACCES || errno == EROFS)) return;
    if (fd < 0)
      throw io::IoError(key, std::string("cannot open lock file: ") + std::strerror(errno));
    if (::flock(fd, (mode == Mode::shared ? LOCK_SH : LOCK_EX) | LOCK_NB) != 0) {
      const int err = errno;
      ::close(fd);
      if (err == EWOULDBLOCK) throw DirBusy(what, holder_pid(key));
      throw io::IoError(key, std::string("cannot lock: ") + std::strerror(err));
    }
    // The previous holder may have removed the file between our open and flock:
    // then we locked an unlinked file; open the path again.
    struct stat a {
    }, b{};
    if (::fstat(fd, &a) != 0 || ::stat(key.c_str(), &b) != 0 || a.st_ino != b.st_ino ||
        a.st_dev != b.st_dev) {
      ::close(fd);
      if (attempt < 100) continue;
      throw io::IoError(key, "lock file keeps changing");
    }
    const std::string pid = std::to_string(::getpid()) + "\n";
    if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) < 0) {
      // the pid is only for the message of a second run
    }
    held()[key] = Held{fd, 1, existed ? std::string() : fs::path(key).parent_path().string()};
    key_ = key;
    return;
  }
}

DirLock::~DirLock() {
  if (key_.empty()) return;
  std::lock_guard<std::mutex> guard(held_mutex());
  auto it = held().find(key_);
  if (it == held().end() || --it->second.count > 0) return;
  // Remove the file while still holding it exclusively (a contender re-checks the
  // inode): a shared holder only when it is the last one (the upgrade succeeds).
  // Then the directory the lock created, if nothing else was put in it.
  if (::flock(it->second.fd, LOCK_EX | LOCK_NB) == 0) ::unlink(key_.c_str());
  ::close(it->second.fd);
  if (!it->second.created.empty()) ::rmdir(it->second.created.c_str());
  held().erase(it);
}

}  // namespace citylod::tiler
