// Input colours onto the faces of the models (ours: the paper has no colour).
#pragma once

#include "citylod/lod/lod.hpp"
#include "samples.hpp"

#include <vector>

namespace citylod::lod::detail {

/// The input points (with their colours) sorted into a grid once per
/// building, shared by every model.
class ColourSource {
 public:
  /// points, their unit outward normals (zero: fits no face) and colours.
  ColourSource(const std::vector<Vec3>& points, const std::vector<Vec3>& normals,
               const std::vector<Rgb8>& colours, const ColourParams& p);
  bool empty() const { return points_.empty(); }

  /// One colour per face (faces: polygons, each a CCW loop of `vertices`).
  /// A point goes to the nearest face within ColourParams::distance (point
  /// to polygon) whose normal is within max_angle_deg of the point's (at a
  /// tie the face with the nearer plane, then the lower index). Coplanar faces sharing an edge form
  /// a plane region; a region with >= min_points points gets their per-channel median, a = 255; the
  /// other faces a = 0.
  std::vector<Rgba8> faces(const std::vector<Vec3>& vertices,
                           const std::vector<std::vector<int>>& faces) const;

 private:
  std::vector<Vec3> points_, normals_;
  std::vector<Rgb8> colours_;
  ColourParams p_;
  double cell_ = 1.0;
  Vec3 lo_;
  // cell (ix, iy, iz) -> point indices, cells sorted by key
  std::vector<std::pair<long long, std::vector<int>>> cells_;
  long long key(long long ix, long long iy, long long iz) const;
  const std::vector<int>* cell(long long k) const;
};

/// Sets polygon_colours and triangle_colours of every model (nothing when the
/// input has no colours or colour.enabled is false).
void colour_models(const BuildingInput& in, const Samples& samples, const ColourParams& p,
                   std::vector<LodModel>& models, int threads);

}  // namespace citylod::lod::detail
