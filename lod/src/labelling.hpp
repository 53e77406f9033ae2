// Internal: in/out labelling of polyhedra by ray casting against the
// alpha-shapes of the primitives (paper, Appendix C). Implemented in
// labelling.cpp (a BVH with CGAL's exact-predicate ray-triangle
// intersection and exact tie-breaks inside).
#pragma once

#include "citylod/lod/types.hpp"

#include <array>
#include <memory>
#include <vector>

namespace citylod::lod::detail {

/// Triangles of alpha-shapes, each CCW about its primitive's outward normal,
/// tagged with the level set of its primitive (0 = principal).
struct LevelTriangles {
  std::vector<std::array<Vec3, 3>> triangles;
  std::vector<int> level;
};

class RayLabeller {
 public:
  /// How the first hit of a ray is found. Both give the same hit: the
  /// triangle the ray meets first by exact predicates and exact parameters,
  /// the lowest index at an exact tie. `exact_brute_force` tries every
  /// triangle with exact constructions (slow: the tests' reference).
  enum class Method { bvh, exact_brute_force };

  /// `rays`: rays per cell, uniformly distributed directions (Fibonacci sphere).
  RayLabeller(const LevelTriangles& tris, int rays, Method method = Method::bvh);
  ~RayLabeller();

  /// Labels for each centre and each level 0..num_levels-1: label k uses the
  /// triangles of levels <= k. A ray votes "in" when the first triangle it hits
  /// faces away from the centre (u.n > 0), "out" when it faces towards it or
  /// nothing is hit; a cell is in when more than half of its rays vote in.
  /// Result [cell][level] in {0,1}. Deterministic; parallel over cells with
  /// `threads` OpenMP threads.
  std::vector<std::vector<char>> label(const std::vector<Vec3>& centres, int num_levels,
                                       int threads) const;

  /// The same with several ray origins per cell (the rays are spread over
  /// them in turn): thin cells that reach far out of the building are judged
  /// by where their volume is, not by one centre point.
  std::vector<std::vector<char>> label(const std::vector<std::vector<Vec3>>& origins,
                                       int num_levels, int threads) const;

  /// Rays of level 0 from `origin` into the half-space `side` points to
  /// (u.side > 0 only): {rays voting in, rays cast}. Tells which side of a
  /// surface the triangles around it see as inside.
  std::pair<int, int> half_space_votes(const Vec3& origin, const Vec3& side) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace citylod::lod::detail
