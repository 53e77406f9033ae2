// Ground model, point features and building clustering of one cell (+ halo).
#include "citylod/tiler/segment.hpp"

// PCL's kd-tree (the radius search that attaches edge points to clusters) is
// instantiated here from its headers instead of linked from libpcl_kdtree: linking PCL's
// libraries (libpcl_segmentation pulled in pcl_features, pcl_filters, pcl_ml ...) cost
// every citylod process ~0.1 s of symbol binding at start-up (BENCHMARKS.md, "Process
// start-up and I/O"). Only libpcl_common and FLANN are linked. The points' k nearest
// neighbours (PCA features) ask FLANN's index, the one PCL's kd-tree wraps, directly;
// the clustering: euclidean_clusters().
#define PCL_NO_PRECOMPILE
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>

namespace citylod::tiler {

const char* class_mode_name(ClassMode m) {
  switch (m) {
    case ClassMode::none:
      return "no classes (DTM by grid-minimum opening, vegetation by PCA features)";
    case ClassMode::ground:
      return "ground class 2 (vegetation by PCA features)";
    case ClassMode::buildings:
      return "ground class 2 and building class 6";
  }
  return "";
}

bool non_building_class(std::uint8_t c) {
  switch (c) {
    case 2:   // ground
    case 3:   // low vegetation
    case 4:   // medium vegetation
    case 5:   // high vegetation
    case 7:   // low point (noise)
    case 9:   // water
    case 10:  // rail
    case 11:  // road surface
    case 18:  // high noise
      return true;
    default:
      return false;
  }
}

std::vector<std::vector<std::uint32_t>> euclidean_clusters(
    const std::vector<std::array<float, 3>>& pts, double tolerance, std::size_t min_size) {
  const std::size_t n = pts.size();
  // as PCL passes it: the tolerance as float, squared in double, then float
  const double tol = double(static_cast<float>(tolerance));
  const float r2 = static_cast<float>(tol * tol);
  // Cells a hair larger than the tolerance: a neighbour lies in the 3 x 3 cells around.
  const double cell = tol * (1 + 1e-4);
  using Key = std::pair<std::int64_t, std::int64_t>;
  auto key_of = [&](std::size_t i) {
    return Key(std::int64_t(std::floor(double(pts[i][0]) / cell)),
               std::int64_t(std::floor(double(pts[i][1]) / cell)));
  };
  std::vector<std::pair<Key, std::uint32_t>> by_cell(n);
  for (std::size_t i = 0; i < n; ++i) by_cell[i] = {key_of(i), std::uint32_t(i)};
  std::sort(by_cell.begin(), by_cell.end());
  auto near = [&](std::size_t a, std::size_t b) {  // FLANN's L2_Simple<float>, its radius test
    float d = 0, e;
    for (std::size_t k = 0; k < 3; ++k) {
      e = pts[a][k] - pts[b][k];
      d += e * e;
    }
    return d < r2;
  };
  std::vector<std::vector<std::uint32_t>> clusters;
  std::vector<char> processed(n, 0);
  std::vector<std::uint32_t> queue;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (processed[seed]) continue;
    queue.assign(1, std::uint32_t(seed));
    processed[seed] = 1;
    for (std::size_t at = 0; at < queue.size(); ++at) {
      const std::uint32_t i = queue[at];
      const Key k = key_of(i);
      for (std::int64_t dx = -1; dx <= 1; ++dx)
        for (std::int64_t dy = -1; dy <= 1; ++dy) {
          const Key c(k.first + dx, k.second + dy);
          for (auto it = std::lower_bound(by_cell.begin(), by_cell.end(),
                                          std::make_pair(c, std::uint32_t(0)));
               it != by_cell.end() && it->first == c; ++it)
            if (!processed[it->second] && near(i, it->second)) {
              processed[it->second] = 1;
              queue.push_back(it->second);
            }
        }
    }
    if (queue.size() < min_size) continue;
    clusters.push_back(queue);
    std::sort(clusters.back().begin(), clusters.back().end());
  }
  // PCL's order: std::sort of the reversed list by size (pcl::comparePointClusters)
  std::sort(clusters.rbegin(), clusters.rend(),
            [](const auto& a, const auto& b) { return a.size() < b.size(); });
  return clusters;
}

