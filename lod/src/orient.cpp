// Consistent orientation of the detected planes. Ray labelling reads a
// primitive's normal as "outside is this way"; a plane whose input normals
// point into the building (a flipped facade patch in a scan, a floor seen
// through a window) turns the cells behind it out. Each plane asks the
// others: rays cast into the half-space in front of it and into the one
// behind it vote in/out (level-0 labelling rule); when the front looks
// inside, the back outside, and the two differ clearly, the plane is turned
// round.
#include "orient.hpp"

#include "labelling.hpp"

#include <algorithm>
#include <cmath>

namespace citylod::lod::detail {

namespace {

void turn_round(Primitive& p) {
  p.normal = -p.normal;
  p.d = -p.d;
  std::swap(p.u, p.v);  // u x v = normal again
  std::reverse(p.hull.begin(), p.hull.end());
  for (auto& t : p.alpha_tris) std::swap(t[1], t[2]);
}

}  // namespace

int orient_primitives(std::vector<Primitive>& prims, const Samples& s, const OrientParams& p,
                      int threads) {
  if (!p.enabled || prims.size() < 2) return 0;
  LevelTriangles tris;
  for (const auto& pr : prims)
    for (const auto& t : pr.alpha_tris) {
      tris.triangles.push_back(t);
      tris.level.push_back(0);
    }
  const RayLabeller labeller(tris, p.rays);
  std::vector<char> flip(prims.size(), 0);
  const long n = long(prims.size());
#pragma omp parallel for schedule(dynamic, 4) num_threads(std::max(1, threads))
  for (long i = 0; i < n; ++i) {
    const Primitive& pr = prims[size_t(i)];
    if (pr.inferred || pr.inliers.empty()) continue;
    const size_t m = pr.inliers.size();
    const size_t k = std::min<size_t>(size_t(std::max(1, p.points_per_plane)), m);
    int front_in = 0, front_cast = 0, back_in = 0, back_cast = 0;
    for (size_t j = 0; j < k; ++j) {
      Vec3 q = s.points[size_t(pr.inliers[(j * m) / k])];
      q -= (pr.normal.dot(q) + pr.d) * pr.normal;  // onto the plane
      const auto f = labeller.half_space_votes(q + p.offset * pr.normal, pr.normal);
      const auto b = labeller.half_space_votes(q - p.offset * pr.normal, -pr.normal);
      front_in += f.first;
      front_cast += f.second;
      back_in += b.first;
      back_cast += b.second;
      // Half the probes without a hint of a wrong orientation (the front seen
      // no more inside than the back): the rest cannot make the margin.
      if (2 * (j + 1) >= k && front_cast > 0 && back_cast > 0 &&
          double(front_in) / front_cast <= double(back_in) / back_cast)
        break;
    }
    if (front_cast == 0 || back_cast == 0) continue;
    const double front = double(front_in) / front_cast, back = double(back_in) / back_cast;
    if (front > 0.5 && back < 0.5 && front > back + p.margin) flip[size_t(i)] = 1;
  }
  int flipped = 0;
  for (size_t i = 0; i < prims.size(); ++i)
    if (flip[i]) {
      turn_round(prims[i]);
      ++flipped;
    }
  return flipped;
}

}  // namespace citylod::lod::detail
