// Minimal LAS 1.x header/VLR scan for the geo tests: the OGC WKT record (id 2112), the
// GeoTIFF keys (34735) and the first point. Not a LAS reader; io/ owns that.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

namespace citylod::geo::test {

struct LasInfo {
  std::string wkt;                      // empty when there is no WKT VLR
  std::vector<uint16_t> geokeys;        // raw 34735 record
  std::array<double, 3> first_point{};  // scaled + offset
  std::array<double, 6> bbox{};         // min x, y, z, max x, y, z
};

template <class T>
T get(const std::vector<char>& b, size_t at) {
  T v;
  std::memcpy(&v, b.data() + at, sizeof v);
  return v;
}

inline std::optional<LasInfo> scan_las(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return std::nullopt;
  std::vector<char> b((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (b.size() < 227 || std::string(b.data(), 4) != "LASF") return std::nullopt;
  LasInfo info;
  const auto header_size = get<uint16_t>(b, 94);
  const auto point_offset = get<uint32_t>(b, 96);
  const auto nvlr = get<uint32_t>(b, 100);
  size_t p = header_size;
  for (uint32_t i = 0; i < nvlr && p + 54 <= b.size(); ++i) {
    const auto id = get<uint16_t>(b, p + 18);
    const auto len = get<uint16_t>(b, p + 20);
    const char* data = b.data() + p + 54;
    if (id == 2112 && info.wkt.empty()) info.wkt.assign(data, strnlen(data, len));
    if (id == 34735)
      for (size_t k = 0; k + 1 < len; k += 2) info.geokeys.push_back(get<uint16_t>(b, p + 54 + k));
    p += 54 + len;
  }
  double scale[3], offset[3];
  for (int a = 0; a < 3; ++a) {
    scale[a] = get<double>(b, 131 + 8 * a);
    offset[a] = get<double>(b, 155 + 8 * a);
    info.bbox[3 + a] = get<double>(b, 179 + 16 * a);  // max x, max y, max z
    info.bbox[a] = get<double>(b, 187 + 16 * a);      // min x, min y, min z
    info.first_point[a] = get<int32_t>(b, point_offset + 4 * a) * scale[a] + offset[a];
  }
  return info;
}

}  // namespace citylod::geo::test