double GroundGrid::at(double x, double y) const {
  if (nx == 0 || ny == 0) return 0.0;
  int i = static_cast<int>(std::floor((x - x0) / res));
  int j = static_cast<int>(std::floor((y - y0) / res));
  i = std::clamp(i, 0, nx - 1);
  j = std::clamp(j, 0, ny - 1);
  return z[static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) +
           static_cast<std::size_t>(i)];
}

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Smallest extent of a convex polygon over all directions (an edge direction is optimal).
double hull_width(const Ring& h) {
  if (h.size() < 3) return 0.0;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < h.size(); ++i) {
    const Vec2& a = h[i];
    const Vec2& b = h[(i + 1) % h.size()];
    const double len = std::hypot(b[0] - a[0], b[1] - a[1]);
    if (len <= 0) continue;
    double far = 0;
    for (const Vec2& v : h)
      far = std::max(far,
                     std::abs((b[0] - a[0]) * (v[1] - a[1]) - (b[1] - a[1]) * (v[0] - a[0])) / len);
    best = std::min(best, far);
  }
  return std::isfinite(best) ? best : 0.0;
}

// Min (or max) over a (2r+1)-window along rows then columns; +inf cells are empty and ignored.
// (Not inlined: GCC 12 inlining it into build_dtm reports a false -Wfree-nonheap-object.)
[[gnu::noinline]] void window_filter(std::vector<float>& z, int nx, int ny, int r, bool take_min) {
  std::vector<float> tmp(z.size(), kInf);
  auto better = [take_min](float a, float b) { return take_min ? std::min(a, b) : std::max(a, b); };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      float best = kInf;
      bool any = false;
      for (int k = std::max(0, i - r); k <= std::min(nx - 1, i + r); ++k) {
        const float v = z[std::size_t(j) * std::size_t(nx) + std::size_t(k)];
        if (v == kInf) continue;
        best = any ? better(best, v) : v;
        any = true;
      }
      tmp[std::size_t(j) * std::size_t(nx) + std::size_t(i)] = any ? best : kInf;
    }
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      float best = kInf;
      bool any = false;
      for (int k = std::max(0, j - r); k <= std::min(ny - 1, j + r); ++k) {
        const float v = tmp[std::size_t(k) * std::size_t(nx) + std::size_t(i)];
        if (v == kInf) continue;
        best = any ? better(best, v) : v;
        any = true;
      }
      z[std::size_t(j) * std::size_t(nx) + std::size_t(i)] = any ? best : kInf;
    }
}

// Empty cells take the mean of their filled 8-neighbours, repeatedly (nearest-fill).
void fill_holes(std::vector<float>& z, int nx, int ny) {
  bool any_filled = false;
  for (float v : z)
    if (v != kInf) any_filled = true;
  if (!any_filled) {
    std::fill(z.begin(), z.end(), 0.0f);
    return;
  }
  // Rounds of dilation: an empty cell with filled neighbours takes their mean (of the
  // previous round's values). Only the front is visited: the empty cells next to the
  // cells filled in the round before (a whole-grid scan per round cost 14 % of a split).
  const auto idx = [nx](int i, int j) { return std::size_t(j) * std::size_t(nx) + std::size_t(i); };
  std::vector<char> queued(z.size(), 0);
  std::vector<std::size_t> front;
  const auto queue_empty_neighbours = [&](int i, int j) {
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di) {
        const int a = i + di, b = j + dj;
        if (a < 0 || b < 0 || a >= nx || b >= ny) continue;
        const std::size_t c = idx(a, b);
        if (z[c] != kInf || queued[c]) continue;
        queued[c] = 1;
        front.push_back(c);
      }
  };
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      if (z[idx(i, j)] != kInf) queue_empty_neighbours(i, j);
  std::vector<float> val;
  while (!front.empty()) {
    val.assign(front.size(), 0.0f);
    for (std::size_t k = 0; k < front.size(); ++k) {
      const int i = int(front[k] % std::size_t(nx)), j = int(front[k] / std::size_t(nx));
      double s = 0;
      int n = 0;
      for (int dj = -1; dj <= 1; ++dj)
        for (int di = -1; di <= 1; ++di) {
          const int a = i + di, b = j + dj;
          if (a < 0 || b < 0 || a >= nx || b >= ny) continue;
          const float v = z[idx(a, b)];
          if (v == kInf) continue;
          s += v;
          ++n;
        }
      val[k] = static_cast<float>(s / n);  // n >= 1: queued next to a filled cell
    }
    for (std::size_t k = 0; k < front.size(); ++k) z[front[k]] = val[k];
    std::vector<std::size_t> done;
    done.swap(front);
    for (const std::size_t c : done)
      queue_empty_neighbours(int(c % std::size_t(nx)), int(c / std::size_t(nx)));
  }
}

