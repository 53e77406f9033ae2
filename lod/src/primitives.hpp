// Internal: samples of the input surface and planar primitives (plane
// detection, alpha-shapes, convex hulls, closure planes, regularization of the
// principal planes). Implemented in primitives.cpp / closure.cpp (CGAL inside).
#pragma once

#include "citylod/lod/lod.hpp"

#include <array>
#include <cstdint>
#include <memory>
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
};

/// A planar primitive with its alpha-shape and convex hull.
struct Primitive {
  Vec3 normal = Vec3::UnitZ();  ///< unit, oriented like its inliers' normals (outward)
  double d = 0.0;               ///< plane: normal.dot(x) + d = 0
  std::vector<int> inliers;     ///< indices into Samples
  Vec3 centroid = Vec3::Zero();
  Vec3 u = Vec3::UnitX(), v = Vec3::UnitY();  ///< orthonormal in-plane axes, u x v = normal
  std::vector<Vec3> hull;  ///< convex hull of the projected inliers, CCW about normal
  std::vector<std::array<Vec3, 3>> alpha_tris;  ///< alpha-shape as triangles on the plane
  double hull_area = 0.0;
  double alpha_area = 0.0;
  bool inferred = false;       ///< closure plane (ground / outline wall), not detected
  bool from_template = false;  ///< cuboid template face
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

/// Region growing (CGAL Shape_detection): on the points of a cloud, on the
/// faces of a mesh. Deterministic. Largest planes first; at most p.max_planes.
std::vector<Primitive> detect_planes(const BuildingInput& in, const Samples& s,
                                     const PlaneParams& p);

/// (Re)computes centroid, u/v, hull and alpha-shape of a primitive from its
/// inliers projected on its current plane.
void compute_shape(Primitive& prim, const Samples& s, const AlphaParams& p);

/// Airborne LiDAR closure: when walls are missing (few near-horizontal
/// normals), adds a ground plane and vertical walls through the outline (the
/// footprint when given, else a 2D alpha-shape of the samples, simplified).
/// With p.footprint_walls, walls go along a given footprint even when some
/// walls were scanned. An open bottom gets a base plane; a terrain sheet
/// (params.terrain) becomes a plinth (base + walls along the scene's outline)
/// or is cut off.
struct Closure {
  enum What { None, Base, Walls, FootprintWalls, Plinth };
  int added = 0;  ///< primitives added
  What what = None;
  std::vector<Vec2> outline;  ///< the outline the walls stand on (CCW), when walls were inferred
  double ground_z = 0;        ///< the ground plane's height
};
Closure close_building(const BuildingInput& in, const Samples& s, const ClosureParams& p,
                       std::vector<Primitive>& prims);

class HeightField;
/// (ours) Vertical walls where a roof steps down (airborne LiDAR has no wall
/// points there): along each edge of a roof plane's simplified 2D alpha
/// outline across which the height field `hf`, probed p.step_probe beyond the
/// edge and inside the outline, lies more than p.step_min below the plane.
/// Edge directions within 15 degrees of an outline edge's are snapped to it.
/// Each wall reaches from the ground to the plane's top along the edge.
/// Returns the number of walls added (inferred primitives).
int infer_step_walls(const Samples& s, const HeightField& hf, const AirborneParams& p,
                     std::vector<Primitive>& prims);

/// Mild regularization of the principal primitives (CGAL Shape_regularization:
/// parallelism, orthogonality, coplanarity; angle/distance from p). Only the
/// primitives listed in `which` are changed; shapes are recomputed.
void regularize_principal(std::vector<Primitive>& prims, const std::vector<int>& which,
                          const Samples& s, const RegularizationParams& p, const AlphaParams& a);

/// e1 (model -> input) and e2 (input -> model) RMSE in % of `diag`, and the
/// symmetric Hausdorff estimate in metres. The input surface is the mesh when
/// `in` is a mesh, else the points.
struct Fidelity {
  double e1 = 0, e2 = 0, hausdorff = 0;
};
Fidelity measure_fidelity(const TriangleMesh& model, const BuildingInput& in, const Samples& s,
                          double diag, int model_samples);

/// The same, for many models of one building: the input's search structures
/// are built once. e2 uses at most `samples` input samples (an even stride
/// over them, weights kept). measure() is const and thread-safe.
class FidelityMeter {
 public:
  FidelityMeter(const BuildingInput& in, const Samples& s, double diag, int samples);
  ~FidelityMeter();
  Fidelity measure(const TriangleMesh& model) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace citylod::lod::detail
