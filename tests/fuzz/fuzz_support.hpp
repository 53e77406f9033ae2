// Shared by the libFuzzer harnesses (tests/fuzz): a scratch file per process,
// and the error policy every reader promises — bad input ends in an exception
// whose message names the file; anything else (a crash, a hang, a message
// without the file) is a finding.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

namespace citylod::fuzz {

/// A private scratch directory (in /dev/shm when it exists), made once and
/// removed when the process exits normally (libFuzzer's -max_total_time).
inline const std::string& scratch_dir() {
  // never destroyed: the exit handler below runs after the static destructors
  static const std::string* const dir = [] {
    const std::string base = std::filesystem::exists("/dev/shm") ? "/dev/shm" : "/tmp";
    auto* d = new std::string(base + "/citylod-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(*d);
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(scratch_dir(), ec);
    });
    return d;
  }();
  return *dir;
}

/// Writes the fuzzer's bytes to `name` in the scratch directory; returns its path.
inline std::string write_input(const std::string& name, const std::uint8_t* data,
                               std::size_t size) {
  const std::string path = scratch_dir() + "/" + name;
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(data), std::streamsize(size));
  return path;
}

/// The error policy: the message must name `file`.
inline void expect_names_file(const std::exception& e, const std::string& file) {
  const std::string what = e.what();
  if (what.find(file) == std::string::npos) {
    std::fprintf(stderr, "FINDING: an error that does not name the file %s: %s\n", file.c_str(),
                 what.c_str());
    std::abort();
  }
}

}  // namespace citylod::fuzz