GroundGrid build_dtm(const std::vector<io::Vec3d>& pos, const std::vector<std::uint8_t>& cls,
                     ClassMode mode, const SegmentParams& p, const std::array<double, 4>& region) {
  GroundGrid g;
  g.res = p.dtm_resolution;
  g.x0 = std::floor(region[0] / g.res) * g.res;
  g.y0 = std::floor(region[1] / g.res) * g.res;
  g.nx = std::max(1, static_cast<int>(std::ceil((region[2] - g.x0) / g.res)) + 1);
  g.ny = std::max(1, static_cast<int>(std::ceil((region[3] - g.y0) / g.res)) + 1);
  g.z.assign(std::size_t(g.nx) * std::size_t(g.ny), kInf);

  auto cell_of = [&](const io::Vec3d& q) -> long {
    const int i = static_cast<int>(std::floor((q[0] - g.x0) / g.res));
    const int j = static_cast<int>(std::floor((q[1] - g.y0) / g.res));
    if (i < 0 || j < 0 || i >= g.nx || j >= g.ny) return -1;
    return long(j) * g.nx + i;
  };
  bool use_class2 = mode != ClassMode::none && !cls.empty();
  if (use_class2) {
    std::size_t n2 = 0;
    for (std::size_t k = 0; k < pos.size(); ++k)
      if (cls[k] == 2) ++n2;
    use_class2 = n2 > 0;
  }
  for (std::size_t k = 0; k < pos.size(); ++k) {
    if (use_class2 && cls[k] != 2) continue;
    if (!use_class2 && !cls.empty() && (cls[k] == 7 || cls[k] == 18)) continue;  // noise
    const long c = cell_of(pos[k]);
    if (c < 0) continue;
    g.z[std::size_t(c)] = std::min(g.z[std::size_t(c)], static_cast<float>(pos[k][2]));
  }
  if (!use_class2) {
    // Grid-minimum opening: erosion removes everything narrower than the window
    // (buildings, trees), dilation restores the terrain's level.
    const int r = std::max(1, static_cast<int>(std::ceil(0.5 * p.dtm_window / g.res)));
    window_filter(g.z, g.nx, g.ny, r, true);
    window_filter(g.z, g.nx, g.ny, r, false);
  }
  fill_holes(g.z, g.nx, g.ny);
  return g;
}

/// The region centre, the origin of the float coordinates given to FLANN and PCL.
struct Centre {
  double x, y, z;
};

