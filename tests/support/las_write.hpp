// The one LAS writer of the tests (and of bench/): LAS 1.0-1.4, point formats
// 0-10, VLRs for the WKT (2112, or an EVLR in 1.4) and the GeoTIFF keys
// (34735), and deliberately wrong headers (point counts, compressed bit).
//
//   make_las(spec)                 a whole file as bytes (spec.points)
//   LasWriter w(path, scale, offset, wkt); w.add(x, y, z, cls); ...; w.close();
//                                  LAS 1.2 format 1 streamed to a file point by point
//                                  (millions of points); the header (count, bbox) is
//                                  rewritten by close()
//
// Two flavours of the fields no test varies (LasSpec::marked), so that the files
// are byte for byte those the tests wrote before the writers were one:
//   marked (make_las)  records with intensity 100, the synthetic flag on the class,
//                      point source 7 and GPS time 12345.5; header "citylod fixtures",
//                      1/2024, the WKT bit of the global encoding when there is a
//                      WKT, VLR description "test", bbox of the coordinates as given
//   plain (LasWriter)  those fields 0 and the class byte as given; header
//                      "citylod las_writer", bbox of the stored (quantized) coordinates
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace citylod::test {

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
  std::vector<LasPoint> points;   // make_las() writes these (LasWriter: add())
  std::array<double, 3> scale{0.01, 0.01, 0.01};
  std::array<double, 3> offset{1000.0, 2000.0, 0.0};
  std::int64_t declared = -1;  // point count written in the header (-1: actual)
  std::int64_t legacy = -1;    // LAS 1.4 legacy count (-1: same as declared when it fits, pf<6)
  std::string wkt;             // VLR 2112 (or EVLR for 1.4 when wkt_in_evlr)
  bool wkt_in_evlr = false;
  std::vector<std::uint16_t> geokeys;  // full GeoKeyDirectory u16 array
  bool compressed_bit = false;
  bool marked = true;  // the flavour of the fields no test varies (see the top of this file)
};

