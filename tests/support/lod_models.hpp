// Picking and checking models of a LodResult (tests of the LOD engine).
#pragma once

#include "citylod/lod/lod.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <string>

namespace citylod::test {

inline const lod::LodModel* first_anchor(const lod::LodResult& r) {
  for (const auto& m : r.models)
    if (m.kind == lod::ModelKind::anchor) return &m;
  return nullptr;
}

/// The finest anchor (the last one of the candidate set).
inline const lod::LodModel* last_anchor(const lod::LodResult& r) {
  const lod::LodModel* a = nullptr;
  for (const auto& m : r.models)
    if (m.kind == lod::ModelKind::anchor) a = &m;
  return a;
}

/// True when one of the result's notes contains `what`.
inline bool has_note(const lod::LodResult& r, const std::string& what) {
  for (const auto& n : r.stats.notes)
    if (n.find(what) != std::string::npos) return true;
  return false;
}

inline int count_models(const lod::LodResult& r, lod::ModelKind k) {
  int n = 0;
  for (const auto& m : r.models) n += m.kind == k;
  return n;
}

/// A model is a valid solid: closed, edge-manifold, oriented, no pinched
/// vertex, one shell, no self-intersections (exact incidence).
inline void expect_closed_solid(const lod::LodModel& m) {
  const lod::MeshCheck c = lod::check_mesh(m.mesh);
  EXPECT_TRUE(c.closed) << c.boundary_edges << " boundary edges";
  EXPECT_TRUE(c.edge_manifold) << c.nonmanifold_edges << " non-manifold edges";
  EXPECT_TRUE(c.oriented);
  EXPECT_EQ(c.pinched_vertices, 0);
  EXPECT_EQ(c.shells, 1);
  EXPECT_FALSE(c.self_intersecting);
  EXPECT_GT(m.volume, 0.0);
}

/// Lowest z of a model's vertices.
inline double lowest_z(const lod::LodModel& m) {
  double z = std::numeric_limits<double>::infinity();
  for (const auto& v : m.mesh.vertices) z = std::min(z, v.z());
  return z;
}

/// Bounding box of a building input's points.
struct InputBox {
  lod::Vec3 lo, hi;
};
inline InputBox input_box(const lod::BuildingInput& in) {
  InputBox b{in.points.front(), in.points.front()};
  for (const auto& p : in.points) {
    b.lo = b.lo.cwiseMin(p);
    b.hi = b.hi.cwiseMax(p);
  }
  return b;
}

/// How far a model's vertices reach beyond a box (m; 0 when inside).
inline double overhang(const lod::LodModel& m, const InputBox& b) {
  double worst = 0;
  for (const auto& v : m.mesh.vertices)
    worst = std::max({worst, (b.lo - v).maxCoeff(), (v - b.hi).maxCoeff()});
  return worst;
}

}  // namespace citylod::test
