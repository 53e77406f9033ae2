// The one LAS reader of the tests: a LAS 1.0-1.4 file's header fields, its VLRs
// and its point records (xyz and class), of a file or of bytes. Independent of
// io/ (the geo and lod tests do not link it, and the io tests check io against
// known bytes); no validation beyond what it needs not to read out of bounds.
//
//   auto las = read_las(path);          // std::nullopt: no file or not LAS
//   las->wkt(), las->geokeys(), las->vlr("laszip encoded", 22204)->payload,
//   las->point(0).xyz, las->min, las->max, las->point_count
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

namespace citylod::test {

struct LasVlr {
  std::string user;          ///< user id (up to its first NUL)
  std::uint16_t record = 0;  ///< record id
  std::string payload;       ///< the record's bytes after its 54-byte header
};

struct LasRecord {
  std::array<double, 3> xyz{};  ///< scaled and offset
  int cls = 0;                  ///< classification (5 bits before format 6)
};

struct LasFile {
  std::string bytes;  ///< the whole file
  int major = 0, minor = 0;
  std::uint16_t header_size = 0;
  std::uint32_t point_offset = 0;
  int point_format = 0;  ///< without the compressed bits
  std::uint16_t record_length = 0;
  std::uint32_t legacy_count = 0;  ///< the 32-bit point count
  std::uint64_t point_count = 0;   ///< the 64-bit one in LAS 1.4 when the legacy count is 0
  std::array<double, 3> scale{}, offset{}, min{}, max{};
  std::vector<LasVlr> vlrs;  ///< the VLRs after the header (no EVLRs)

  /// The first VLR of `user` and `record`, or nullptr.
  const LasVlr* vlr(const std::string& user, std::uint16_t record) const {
    for (const auto& v : vlrs)
      if (v.user == user && v.record == record) return &v;
    return nullptr;
  }
  /// The OGC WKT (VLR 2112, LASF_Projection) up to its NUL, or "".
  std::string wkt() const {
    const LasVlr* v = vlr("LASF_Projection", 2112);
    return v ? std::string(v->payload.c_str()) : std::string();
  }
  /// The GeoKeyDirectory (VLR 34735) as u16 values, or empty.
  std::vector<std::uint16_t> geokeys() const {
    std::vector<std::uint16_t> k;
    if (const LasVlr* v = vlr("LASF_Projection", 34735))
      for (std::size_t i = 0; i + 1 < v->payload.size(); i += 2)
        k.push_back(get<std::uint16_t>(v->payload, i));
    return k;
  }
  /// Point record `k` (k < point_count, within the file: not checked).
  LasRecord point(std::uint64_t k) const {
    const std::size_t at = point_offset + k * record_length;
    LasRecord r;
    for (int a = 0; a < 3; ++a)
      r.xyz[a] = get<std::int32_t>(bytes, at + 4 * a) * scale[a] + offset[a];
    const auto c = static_cast<unsigned char>(bytes[at + (point_format >= 6 ? 16 : 15)]);
    r.cls = point_format >= 6 ? c : (c & 31);
    return r;
  }

  /// A little-endian value at byte `at` of `s`.
  template <typename T>
  static T get(const std::string& s, std::size_t at) {
    T v;
    std::memcpy(&v, s.data() + at, sizeof v);
    return v;
  }
};

/// `bytes` as a LAS file; std::nullopt when they are not one (no "LASF" or a short header).
inline std::optional<LasFile> parse_las(std::string bytes) {
  if (bytes.size() < 227 || bytes.compare(0, 4, "LASF") != 0) return std::nullopt;
  LasFile f;
  f.bytes = std::move(bytes);
  const std::string& b = f.bytes;
  auto get = [&](auto v, std::size_t at) { return LasFile::get<decltype(v)>(b, at); };
  f.major = static_cast<unsigned char>(b[24]);
  f.minor = static_cast<unsigned char>(b[25]);
  f.header_size = get(std::uint16_t{}, 94);
  f.point_offset = get(std::uint32_t{}, 96);
  const auto nvlr = get(std::uint32_t{}, 100);
  f.point_format = static_cast<unsigned char>(b[104]) & 0x3f;
  f.record_length = get(std::uint16_t{}, 105);
  f.legacy_count = f.point_count = get(std::uint32_t{}, 107);
  if (f.minor >= 4 && f.legacy_count == 0 && b.size() >= 255)
    f.point_count = get(std::uint64_t{}, 247);
  for (int a = 0; a < 3; ++a) {
    f.scale[a] = get(double{}, 131 + 8 * a);
    f.offset[a] = get(double{}, 155 + 8 * a);
    f.max[a] = get(double{}, 179 + 16 * a);
    f.min[a] = get(double{}, 187 + 16 * a);
  }
  std::size_t p = f.header_size;
  for (std::uint32_t i = 0; i < nvlr && p + 54 <= b.size(); ++i) {
    LasVlr v;
    v.user = std::string(b.c_str() + p + 2, strnlen(b.c_str() + p + 2, 16));
    v.record = get(std::uint16_t{}, p + 18);
    const std::size_t len = get(std::uint16_t{}, p + 20);
    v.payload = b.substr(p + 54, len);
    f.vlrs.push_back(std::move(v));
    p += 54 + len;
  }
  return f;
}

/// The LAS file at `path`; std::nullopt when it cannot be read or is no LAS file.
inline std::optional<LasFile> read_las(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  return parse_las(
      std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()));
}

}  // namespace citylod::test