/// PCA features of the points above the ground that may be building: planarity, and
/// foliage (scatter above p.max_scatter) in out.foliage.
void point_features(const std::vector<io::Vec3d>& pos, const std::vector<std::uint8_t>& cls,
                    bool have_cls, const SegmentParams& p, const Centre& c, CellSegmentation& out,
                    std::vector<float>& planarity) {
  const std::size_t n = pos.size();
  std::vector<std::uint32_t> idx;
  for (std::size_t k = 0; k < n; ++k)
    if (!out.ground[k] && out.hag[k] > p.ground_tolerance &&
        !(have_cls && non_building_class(cls[k])))
      idx.push_back(static_cast<std::uint32_t>(k));
  const int kk = std::min<int>(p.feature_neighbours, static_cast<int>(idx.size()));
  if (kk < 5) return;
  // PCL's KdTreeFLANN::nearestKSearch, called on FLANN's index directly: the same
  // index (KDTreeSingleIndex, 15 points per leaf), search parameters (exact, sorted)
  // and result set as PCL's wrapper, without the OpenMP parallel region FLANN's
  // knnSearch opens for every query point (mesh_city's split without footprints
  // 2.9 -> 2.0 s; BENCHMARKS.md, "Splitting").
  std::vector<float> xyz(3 * idx.size());
  for (std::size_t m = 0; m < idx.size(); ++m) {
    const auto& q = pos[idx[m]];
    xyz[3 * m] = float(q[0] - c.x);
    xyz[3 * m + 1] = float(q[1] - c.y);
    xyz[3 * m + 2] = float(q[2] - c.z);
  }
  ::flann::KDTreeSingleIndex<::flann::L2_Simple<float>> tree(
      ::flann::Matrix<float>(xyz.data(), idx.size(), 3), ::flann::KDTreeSingleIndexParams(15));
  tree.buildIndex();
  const ::flann::SearchParams sp(-1, 0.0f);  // PCL's: every leaf checked, exact, sorted
  const std::size_t k = std::size_t(kk);
  std::vector<std::size_t> nn(k);
  std::vector<float> d2(k);
  // the k nearest of point m into nn, sorted, by the result set NNIndex::knnSearch picks
  ::flann::KNNSimpleResultSet<float> simple(k);
  ::flann::KNNResultSet2<float> heap(k);
  auto neighbours = [&](auto& rs, std::size_t m) {
    rs.clear();
    tree.findNeighbors(rs, &xyz[3 * m], sp);
    rs.copy(nn.data(), d2.data(), std::min(rs.size(), k), sp.sorted);
  };
  auto point = [&](std::size_t i) {
    return Eigen::Vector3d(double(xyz[3 * i]), double(xyz[3 * i + 1]), double(xyz[3 * i + 2]));
  };
  for (std::size_t m = 0; m < idx.size(); ++m) {
    if (k > KNN_HEAP_THRESHOLD)
      neighbours(heap, m);
    else
      neighbours(simple, m);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const std::size_t i : nn) mean += point(i);
    mean /= double(k);
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const std::size_t i : nn) {
      const Eigen::Vector3d d = point(i) - mean;
      cov += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov, Eigen::EigenvaluesOnly);
    const Eigen::Vector3d ev = es.eigenvalues().cwiseMax(0.0);  // ascending
    const double l1 = std::max(ev[2], 1e-12);
    const double scatter = ev[0] / l1;
    planarity[idx[m]] = static_cast<float>((ev[1] - ev[0]) / l1);
    if (scatter > p.max_scatter) out.foliage[idx[m]] = 1;
  }
}

/// The points that may belong to a building: class 6 when the building class is
/// trusted, else above p.min_height, not foliage, not of a non-building class.
std::vector<std::uint32_t> building_candidates(const std::vector<std::uint8_t>& cls, ClassMode mode,
                                               bool have_cls, const SegmentParams& p,
                                               const CellSegmentation& out) {
  std::vector<std::uint32_t> cand;
  for (std::size_t k = 0; k < out.hag.size(); ++k) {
    if (mode == ClassMode::buildings) {
      if (cls[k] == 6) cand.push_back(static_cast<std::uint32_t>(k));
      continue;
    }
    if (out.ground[k] || out.foliage[k] || out.hag[k] < p.min_height) continue;
    if (have_cls && non_building_class(cls[k])) continue;
    cand.push_back(static_cast<std::uint32_t>(k));
  }
  return cand;
}

/// The candidates' groups (point indices) and each point's group (-1: none).
struct Groups {
  std::vector<std::vector<std::uint32_t>> members;
  std::vector<int> label;
};

