// Ray-casting in/out labelling (Appendix C of the paper).
#include "labelling.hpp"

#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace citylod::lod::detail {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Triangle = K::Triangle_3;
using Ray = K::Ray_3;
using TriIter = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<K, TriIter>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;

/// Uniform directions on the sphere (Fibonacci lattice), slightly rotated so
/// no direction is exactly parallel to an axis-aligned plane.
std::vector<Vec3> sphere_directions(int n) {
  std::vector<Vec3> dirs;
  dirs.reserve(static_cast<size_t>(n));
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  const double tilt = 0.1234;  // radians, breaks axis alignment
  const double ct = std::cos(tilt), st = std::sin(tilt);
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - (2.0 * i + 1.0) / n;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double phi = golden * i + 0.0371;
    Vec3 d(r * std::cos(phi), r * std::sin(phi), z);
    // rotate about x, then about y
    d = Vec3(d.x(), ct * d.y() - st * d.z(), st * d.y() + ct * d.z());
    d = Vec3(ct * d.x() + st * d.z(), d.y(), -st * d.x() + ct * d.z());
    dirs.push_back(d.normalized());
  }
  return dirs;
}

}  // namespace

struct RayLabeller::Impl {
  std::vector<Triangle> tris;
  std::vector<Vec3> normals;  // unit, outward
  std::vector<int> level;
  std::vector<Vec3> dirs;
  Tree tree;
  int max_level = 0;
};

RayLabeller::RayLabeller(const LevelTriangles& in, int rays) : impl_(std::make_unique<Impl>()) {
  auto& I = *impl_;
  I.dirs = sphere_directions(std::max(1, rays));
  for (size_t i = 0; i < in.triangles.size(); ++i) {
    const auto& t = in.triangles[i];
    const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]);
    if (!(n.norm() > 1e-12)) continue;  // degenerate (or NaN)
    I.tris.emplace_back(Point(t[0].x(), t[0].y(), t[0].z()), Point(t[1].x(), t[1].y(), t[1].z()),
                        Point(t[2].x(), t[2].y(), t[2].z()));
    I.normals.push_back(n.normalized());
    I.level.push_back(in.level[i]);
    I.max_level = std::max(I.max_level, in.level[i]);
  }
  if (!I.tris.empty()) {
    I.tree.insert(I.tris.cbegin(), I.tris.cend());
    I.tree.build();
  }
}

RayLabeller::~RayLabeller() = default;

std::vector<std::vector<char>> RayLabeller::label(const std::vector<Vec3>& centres, int num_levels,
                                                  int threads) const {
  std::vector<std::vector<Vec3>> origins;
  origins.reserve(centres.size());
  for (const auto& c : centres) origins.push_back({c});
  return label(origins, num_levels, threads);
}

std::vector<std::vector<char>> RayLabeller::label(const std::vector<std::vector<Vec3>>& origins,
                                                  int num_levels, int threads) const {
  const auto& I = *impl_;
  const int L = std::max(1, num_levels);
  std::vector<std::vector<char>> out(origins.size(), std::vector<char>(static_cast<size_t>(L), 0));
  if (I.tris.empty()) return out;
  const int nrays = static_cast<int>(I.dirs.size());
  const long n = static_cast<long>(origins.size());

#pragma omp parallel for schedule(dynamic, 16) num_threads(std::max(1, threads))
  for (long c = 0; c < n; ++c) {
    const auto& cell_origins = origins[static_cast<size_t>(c)];
    std::vector<int> votes_in(static_cast<size_t>(L), 0);
    std::vector<int> grazing;  // triangles a ray lies in: no vote, looked through
    for (int r = 0; r < nrays; ++r) {
      const Vec3& u = I.dirs[static_cast<size_t>(r)];
      const Vec3& o = cell_origins[static_cast<size_t>(r) % cell_origins.size()];
      const Ray ray(Point(o.x(), o.y(), o.z()), K::Vector_3(u.x(), u.y(), u.z()));
      // First hit per level: triangles of level <= k count for label k. The
      // nearest hit of any level decides the labels from its level up; then the
      // nearest hit among the lower levels only, and so on down to level 0.
      int bound = L;  // levels [bound, L) already decided
      grazing.clear();
      while (bound > 0) {
        const auto skip = [&](TriIter it) {
          const int id = static_cast<int>(it - I.tris.cbegin());
          return I.level[static_cast<size_t>(id)] >= bound ||
                 std::find(grazing.begin(), grazing.end(), id) != grazing.end();
        };
        const auto hit = I.tree.first_intersection(ray, skip);
        if (!hit) break;
        const int id = static_cast<int>(hit->second - I.tris.cbegin());
        if (!boost::get<Point>(&hit->first)) {  // the ray lies in the triangle's plane
          grazing.push_back(id);
          continue;
        }
        const int lv = I.level[static_cast<size_t>(id)];
        const bool in = I.normals[static_cast<size_t>(id)].dot(u) > 0.0;
        for (int k = lv; k < bound; ++k) votes_in[static_cast<size_t>(k)] += in ? 1 : 0;
        bound = lv;
      }
    }
    for (int k = 0; k < L; ++k)
      out[static_cast<size_t>(c)][static_cast<size_t>(k)] =
          (2 * votes_in[static_cast<size_t>(k)] > nrays) ? 1 : 0;
  }
  return out;
}

std::pair<int, int> RayLabeller::half_space_votes(const Vec3& origin, const Vec3& side) const {
  const auto& I = *impl_;
  int in = 0, cast = 0;
  if (I.tris.empty()) return {0, 0};
  const Point o(origin.x(), origin.y(), origin.z());
  for (const auto& u : I.dirs) {
    if (!(u.dot(side) > 0)) continue;
    ++cast;
    const Ray ray(o, K::Vector_3(u.x(), u.y(), u.z()));
    const auto skip = [&](TriIter it) {
      return I.level[static_cast<size_t>(it - I.tris.cbegin())] > 0;
    };
    const auto hit = I.tree.first_intersection(ray, skip);
    if (!hit || !boost::get<Point>(&hit->first)) continue;
    if (I.normals[static_cast<size_t>(hit->second - I.tris.cbegin())].dot(u) > 0.0) ++in;
  }
  return {in, cast};
}

}  // namespace citylod::lod::detail
