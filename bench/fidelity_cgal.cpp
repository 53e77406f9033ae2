// CGAL 5.5 Garland-Heckbert simplification for fidelity_bench (see fidelity_cgal.hpp).
//
// Stop condition: CGAL 5.5's Count_stop_predicate counts EDGES
// (Count_stop_predicate.h: stop when current_edge_count < threshold); the
// face-count predicate arrived only in CGAL 5.6. On a mesh with boundaries the
// edge count does not map to a face count, so we stop on the face count of the
// mesh being collapsed (Surface_mesh::number_of_faces() excludes removed
// faces), which is what "same triangle count" needs.
#include "fidelity_cgal.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>
#include <CGAL/version.h>

#include <stdexcept>
#include <vector>

namespace citylod::bench {

namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Mesh = CGAL::Surface_mesh<K::Point_3>;
namespace PMP = CGAL::Polygon_mesh_processing;
namespace SMS = CGAL::Surface_mesh_simplification;

/// Stops the collapse once the mesh has at most `target` faces.
struct FaceCountStop {
  const Mesh* mesh;
  std::size_t target;
  template <typename F, typename Profile>
  bool operator()(const F& /*cost*/, const Profile& /*profile*/, std::size_t /*initial_edges*/,
                  std::size_t /*current_edges*/) const {
    return mesh->number_of_faces() <= target;
  }
};

}  // namespace

const char* cgal_version() {
  return CGAL_VERSION_STR;
}

struct GhSimplifier::Impl {
  Mesh mesh;
  GhRepairStats stats;
};

GhSimplifier::GhSimplifier(const lod::TriangleMesh& input) : impl_(std::make_unique<Impl>()) {
  GhRepairStats& s = impl_->stats;
  s.input_triangles = input.triangles.size();
  s.input_vertices = input.vertices.size();
  std::vector<K::Point_3> points;
  points.reserve(input.vertices.size());
  for (const auto& v : input.vertices) points.emplace_back(v.x(), v.y(), v.z());
  std::vector<std::vector<std::size_t>> polygons;
  polygons.reserve(input.triangles.size());
  for (const auto& t : input.triangles)
    polygons.push_back({std::size_t(t[0]), std::size_t(t[1]), std::size_t(t[2])});

  // Merges duplicate points, removes degenerate / duplicate polygons and isolated points.
  PMP::repair_polygon_soup(points, polygons);
  s.soup_polygons = polygons.size();
  s.soup_points = points.size();
  // Consistent orientation; points at non-manifold vertices/edges are duplicated.
  s.oriented_without_duplication = PMP::orient_polygon_soup(points, polygons);
  s.oriented_points = points.size();
  if (!PMP::is_polygon_soup_a_polygon_mesh(polygons))
    throw std::runtime_error("CGAL: the repaired soup is still not a polygon mesh");
  PMP::polygon_soup_to_polygon_mesh(points, polygons, impl_->mesh);
  s.nonmanifold_vertices_split = PMP::duplicate_non_manifold_vertices(impl_->mesh);
  if (!CGAL::is_valid_polygon_mesh(impl_->mesh) || !CGAL::is_triangle_mesh(impl_->mesh))
    throw std::runtime_error("CGAL: the repaired mesh is not a valid triangle mesh");
  s.mesh_faces = impl_->mesh.number_of_faces();
  s.mesh_vertices = impl_->mesh.number_of_vertices();
  s.lost_triangles = s.input_triangles > s.mesh_faces ? s.input_triangles - s.mesh_faces : 0;
}

GhSimplifier::~GhSimplifier() = default;

const GhRepairStats& GhSimplifier::stats() const {
  return impl_->stats;
}

lod::TriangleMesh GhSimplifier::simplify(std::size_t target_triangles) const {
  Mesh m = impl_->mesh;
  if (m.number_of_faces() > target_triangles) {
    SMS::GarlandHeckbert_plane_policies<Mesh, K> gh(m);
    const FaceCountStop stop{&m, target_triangles};
    SMS::edge_collapse(m, stop,
                       CGAL::parameters::get_cost(gh.get_cost()).get_placement(gh.get_placement()));
  }
  lod::TriangleMesh out;
  auto index = m.add_property_map<Mesh::Vertex_index, int>("v:bench_index", -1).first;
  for (const auto v : m.vertices()) {
    index[v] = int(out.vertices.size());
    const auto& p = m.point(v);
    out.vertices.emplace_back(p.x(), p.y(), p.z());
  }
  for (const auto f : m.faces()) {
    std::array<int, 3> t{};
    int k = 0;
    for (const auto v : CGAL::vertices_around_face(m.halfedge(f), m)) {
      if (k < 3) t[std::size_t(k)] = index[v];
      ++k;
    }
    if (k == 3) out.triangles.push_back(t);
  }
  return out;
}

}  // namespace citylod::bench
