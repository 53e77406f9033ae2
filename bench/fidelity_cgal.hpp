// CGAL 5.5 Garland-Heckbert edge-collapse simplification for fidelity_bench.
// The CGAL code lives in fidelity_cgal.cpp only (it compiles slowly); this
// header is plain data.
#pragma once

#include "citylod/lod/types.hpp"

#include <cstddef>
#include <memory>

namespace citylod::bench {

/// What it took to turn the input triangle soup into a valid CGAL::Surface_mesh.
struct GhRepairStats {
  std::size_t input_triangles = 0, input_vertices = 0;
  std::size_t soup_polygons = 0, soup_points = 0;  ///< after repair_polygon_soup
  bool oriented_without_duplication = false;       ///< orient_polygon_soup's return value
  std::size_t oriented_points = 0;  ///< after orient_polygon_soup (non-manifold points duplicated)
  std::size_t mesh_faces = 0, mesh_vertices = 0;  ///< the Surface_mesh that is simplified
  std::size_t lost_triangles = 0;                 ///< input_triangles - mesh_faces
  std::size_t nonmanifold_vertices_split = 0;  ///< by duplicate_non_manifold_vertices on the mesh
};

/// CGAL_VERSION_STR of the CGAL the bench was built with.
const char* cgal_version();

/// Holds the repaired input; simplify() runs a fresh GH edge collapse on a copy.
class GhSimplifier {
 public:
  /// Repairs `input` (a triangle mesh) into a Surface_mesh:
  /// repair_polygon_soup + orient_polygon_soup + polygon_soup_to_polygon_mesh.
  explicit GhSimplifier(const lod::TriangleMesh& input);
  ~GhSimplifier();
  GhSimplifier(const GhSimplifier&) = delete;
  GhSimplifier& operator=(const GhSimplifier&) = delete;

  const GhRepairStats& stats() const;

  /// SMS::edge_collapse with GarlandHeckbert_plane_policies (cost and
  /// placement) until at most `target_triangles` faces remain (or no edge can
  /// be collapsed any more). Deterministic.
  lod::TriangleMesh simplify(std::size_t target_triangles) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace citylod::bench
