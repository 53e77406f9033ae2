// Helpers for the io tests: temp paths, byte builders for PLY and LAS fixtures.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "citylod/io/error.hpp"

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

/// Little/big endian byte appender.
class Bytes {
 public:
  explicit Bytes(bool big_endian = false) : be_(big_endian) {}
  template <typename T>
  Bytes& put(T v) {
    unsigned char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (be_)
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    s_.append(reinterpret_cast<const char*>(b), sizeof(T));
    return *this;
  }
  Bytes& str(const std::string& s) {
    s_ += s;
    return *this;
  }
  Bytes& fixed(const std::string& s, std::size_t n) {
    std::string t = s;
    t.resize(n, '\0');
    s_ += t;
    return *this;
  }
  std::string& data() { return s_; }

 private:
  bool be_;
  std::string s_;
};

struct LasPoint {
  double x, y, z;
  std::uint8_t cls;
  std::uint16_t r = 0, g = 0, b = 0;
};

struct LasSpec {
  int minor = 2;
  int point_format = 1;
  std::uint16_t extra_bytes = 0;  // record length = base + extra
  std::vector<LasPoint> points;
  double scale = 0.01;
  double offset[3] = {1000.0, 2000.0, 0.0};
  std::int64_t declared = -1;  // point count written in the header (-1: actual)
  std::int64_t legacy = -1;    // LAS 1.4 legacy count (-1: same as declared when it fits, pf<6)
  std::string wkt;             // VLR 2112 (or EVLR for 1.4 when wkt_in_evlr)
  bool wkt_in_evlr = false;
  std::vector<std::uint16_t> geokeys;  // full GeoKeyDirectory u16 array
  bool compressed_bit = false;
};

inline std::size_t las_base_record(int pf) {
  static const std::size_t s[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  return s[pf];
}

/// A LAS 1.0-1.4 file as bytes.
inline std::string make_las(const LasSpec& sp) {
  const std::uint16_t header_size = sp.minor >= 4 ? 375 : (sp.minor == 3 ? 235 : 227);
  const std::size_t rl = las_base_record(sp.point_format) + sp.extra_bytes;
  Bytes vlrs;
  std::uint32_t nvlr = 0;
  auto add_vlr = [&](std::uint16_t id, const std::string& payload) {
    vlrs.put<std::uint16_t>(0).fixed("LASF_Projection", 16).put<std::uint16_t>(id);
    vlrs.put<std::uint16_t>(static_cast<std::uint16_t>(payload.size()))
        .fixed("test", 32)
        .str(payload);
    ++nvlr;
  };
  if (!sp.geokeys.empty()) {
    Bytes k;
    for (auto v : sp.geokeys) k.put(v);
    add_vlr(34735, k.data());
  }
  if (!sp.wkt.empty() && !sp.wkt_in_evlr) add_vlr(2112, sp.wkt + std::string(1, '\0'));
  const std::uint32_t point_offset = header_size + static_cast<std::uint32_t>(vlrs.data().size());
  const std::uint64_t declared =
      sp.declared >= 0 ? static_cast<std::uint64_t>(sp.declared) : sp.points.size();

  Bytes pts;
  double mn[3] = {1e300, 1e300, 1e300}, mx[3] = {-1e300, -1e300, -1e300};
  for (const auto& p : sp.points) {
    Bytes rec;
    double c[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) {
      rec.put<std::int32_t>(
          static_cast<std::int32_t>(std::llround((c[a] - sp.offset[a]) / sp.scale)));
      mn[a] = std::min(mn[a], c[a]);
      mx[a] = std::max(mx[a], c[a]);
    }
    rec.put<std::uint16_t>(100);  // intensity
    if (sp.point_format < 6) {
      rec.put<std::uint8_t>(0x09);  // return 1 of 1
      rec.put<std::uint8_t>(static_cast<std::uint8_t>(p.cls & 0x1F) |
                            0x20);  // class + synthetic flag
      rec.put<std::int8_t>(0).put<std::uint8_t>(0).put<std::uint16_t>(7);
      if (sp.point_format == 1 || sp.point_format == 3) rec.put<double>(12345.5);
      if (sp.point_format == 2 || sp.point_format == 3) rec.put(p.r).put(p.g).put(p.b);
    } else {
      rec.put<std::uint8_t>(0x11).put<std::uint8_t>(0).put<std::uint8_t>(p.cls).put<std::uint8_t>(
          0);
      rec.put<std::int16_t>(0).put<std::uint16_t>(7).put<double>(12345.5);
      if (sp.point_format == 7 || sp.point_format == 8) rec.put(p.r).put(p.g).put(p.b);
      if (sp.point_format == 8) rec.put<std::uint16_t>(0);
    }
    std::string r = rec.data();
    r.resize(rl, '\0');
    pts.str(r);
  }

  Bytes evlr;
  std::uint32_t nevlr = 0;
  if (!sp.wkt.empty() && sp.wkt_in_evlr) {
    std::string payload = sp.wkt + std::string(1, '\0');
    evlr.put<std::uint16_t>(0).fixed("LASF_Projection", 16).put<std::uint16_t>(2112);
    evlr.put<std::uint64_t>(payload.size()).fixed("wkt", 32).str(payload);
    nevlr = 1;
  }

  Bytes h;
  h.str("LASF").put<std::uint16_t>(0).put<std::uint16_t>(sp.wkt.empty() ? 0 : 16);
  h.fixed("", 16);
  h.put<std::uint8_t>(1).put<std::uint8_t>(static_cast<std::uint8_t>(sp.minor));
  h.fixed("citylod test", 32).fixed("citylod fixtures", 32);
  h.put<std::uint16_t>(1).put<std::uint16_t>(2024);
  h.put<std::uint16_t>(header_size).put<std::uint32_t>(point_offset).put<std::uint32_t>(nvlr);
  h.put<std::uint8_t>(static_cast<std::uint8_t>(sp.point_format | (sp.compressed_bit ? 0x80 : 0)));
  h.put<std::uint16_t>(static_cast<std::uint16_t>(rl));
  std::uint32_t legacy = 0;
  if (sp.legacy >= 0)
    legacy = static_cast<std::uint32_t>(sp.legacy);
  else if (sp.point_format < 6 && declared <= 0xFFFFFFFFull)
    legacy = static_cast<std::uint32_t>(declared);
  h.put<std::uint32_t>(legacy);
  for (int i = 0; i < 5; ++i) h.put<std::uint32_t>(i == 0 ? legacy : 0);
  for (int a = 0; a < 3; ++a) h.put<double>(sp.scale);
  for (int a = 0; a < 3; ++a) h.put<double>(sp.offset[a]);
  if (sp.points.empty()) {
    for (int a = 0; a < 3; ++a) mn[a] = mx[a] = 0;
  }
  for (int a = 0; a < 3; ++a) h.put<double>(mx[a]).put<double>(mn[a]);
  if (sp.minor >= 3) h.put<std::uint64_t>(0);
  if (sp.minor >= 4) {
    std::uint64_t evlr_start = nevlr ? point_offset + pts.data().size() : 0;
    h.put<std::uint64_t>(evlr_start).put<std::uint32_t>(nevlr).put<std::uint64_t>(declared);
    for (int i = 0; i < 15; ++i) h.put<std::uint64_t>(i == 0 ? declared : 0);
  }
  EXPECT_EQ(h.data().size(), header_size);
  return h.data() + vlrs.data() + pts.data() + evlr.data();
}

}  // namespace citylod::io::test