/// The candidates clustered in 2D (euclidean_clusters). Edges and ridges look like
/// foliage to the PCA (their neighbourhood spans two planes), which cuts walls from
/// roofs and roof halves apart. Foliage-like points within reach of clustered points
/// join them, and bridge the clusters they touch.
Groups group_candidates(const std::vector<io::Vec3d>& pos, const std::vector<std::uint8_t>& cls,
                        ClassMode mode, bool have_cls, const SegmentParams& p, const Centre& ce,
                        const std::vector<std::uint32_t>& cand, const CellSegmentation& out) {
  const std::size_t n = pos.size();
  std::vector<std::array<float, 3>> flat(cand.size());
  for (std::size_t m = 0; m < cand.size(); ++m) {
    const auto& q = pos[cand[m]];
    flat[m] = {float(q[0] - ce.x), float(q[1] - ce.y), 0.0f};
  }
  const std::vector<std::vector<std::uint32_t>> found =
      euclidean_clusters(flat, p.cluster_tolerance, std::size_t(std::max(1, p.min_cluster_points)));

  std::vector<int> parent(found.size());
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = int(i);
  std::function<int(int)> root = [&](int i) {
    return parent[std::size_t(i)] == i ? i : parent[std::size_t(i)] = root(parent[std::size_t(i)]);
  };
  std::vector<int> label(n, -1);
  for (std::size_t c = 0; c < found.size(); ++c)
    for (const std::uint32_t m : found[c]) label[cand[m]] = int(c);
  std::vector<std::pair<std::uint32_t, int>> attached;  // foliage point -> cluster
  if (mode != ClassMode::buildings && !found.empty()) {
    pcl::PointCloud<pcl::PointXYZ>::Ptr c3(new pcl::PointCloud<pcl::PointXYZ>);
    c3->resize(cand.size());
    for (std::size_t m = 0; m < cand.size(); ++m) {
      const auto& q = pos[cand[m]];
      (*c3)[m] = pcl::PointXYZ(float(q[0] - ce.x), float(q[1] - ce.y), float(q[2] - ce.z));
    }
    pcl::KdTreeFLANN<pcl::PointXYZ> t3;
    t3.setInputCloud(c3);
    const double reach = 1.5 * p.cluster_tolerance;
    std::vector<int> nn;
    std::vector<float> d2;
    for (std::size_t k = 0; k < n; ++k) {
      if (!out.foliage[k] || out.hag[k] < p.min_height) continue;
      if (have_cls && non_building_class(cls[k])) continue;
      const pcl::PointXYZ q(float(pos[k][0] - ce.x), float(pos[k][1] - ce.y),
                            float(pos[k][2] - ce.z));
      if (t3.radiusSearch(q, reach, nn, d2) <= 0) continue;
      int first = -1;
      for (int m : nn) {
        const int l = label[cand[std::size_t(m)]];
        if (l < 0) continue;
        if (first < 0)
          first = l;
        else if (root(l) != root(first))
          parent[std::size_t(root(l))] = root(first);
      }
      if (first >= 0) attached.push_back({std::uint32_t(k), first});
    }
  }
  Groups g;
  g.members.resize(found.size());
  for (std::size_t c = 0; c < found.size(); ++c)
    for (const std::uint32_t m : found[c]) g.members[std::size_t(root(int(c)))].push_back(cand[m]);
  for (const auto& [k, c] : attached) {
    g.members[std::size_t(root(c))].push_back(k);
    label[k] = root(c);
  }
  for (std::size_t c = 0; c < found.size(); ++c)
    for (const std::uint32_t m : found[c]) label[cand[m]] = root(int(c));
  g.label = std::move(label);
  return g;
}

/// Foliage points above building height, bucketed for the vegetation ratio (none when
/// the building class is trusted).
struct FoliageBuckets {
  double size = 2.0;  ///< m
  int bx = 1, by = 1;
  std::vector<std::vector<std::uint32_t>> cells;  ///< row-major, bx x by
};

