// Internal: (ours) airborne LiDAR is 2.5D. A scan from above sees roofs and
// hardly any walls, so the paper's ray labelling (App. C) has nothing to hit
// sideways above a lower roof part and fills it up to the highest roof. For a
// point cloud whose walls were inferred (closure), the building is what lies
// under its roof surface and inside its outline:
//   - HeightField: a robust roof height raster of the samples over the outline
//     (median per cell, gaps filled from neighbours);
//   - infer_step_walls: vertical walls along the edges of roof
//     planes where the roof drops by more than a step (BSP/IO-View primitives,
//     so a lower roof part bounds its own cells);
//   - label_by_height: a cell is in when most of its ray origins lie inside the
//     outline, above the ground and under the roof surface;
//   - block_model: the LoD1.2-style block (outline extruded to the height that
//     fits the points best), the coarsest model of the chain.
#pragma once

#include "planes.hpp"

#include <vector>

namespace citylod::lod::detail {

class HeightField {
 public:
  /// Roof heights of `s` over the polygon `outline` (CCW, xy) with the cell
  /// size and gap filling of `p`. Heights below roof_floor() are not roof.
  HeightField(const Samples& s, const std::vector<Vec2>& outline, double ground_z,
              const AirborneParams& p);

  /// Roof height at p; NaN outside the outline's grid or where no roof point
  /// is within the fill radius.
  double at(const Vec2& p) const;
  /// Exact point-in-polygon test against the outline.
  bool inside(const Vec2& p) const;
  double ground() const { return ground_; }
  /// The samples' 98th-percentile height above the ground (m).
  double top() const { return top_; }
  /// Lowest roof height: the ground + 0.5 m, or + top() / 2 when top() is
  /// under 1 m.
  double roof_floor() const { return roof_floor_; }
  const std::vector<Vec2>& outline() const { return outline_; }
  /// Share of the outline's cells (centre inside) holding roof returns,
  /// before gaps are filled: what the scan saw of the roof.
  double roof_coverage() const { return roof_coverage_; }

 private:
  std::vector<Vec2> outline_;
  double ground_ = 0, top_ = 0, roof_floor_ = 0.5, cell_ = 0.5;
  Vec2 lo_ = Vec2::Zero();
  int nx_ = 0, ny_ = 0;
  double roof_coverage_ = 0;
  std::vector<float> z_;  ///< NaN = no data
};

/// (ours) Vertical walls where a roof steps down (airborne LiDAR has no wall
/// points there): along each edge of a roof plane's simplified 2D alpha
/// outline across which the height field `hf`, probed p.step_probe beyond the
/// edge and inside the outline, lies more than p.step_min below the plane.
/// Edge directions within 15 degrees of an outline edge's are snapped to it.
/// Each wall reaches from the ground to the plane's top along the edge.
/// Returns the number of walls added (inferred primitives).
int infer_step_walls(const Samples& s, const HeightField& hf, const AirborneParams& p,
                     std::vector<Primitive>& prims);

/// Robust refit of the roof planes (detected, normal.z > 0.3) of airborne
/// input: Tukey-weighted least squares, edge points (within
/// `p.roof_edge_margin` of `outline`) weighted down; shapes recomputed with
/// `alpha`. Returns the number of planes refitted.
int refit_roof_planes(const Samples& s, const std::vector<Vec2>& outline, const AirborneParams& p,
                      const AlphaParams& alpha, std::vector<Primitive>& prims);

/// In/out per leaf from its ray origins: in when more than half of them lie
/// inside the outline, above the ground and under the roof height.
/// Returns one label per leaf (the same at every level).
std::vector<char> label_by_height(const std::vector<std::vector<Vec3>>& origins,
                                  const HeightField& hf);

/// The samples against the outline (its ring without repeated or collinear
/// vertices): each one's distance to it and whether it lies inside. Shared by
/// the block and the roof fit.
struct OutlineDistances {
  std::vector<Vec2> ring;
  std::vector<double> dist;
  std::vector<char> inside;
};
OutlineDistances outline_distances(const Samples& s, const HeightField& hf);

/// The outline extruded from the ground to the height that minimises the
/// RMSE of the samples to the block (a scan over the samples' roof height
/// quantiles); `od` = outline_distances(s, hf). Throws LodError when the
/// outline is not a simple polygon.
LodModel block_model(const Samples& s, const HeightField& hf, const OutlineDistances& od);

/// (ours) Airborne LiDAR sees a building from above. The returns a roof fit
/// measures: the samples inside the outline and farther than `edge_margin`
/// from it (at most half the depth of the deepest sample, so that a small
/// outline keeps some).
std::vector<Vec3> roof_returns(const Samples& s, const OutlineDistances& od, double edge_margin);

/// The RMSE of the vertical residuals of `returns` each to the highest
/// surface of `m` over it above `ground` (the ground where the model has
/// none). NaN when the model lies over fewer than half of the returns (a
/// fragment, a sliver: over a patch at the ground's level it would fit).
double roof_rmse(const TriangleMesh& m, const std::vector<Vec3>& returns, double ground);

/// (ours) When the finest anchor after the block (models[0]) fits worse than
/// the block -- a larger e2 and a roof fit (roof_rmse) that is not better, or
/// not measured -- (an IO-View core that missed part of the building, cells
/// under a roof without returns), the models after the block that fit worse
/// in the same sense are dropped (more triangles and a larger error help no
/// level) and the finest is the best anchor left, or the block. A chain whose
/// finest beats the block either way is kept whole: a tall block can have the
/// smaller e2 only because walls lie near returns under its top (a low shed
/// under a tree), while the scanner saw a lower roof. Steps are renumbered.
/// Returns how many were dropped.
int drop_worse_than_block(std::vector<LodModel>& models);

/// (ours) The chain's last level -- its finest anchor and the models after the
/// anchor before it -- when that anchor fits worse than the anchor before it
/// in the sense above (a larger e2 and a roof fit that is not better): finer
/// cells that follow tree returns over a roof up to the canopy refine nothing.
/// Repeated while it holds; the block (models[0]) is left to
/// drop_worse_than_block. Steps are renumbered. Returns how many were dropped.
int drop_worse_last_levels(std::vector<LodModel>& models);

/// (ours) A low object's chain (IO-View took every plane bounding its core as
/// principal): the models after the block (models[0]) with a larger e2 than
/// the block's are dropped, whatever their roof fit -- a roof plane tilted
/// through the ground leaves a wedge whose roof follows the returns while
/// most of the slab is missing. Steps are renumbered. Returns how many were
/// dropped; only the block left means the tree did not model the object.
int drop_low_object_worse_than_block(std::vector<LodModel>& models);

}  // namespace citylod::lod::detail
