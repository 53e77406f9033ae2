// Helpers for the io tests: temp paths, file bytes, the expected IoError.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "citylod/io/error.hpp"
#include "support/las_write.hpp"

namespace citylod::io::test {

/// `name` in a directory of the running test's own (io/<Suite>.<Test>), so tests that ctest
/// runs in parallel never write the same file: two tests writing "c.off" at once made
/// OffReader.Errors read the other test's bytes in CI.
inline std::string tmp_path(const std::string& name) {
  std::string test = "outside_tests";
  if (const auto* info = ::testing::UnitTest::GetInstance()->current_test_info())
    test = std::string(info->test_suite_name()) + "." + info->name();
  std::replace(test.begin(), test.end(), '/', '_');
  std::filesystem::path dir = std::filesystem::path(CITYLOD_TEST_TMP) / "io" / test;
  std::filesystem::create_directories(dir);
  return (dir / name).string();
}

/// The whole file as bytes ("" when it cannot be read).
inline std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

/// A little-endian value at byte `off` of `s` (the tests run on x86/ARM LE).
template <typename T>
T get(const std::string& s, std::size_t off) {
  T v;
  std::memcpy(&v, s.data() + off, sizeof v);
  return v;
}
/// Overwrites the value at byte `off` of `s`.
template <typename T>
void put(std::string& s, std::size_t off, T v) {
  std::memcpy(&s[off], &v, sizeof v);
}

inline std::string write_file(const std::string& name, const std::string& bytes) {
  std::string p = tmp_path(name);
  std::ofstream(p, std::ios::binary) << bytes;
  return p;
}

inline std::string shared(const std::string& rel) {
  return std::string(CITYLOD_SHARED_DATA) + "/" + rel;
}

/// Optional local data outside shared/ (CITYLOD_EXTRA_DATA); CI has none.
inline std::string extra(const std::string& rel) {
  return std::string(CITYLOD_EXTRA_DATA) + "/" + rel;
}

#define CITYLOD_REQUIRE_SHARED(path) \
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "shared data missing: " << (path)

/// Runs `fn`, expects an IoError whose what() contains `needle`; returns what().
template <typename Fn>
std::string expect_io_error(Fn fn, const std::string& needle) {
  try {
    fn();
  } catch (const IoError& e) {
    std::string w = e.what();
    EXPECT_NE(w.find(needle), std::string::npos)
        << "message: " << w << "\nexpected to contain: " << needle;
    EXPECT_EQ(w.find('\n'), std::string::npos) << "message must be one line: " << w;
    return w;
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected IoError, got other exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected IoError containing '" << needle << "', nothing thrown";
  return {};
}

// The LAS writer and the byte appender are the tests' common ones (support/las_write.hpp).
using citylod::test::Bytes;
using citylod::test::LasPoint;
using citylod::test::LasSpec;
using citylod::test::make_las;

}  // namespace citylod::io::test
