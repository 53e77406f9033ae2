#include "citylod/tiler/supervise.hpp"

#include "citylod/tiler/log.hpp"
#include "citylod/tiler/workdir.hpp"

#include <csignal>
#include <cstring>
#include <filesystem>
#include <vector>

#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

namespace citylod::tiler {

namespace fs = std::filesystem;

namespace {

// The running worker, for the forwarding handler (one supervised child at a time).
volatile sig_atomic_t g_child = 0;
volatile sig_atomic_t g_signal = 0;

extern "C" void forward_signal(int sig) {
  g_signal = sig;
  if (g_child > 0) ::kill(pid_t(g_child), sig);
}

/// While alive: SIGTERM / SIGINT / SIGHUP to the supervisor are passed on to the
/// worker; afterwards the supervisor dies of the same signal (see supervise()).
class ForwardSignals {
 public:
  explicit ForwardSignals(pid_t child) {
    g_child = child;
    g_signal = 0;
    struct sigaction sa {};
    sa.sa_handler = forward_signal;
    sigemptyset(&sa.sa_mask);
    for (int i = 0; i < 3; ++i) ::sigaction(kSignals[i], &sa, &old_[i]);
  }
  ~ForwardSignals() {
    for (int i = 0; i < 3; ++i) ::sigaction(kSignals[i], &old_[i], nullptr);
    g_child = 0;
  }
  ForwardSignals(const ForwardSignals&) = delete;
  ForwardSignals& operator=(const ForwardSignals&) = delete;

 private:
  static constexpr int kSignals[3] = {SIGTERM, SIGINT, SIGHUP};
  struct sigaction old_[3]{};
};

}  // namespace

int supervise(const std::string& work_dir, const std::function<int()>& work, int max_restarts,
              int* crashes) {
  for (int attempt = 0;; ++attempt) {
    if (crashes) *crashes = attempt;
    std::fflush(stdout);
    std::fflush(stderr);
    const pid_t parent = ::getpid();
    const pid_t pid = ::fork();
    if (pid < 0) return work();  // no fork: run in-process
    if (pid == 0) {
      // The worker dies with its supervisor (even by SIGKILL): no orphan keeps writing.
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (::getppid() != parent) ::_exit(1);  // the supervisor died before the prctl
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
    {
      const ForwardSignals forward(pid);
      while (::waitpid(pid, &status, 0) < 0) {
        if (errno != EINTR) return 1;
      }
    }
    if (g_signal != 0) ::raise(g_signal);  // handlers restored: die of it as asked
    if (WIFEXITED(status)) return WEXITSTATUS(status);
    const int sig = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
    if (sig == SIGKILL || sig == SIGTERM || sig == SIGINT) return 128 + sig;  // killed from outside
    // A crash: mark what was running.
    std::vector<std::string> running;  // building ids
    const fs::path lod = lod_root(work_dir);
    if (fs::exists(lod))
      for (const auto& e : fs::directory_iterator(lod)) {
        std::string id = marker_id(e.path().filename().string(), LodMarker::running);
        if (!id.empty()) running.push_back(std::move(id));
      }
    for (const auto& id : running)
      fs::rename(lod_marker_path(work_dir, id, LodMarker::running),
                 lod_marker_path(work_dir, id,
                                 running.size() == 1 ? LodMarker::crashed : LodMarker::suspect));
    log_warn("lod stage crashed (" + std::string(::strsignal(sig)) + ") with " +
             std::to_string(running.size()) + " building(s) running; " +
             (running.size() == 1 ? "it gets its fallback" : "retrying them one at a time"));
    if (attempt >= max_restarts) return 1;
  }
}

}  // namespace citylod::tiler
