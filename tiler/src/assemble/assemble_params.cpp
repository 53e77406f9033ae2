// AssembleParams::validate(), apart from the assembly itself: the work
// directory's records (workdir.cpp) check the parameters a run report names,
// and the records' fuzz harness links them without the LOD engine.
#include "citylod/tiler/assemble.hpp"

#include <cmath>
#include <stdexcept>

namespace citylod::tiler {

void AssembleParams::validate() const {
  if (max_tile_triangles < 1) throw std::invalid_argument("max_tile_triangles must be >= 1");
  if (max_tile_bytes < 1024) throw std::invalid_argument("max_tile_bytes must be >= 1024");
  if (!(tile_extent_factor >= 0) || !std::isfinite(tile_extent_factor))
    throw std::invalid_argument("tile_extent_factor must be >= 0");
  if (!(min_tile_extent_m >= 0) || !std::isfinite(min_tile_extent_m))
    throw std::invalid_argument("min_tile_extent_m must be >= 0");
  if (max_tiles_per_file < 1) throw std::invalid_argument("max_tiles_per_file must be >= 1");
  if (!(min_change_m >= 0) || !std::isfinite(min_change_m))
    throw std::invalid_argument("min_change_m must be >= 0");
  if (!(hausdorff_tolerance_m > 0) || !std::isfinite(hausdorff_tolerance_m))
    throw std::invalid_argument("hausdorff_tolerance_m must be > 0");
  if (threads < 0) throw std::invalid_argument("threads must be >= 0");
}

}  // namespace citylod::tiler