FoliageBuckets foliage_buckets(const std::vector<io::Vec3d>& pos, ClassMode mode,
                               const SegmentParams& p, const std::array<double, 4>& region,
                               const CellSegmentation& out) {
  FoliageBuckets b;
  const double bucket = b.size;
  const int bx = std::max(1, int(std::ceil((region[2] - region[0]) / bucket)) + 1);
  const int by = std::max(1, int(std::ceil((region[3] - region[1]) / bucket)) + 1);
  b.bx = bx;
  b.by = by;
  if (mode == ClassMode::buildings) return b;
  b.cells.resize(std::size_t(bx) * std::size_t(by));
  for (std::size_t k = 0; k < pos.size(); ++k)
    if (out.foliage[k] && out.hag[k] >= p.min_height) {
      const int i = std::clamp(int((pos[k][0] - region[0]) / bucket), 0, bx - 1);
      const int j = std::clamp(int((pos[k][1] - region[1]) / bucket), 0, by - 1);
      b.cells[std::size_t(j) * std::size_t(bx) + std::size_t(i)].push_back(std::uint32_t(k));
    }
  return b;
}

/// A group's cluster: members, anchor, centroid, hull, area, width, height, planar
/// fraction (not yet the vegetation ratio and the verdict).
Cluster describe_cluster(const std::vector<io::Vec3d>& pos, const CellSegmentation& out,
                         const std::vector<float>& planarity,
                         const std::vector<std::uint32_t>& group) {
  Cluster c;
  c.members.reserve(group.size());
  std::vector<Vec2> xy;
  xy.reserve(group.size());
  double sx = 0, sy = 0, sz = 0;
  std::size_t planar = 0;
  c.anchor = pos[group.front()];
  for (const std::uint32_t k : group) {
    c.members.push_back(k);
    if (pos[k] < c.anchor) c.anchor = pos[k];
    sx += pos[k][0];
    sy += pos[k][1];
    sz += pos[k][2];
    xy.push_back({pos[k][0], pos[k][1]});
    c.height = std::max(c.height, double(out.hag[k]));
    if (planarity[k] > 0.5f) ++planar;
  }
  std::sort(c.members.begin(), c.members.end());
  const double cnt = double(c.members.size());
  c.centroid = {sx / cnt, sy / cnt, sz / cnt};
  c.hull = convex_hull(std::move(xy));
  c.area = c.hull.size() >= 3 ? signed_area(c.hull) : 0.0;
  c.width = hull_width(c.hull);
  c.planar_fraction = double(planar) / cnt;
  return c;
}

/// The share of foliage points of other groups inside cluster `g`'s hull, per member.
double vegetation_ratio(const Cluster& c, int g, const std::vector<int>& label,
                        const FoliageBuckets& b, const std::vector<io::Vec3d>& pos,
                        const std::array<double, 4>& region) {
  const double bucket = b.size;
  const int bx = b.bx, by = b.by;
  double xmin = 1e300, ymin = 1e300, xmax = -1e300, ymax = -1e300;
  for (const auto& v : c.hull) {
    xmin = std::min(xmin, v[0]);
    ymin = std::min(ymin, v[1]);
    xmax = std::max(xmax, v[0]);
    ymax = std::max(ymax, v[1]);
  }
  const int i0 = std::clamp(int((xmin - region[0]) / bucket), 0, bx - 1);
  const int i1 = std::clamp(int((xmax - region[0]) / bucket), 0, bx - 1);
  const int j0 = std::clamp(int((ymin - region[1]) / bucket), 0, by - 1);
  const int j1 = std::clamp(int((ymax - region[1]) / bucket), 0, by - 1);
  std::size_t inside = 0;
  for (int j = j0; j <= j1; ++j)
    for (int i = i0; i <= i1; ++i)
      for (std::uint32_t k : b.cells[std::size_t(j) * std::size_t(bx) + std::size_t(i)])
        if (label[k] != g && point_in_ring(c.hull, {pos[k][0], pos[k][1]})) ++inside;
  return double(inside) / double(c.members.size());
}