inline std::size_t las_base_record(int pf) {
  static const std::size_t s[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
  return s[pf];
}

class LasWriter {
 public:
  /// LAS 1.2 format 1 streamed to `path` (plain flavour), with the WKT VLR unless `wkt` is empty.
  LasWriter(const std::string& path, std::array<double, 3> scale, std::array<double, 3> offset,
            std::string wkt = "")
      : LasWriter(path, plain(scale, offset, std::move(wkt))) {}
  /// `spec` streamed to `path` (spec.points are not written: add() them).
  LasWriter(const std::string& path, LasSpec spec) : sp_(std::move(spec)) {
    f_ = std::fopen(path.c_str(), "wb");
    if (!f_) throw std::runtime_error("cannot create " + path);
    start();
  }
  /// `spec` written into memory: bytes() after close().
  explicit LasWriter(LasSpec spec) : sp_(std::move(spec)) { start(); }
  ~LasWriter() {
    if (f_) std::fclose(f_);
  }
  LasWriter(const LasWriter&) = delete;
  LasWriter& operator=(const LasWriter&) = delete;

  void add(double x, double y, double z, std::uint8_t cls = 1) { add(LasPoint{x, y, z, cls}); }
  void add(const LasPoint& p) {
    Bytes rec;
    const double c[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) {
      const auto q = static_cast<std::int32_t>(std::llround((c[a] - sp_.offset[a]) / sp_.scale[a]));
      rec.put<std::int32_t>(q);
      const double v = sp_.marked ? c[a] : q * sp_.scale[a] + sp_.offset[a];
      min_[a] = std::min(min_[a], v);
      max_[a] = std::max(max_[a], v);
    }
    const std::uint16_t intensity = sp_.marked ? 100 : 0, source = sp_.marked ? 7 : 0;
    const double gps = sp_.marked ? 12345.5 : 0.0;
    const int pf = sp_.point_format;
    rec.put<std::uint16_t>(intensity);
    if (pf < 6) {
      rec.put<std::uint8_t>(0x09);  // return 1 of 1
      rec.put<std::uint8_t>(sp_.marked ? static_cast<std::uint8_t>((p.cls & 0x1F) | 0x20)
                                       : p.cls);  // class (+ synthetic flag)
      rec.put<std::int8_t>(0).put<std::uint8_t>(0).put<std::uint16_t>(source);
      if (pf == 1 || pf == 3) rec.put<double>(gps);
      if (pf == 2 || pf == 3) rec.put(p.r).put(p.g).put(p.b);
    } else {
      rec.put<std::uint8_t>(0x11).put<std::uint8_t>(0).put<std::uint8_t>(p.cls).put<std::uint8_t>(
          0);
      rec.put<std::int16_t>(0).put<std::uint16_t>(source).put<double>(gps);
      if (pf == 7 || pf == 8) rec.put(p.r).put(p.g).put(p.b);
      if (pf == 8) rec.put<std::uint16_t>(0);
    }
    std::string r = std::move(rec.data());
    r.resize(record_length(), '\0');
    write(r);
    ++count_;
  }

  /// Appends the EVLR (1.4) and rewrites the header; `lie_count` writes a wrong
  /// point count (for bad-input tests).
  void close(std::int64_t lie_count = -1) {
    const std::string evlr = evlrs();
    write(evlr);
    const std::string h = header(lie_count, evlr.empty() ? 0 : 1);
    if (f_) {
      std::fseek(f_, 0, SEEK_SET);
      std::fwrite(h.data(), 1, h.size(), f_);
      std::fclose(f_);
      f_ = nullptr;
    } else {
      mem_.replace(0, h.size(), h);
    }
  }
  std::uint64_t count() const { return count_; }
  /// The file, when written into memory (after close()).
  const std::string& bytes() const { return mem_; }

 private:
  static LasSpec plain(std::array<double, 3> scale, std::array<double, 3> offset, std::string wkt) {
    LasSpec s;
    s.scale = scale;
    s.offset = offset;
    s.wkt = std::move(wkt);
    s.marked = false;
    return s;
  }
  std::uint16_t header_size() const { return sp_.minor >= 4 ? 375 : (sp_.minor == 3 ? 235 : 227); }
  std::size_t record_length() const { return las_base_record(sp_.point_format) + sp_.extra_bytes; }
  void write(const std::string& s) {
    if (f_)
      std::fwrite(s.data(), 1, s.size(), f_);
    else
      mem_ += s;
  }
  void start() {
    std::fill(min_.begin(), min_.end(),
              sp_.marked ? 1e300 : std::numeric_limits<double>::infinity());
    std::fill(max_.begin(), max_.end(),
              sp_.marked ? -1e300 : -std::numeric_limits<double>::infinity());
    Bytes v;
    auto add_vlr = [&](std::uint16_t id, const std::string& payload) {
      v.put<std::uint16_t>(0).fixed("LASF_Projection", 16).put<std::uint16_t>(id);
      v.put<std::uint16_t>(static_cast<std::uint16_t>(payload.size()))
          .fixed(sp_.marked ? "test" : "", 32)
          .str(payload);
      ++nvlr_;
    };
    if (!sp_.geokeys.empty()) {
      Bytes k;
      for (auto g : sp_.geokeys) k.put(g);
      add_vlr(34735, k.data());
    }
    if (!sp_.wkt.empty() && !sp_.wkt_in_evlr) add_vlr(2112, sp_.wkt + std::string(1, '\0'));
    vlrs_ = std::move(v.data());
    write(std::string(header_size(), '\0'));  // rewritten by close()
    write(vlrs_);
  }
  std::string evlrs() {
    if (sp_.wkt.empty() || !sp_.wkt_in_evlr) return "";  // (before 1.4 too: a bad file)
    const std::string payload = sp_.wkt + std::string(1, '\0');
    Bytes e;
    e.put<std::uint16_t>(0).fixed("LASF_Projection", 16).put<std::uint16_t>(2112);
    e.put<std::uint64_t>(payload.size()).fixed("wkt", 32).str(payload);
    return e.data();
  }
  std::string header(std::int64_t lie_count, std::uint32_t nevlr) const {
    const std::uint16_t hs = header_size();
    const std::uint32_t point_offset = hs + static_cast<std::uint32_t>(vlrs_.size());
    std::uint64_t declared = count_;
    if (lie_count >= 0)
      declared = static_cast<std::uint64_t>(lie_count);
    else if (sp_.declared >= 0)
      declared = static_cast<std::uint64_t>(sp_.declared);
    const int pf = sp_.point_format;
    Bytes h;
    h.str("LASF").put<std::uint16_t>(0);
    h.put<std::uint16_t>(sp_.marked && !sp_.wkt.empty() ? 16 : 0);  // global encoding: WKT bit
    h.fixed("", 16);
    h.put<std::uint8_t>(1).put<std::uint8_t>(static_cast<std::uint8_t>(sp_.minor));
    h.fixed("citylod test", 32).fixed(sp_.marked ? "citylod fixtures" : "citylod las_writer", 32);
    h.put<std::uint16_t>(sp_.marked ? 1 : 0).put<std::uint16_t>(sp_.marked ? 2024 : 0);
    h.put<std::uint16_t>(hs).put<std::uint32_t>(point_offset).put<std::uint32_t>(nvlr_);
    h.put<std::uint8_t>(static_cast<std::uint8_t>(pf | (sp_.compressed_bit ? 0x80 : 0)));
    h.put<std::uint16_t>(static_cast<std::uint16_t>(record_length()));
    std::uint32_t legacy = 0;
    if (sp_.legacy >= 0)
      legacy = static_cast<std::uint32_t>(sp_.legacy);
    else if (pf < 6 && declared <= 0xFFFFFFFFull)
      legacy = static_cast<std::uint32_t>(declared);
    h.put<std::uint32_t>(legacy);
    // points by return: all of return 1 (the plain flavour counts the points written)
    const auto first = sp_.marked ? legacy : static_cast<std::uint32_t>(count_);
    for (int i = 0; i < 5; ++i) h.put<std::uint32_t>(i == 0 ? first : 0);
    for (int a = 0; a < 3; ++a) h.put<double>(sp_.scale[a]);
    for (int a = 0; a < 3; ++a) h.put<double>(sp_.offset[a]);
    for (int a = 0; a < 3; ++a)
      h.put<double>(count_ ? max_[a] : 0.0).put<double>(count_ ? min_[a] : 0.0);
    if (sp_.minor >= 3) h.put<std::uint64_t>(0);  // waveform data
    if (sp_.minor >= 4) {
      const std::uint64_t evlr_start = nevlr ? point_offset + count_ * record_length() : 0;
      h.put<std::uint64_t>(evlr_start).put<std::uint32_t>(nevlr).put<std::uint64_t>(declared);
      for (int i = 0; i < 15; ++i) h.put<std::uint64_t>(i == 0 ? declared : 0);
    }
    if (h.data().size() != hs) throw std::logic_error("las_write: header size");
    return h.data();
  }

  LasSpec sp_;
  std::FILE* f_ = nullptr;
  std::string mem_;
  std::string vlrs_;
  std::uint32_t nvlr_ = 0;
  std::uint64_t count_ = 0;
  std::array<double, 3> min_{}, max_{};
};

/// A LAS file as bytes: `sp` with its points.
inline std::string make_las(const LasSpec& sp) {
  LasWriter w(sp);
  for (const auto& p : sp.points) w.add(p);
  w.close();
  return w.bytes();
}

}  // namespace citylod::test
