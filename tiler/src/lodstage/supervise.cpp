#include "citylod/tiler/supervise.hpp"

#include "citylod/tiler/log.hpp"

#include <csignal>
#include <cstring>
#include <filesystem>
#include <vector>

#include <sys/wait.h>
#include <unistd.h>

namespace citylod::tiler {

namespace fs = std::filesystem;

int supervise(const std::string& work_dir, const std::function<int()>& work, int max_restarts,
              int* crashes) {
  for (int attempt = 0;; ++attempt) {
    if (crashes) *crashes = attempt;
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t pid = ::fork();
    if (pid < 0) return work();  // no fork: run in-process
    if (pid == 0) {
      int rc = 1;
      try {
        rc = work();
      } catch (const std::exception& e) {
        log_error(e.what());
        rc = 1;
      }
      std::fflush(stdout);
      std::fflush(stderr);
      ::_exit(rc);
    }
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0) {
      if (errno != EINTR) return 1;
    }
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    const int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    if (sig == SIGKILL || sig == SIGTERM || sig == SIGINT) return 128 + sig;  // killed from outside
    // A crash: mark what was running.
    std::vector<fs::path> running;
    const fs::path lod = fs::path(work_dir) / "lod";
    if (fs::exists(lod))
      for (const auto& e : fs::directory_iterator(lod))
        if (e.path().extension() == ".running") running.push_back(e.path());
    for (const auto& r : running) {
      fs::path target = r;
      target.replace_extension(running.size() == 1 ? ".crashed" : ".suspect");
      fs::rename(r, target);
    }
    log_warn("lod stage crashed (" + std::string(::strsignal(sig)) + ") with " +
             std::to_string(running.size()) + " building(s) running; " +
             (running.size() == 1 ? "it gets its fallback" : "retrying them one at a time"));
    if (attempt >= max_restarts) return 1;
  }
}

}  // namespace citylod::tiler
