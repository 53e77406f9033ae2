// Benchmarks that measure a stage in a fresh process: this program re-executed
// (/proc/self/exe) with "--child" and its arguments, stdout captured, and its
// wall time, CPU time and peak RSS taken from wait4() (Linux).
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <vector>

namespace citylod::bench {

struct ChildRun {
  bool ok = false;    ///< exited with status 0
  std::string out;    ///< what the child printed on stdout
  double wall_s = 0;  ///< from fork to exit
  double cpu_s = 0;   ///< user + system
  double rss_mb = 0;  ///< peak resident set size
};

/// Runs `argv0 --child args...` as /proc/self/exe and waits for it.
inline ChildRun run_child(const char* argv0, const std::vector<std::string>& args) {
  ChildRun r;
  std::vector<char*> argv{const_cast<char*>(argv0), const_cast<char*>("--child")};
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  int pipefd[2];
  if (pipe(pipefd) != 0) return r;
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(pipefd[1], 1);
    close(pipefd[0]);
    execv("/proc/self/exe", argv.data());
    _exit(127);
  }
  close(pipefd[1]);
  char buf[512];
  ssize_t got;
  while ((got = read(pipefd[0], buf, sizeof buf)) > 0) r.out.append(buf, std::size_t(got));
  close(pipefd[0]);
  int status = 0;
  struct rusage ru {};
  wait4(pid, &status, 0, &ru);
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
  r.cpu_s = double(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
            1e-6 * double(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
  r.rss_mb = double(ru.ru_maxrss) / 1024.0;  // KiB -> MiB
  return r;
}

}  // namespace citylod::bench
