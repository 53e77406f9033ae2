// Helpers of the tests that run the real `citylod` binary or shell commands.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

namespace citylod::test {

namespace fs = std::filesystem;

struct CliRun {
  int code = -1;
  std::string out;  ///< stdout + stderr
};

/// Runs a shell command, capturing stdout and stderr; code = exit status (-1 on a signal).
inline CliRun sh(const std::string& cmd) {
  CliRun r;
  FILE* p = popen(("(" + cmd + ") 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[4096];
  std::size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int st = pclose(p);
  r.code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

/// Runs `citylod ARGS`.
inline CliRun run(const std::string& args) {
  return sh(std::string(CITYLOD_BINARY) + " " + args);
}

/// A fresh, empty directory under the test tmp dir.
inline fs::path tmp_dir(const std::string& name) {
  fs::path p = fs::path(CITYLOD_TEST_TMP) / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p;
}

/// Shell-quoted path.
inline std::string q(const fs::path& p) {
  return "'" + p.string() + "'";
}

inline std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

/// Relative path -> bytes of every file under root.
inline std::map<std::string, std::string> tree(const fs::path& root) {
  std::map<std::string, std::string> t;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (e.is_regular_file()) t[fs::relative(e.path(), root).generic_string()] = slurp(e.path());
  return t;
}

}  // namespace citylod::test