/// A building, or why not (c.reject_reason).
void judge_cluster(Cluster& c, ClassMode mode, const SegmentParams& p) {
  char why[160] = "";
  if (c.area < p.min_area)
    std::snprintf(why, sizeof why, "small (%.1f m2 < %.1f m2)", c.area, p.min_area);
  else if (c.height < p.min_building_height)
    std::snprintf(why, sizeof why, "low (%.1f m < %.1f m above ground)", c.height,
                  p.min_building_height);
  else if (c.width < p.min_width)
    std::snprintf(why, sizeof why, "narrow (%.1f m < %.1f m wide)", c.width, p.min_width);
  else if (mode != ClassMode::buildings && c.height < p.low_height &&
           (c.vegetation_ratio > p.low_max_vegetation_ratio ||
            c.planar_fraction < p.low_min_planar_fraction))
    std::snprintf(why, sizeof why, "low object (%.1f m high, %.0f%% foliage, %.0f%% planar)",
                  c.height, 100 * c.vegetation_ratio, 100 * c.planar_fraction);
  else if (mode != ClassMode::buildings && c.vegetation_ratio > p.max_vegetation_ratio)
    std::snprintf(why, sizeof why, "vegetation (%.0f%% foliage-like points in its outline)",
                  100 * c.vegetation_ratio);
  else if (mode != ClassMode::buildings && c.planar_fraction < p.min_planar_fraction)
    std::snprintf(why, sizeof why, "vegetation (only %.0f%% planar points)",
                  100 * c.planar_fraction);
  c.reject_reason = why;
  c.building = c.reject_reason.empty();
}

}  // namespace

CellSegmentation segment_cell(const std::vector<io::Vec3d>& pos,
                              const std::vector<std::uint8_t>& cls, ClassMode mode,
                              const SegmentParams& p, const std::array<double, 4>& region,
                              bool cluster) {
  CellSegmentation out;
  const std::size_t n = pos.size();
  out.dtm = build_dtm(pos, cls, mode, p, region);
  out.hag.resize(n);
  out.ground.assign(n, 0);
  out.foliage.assign(n, 0);
  const bool have_cls = !cls.empty() && mode != ClassMode::none;
  for (std::size_t k = 0; k < n; ++k) {
    out.hag[k] = static_cast<float>(pos[k][2] - out.dtm.at(pos[k][0], pos[k][1]));
    out.ground[k] = have_cls ? (cls[k] == 2) : (out.hag[k] < p.ground_tolerance);
  }
  if (n == 0) return out;

  // Local frame for PCL (float): the region centre.
  Centre c;
  c.x = 0.5 * (region[0] + region[2]);
  c.y = 0.5 * (region[1] + region[3]);
  c.z = out.dtm.at(c.x, c.y);

  // ---- point features (not when the building class is trusted)
  std::vector<float> planarity(n, 1.0f);
  if (mode != ClassMode::buildings) point_features(pos, cls, have_cls, p, c, out, planarity);
  if (!cluster) return out;

  // ---- building candidates, clustered
  const std::vector<std::uint32_t> cand = building_candidates(cls, mode, have_cls, p, out);
  if (cand.size() < static_cast<std::size_t>(std::max(1, p.min_cluster_points))) return out;
  const Groups groups = group_candidates(pos, cls, mode, have_cls, p, c, cand, out);

  // ---- each group judged
  const FoliageBuckets buckets = foliage_buckets(pos, mode, p, region, out);
  for (std::size_t g = 0; g < groups.members.size(); ++g) {
    if (groups.members[g].empty()) continue;
    Cluster cl = describe_cluster(pos, out, planarity, groups.members[g]);
    if (!buckets.cells.empty() && cl.hull.size() >= 3)
      cl.vegetation_ratio = vegetation_ratio(cl, int(g), groups.label, buckets, pos, region);
    judge_cluster(cl, mode, p);
    out.clusters.push_back(std::move(cl));
  }
  return out;
}

}  // namespace citylod::tiler
