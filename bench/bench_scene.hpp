// Scenes for the scaling benchmarks (split_bench, tile_bench): a real LAS tile
// repeated N times side by side into one LAS.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>

#include "citylod/io/reader.hpp"
#include "support/las_write.hpp"

namespace citylod::bench {

/// Writes `out`: N copies of the LAS `in` on a ceil(sqrt(N)) x ceil(sqrt(N))
/// grid (copy c at column c % side, row c / side), 20 m apart, in the input's
/// CRS units, classes kept, 1 mm resolution. Returns the point count.
inline std::uint64_t write_tiled_las(const std::string& in, const std::string& out, int n) {
  const io::FileInfo h = io::read_header(in);
  const int side = static_cast<int>(std::ceil(std::sqrt(double(n))));
  const double dx = h.bbox.max[0] - h.bbox.min[0] + 20, dy = h.bbox.max[1] - h.bbox.min[1] + 20;
  test::LasWriter w(out, {0.001, 0.001, 0.001},
                    {std::floor(h.bbox.min[0]), std::floor(h.bbox.min[1]), 0});
  for (int c = 0; c < n; ++c) {
    const double ox = (c % side) * dx, oy = (c / side) * dy;
    auto r = io::PointReader::open(in);
    io::PointSet b;
    while (r->read(b, 1 << 16) > 0)
      for (std::size_t k = 0; k < b.size(); ++k)
        w.add(b.positions[k][0] + ox, b.positions[k][1] + oy, b.positions[k][2],
              b.has_classes() ? b.classes[k] : 1);
  }
  const std::uint64_t count = w.count();
  w.close();
  return count;
}

}  // namespace citylod::bench
