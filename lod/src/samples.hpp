// Internal: the input surface as oriented samples (paper Section 4.1 input),
// and the deterministic random numbers the LOD steps draw. Implemented in
// samples.cpp (CGAL inside).
#pragma once

#include "citylod/lod/lod.hpp"

#include <cstdint>
#include <vector>

namespace citylod::lod::detail {

/// The input surface as oriented samples. For a point cloud: the points
/// (normals estimated when missing). For a mesh: one sample per face centroid
/// plus area-proportional extra samples, normals = face normals; `face_of[i]`
/// gives the source triangle (or -1).
struct Samples {
  std::vector<Vec3> points;
  std::vector<Vec3> normals;    ///< unit, pointing out of the building
  std::vector<double> weights;  ///< area represented by each sample (m^2); 1 for point clouds
  std::vector<int> face_of;     ///< mesh input: triangle index of each sample
  bool normals_estimated = false;
  /// When every normal was estimated: each sample's nearest samples as the
  /// normal estimation found them (itself first, then by distance), sample i's
  /// at [i * neighbours_each, (i + 1) * neighbours_each). Plane detection reuses
  /// them instead of a second k-d tree and search (its k <= neighbours_each).
  std::vector<std::uint32_t> neighbours;
  std::size_t neighbours_each = 0;
};

/// Deterministic pseudo-random numbers (splitmix64): the same sequence on
/// every platform and thread count.
struct Rng {
  std::uint64_t s;
  explicit Rng(std::uint64_t seed) : s(seed) {}
  std::uint64_t next_u64() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1).
  double next() { return static_cast<double>(next_u64() >> 11) * (1.0 / 9007199254740992.0); }
};

/// Builds the oriented samples; estimates and orients normals when missing.
/// `mst_orientation` false skips the minimum-spanning-tree propagation (the
/// roofs-up / away-from-the-axis rules alone orient the normals).
Samples make_samples(const BuildingInput& in, const NormalParams& p, bool mst_orientation = true);

}  // namespace citylod::lod::detail
