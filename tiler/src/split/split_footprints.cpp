// The split's footprints: read before the points (a bad source fails fast), reprojected
// to the scene frame and placed (the cells owning them, a bucket index); which
// footprint a point belongs to (footprint_of, through answer rasters) and which one a
// mesh triangle belongs to (mesh_footprint_of); and the planar share that tells a
// mesh's buildings from its trees.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include <Eigen/Eigenvalues>

#include "citylod/io/error.hpp"
#include "citylod/tiler/option_names.hpp"
#include "split_internal.hpp"

namespace citylod::tiler::split_detail {

// ---------------------------------------------------------------------- footprints
// Read before the points (a bad source, layer or id fails fast); placed in load_footprints().
void Splitter::read_footprints() {
  FootprintSourceOptions fo;
  fo.layer = opt_.footprints_layer;
  fo.id_attribute = opt_.footprints_id;
  fp_set_ = read_footprint_source(opt_.footprints, fo);
}

void Splitter::load_footprints() {
  FootprintSet set = std::move(fp_set_);
  const std::string src = set.source;  // as given, a "PG:" password masked
  fp_source_ = src;
  rep_.footprints_total = set.footprints.size();
  rep_.footprints_repaired = set.repaired;
  rep_.footprints_skipped = set.skipped;
  constexpr std::size_t kMaxProblemNotes = 20;  // the rest counted: notes stay readable
  for (std::size_t i = 0; i < set.problems.size() && i < kMaxProblemNotes; ++i)
    rep_.notes.push_back("footprints: " + set.problems[i]);
  if (set.problems.size() > kMaxProblemNotes)
    rep_.notes.push_back("footprints: " + std::to_string(set.problems.size() - kMaxProblemNotes) +
                         " more features skipped or repaired (" + std::to_string(set.repaired) +
                         " repaired, " + std::to_string(set.skipped) + " skipped in all)");
  if (set.footprints.empty())
    throw IoError(
        src,
        set.source_features == 0
            ? "no footprints (layer '" + set.layer + "' is empty)"
            : "none of its " + std::to_string(set.source_features) +
                  " features is a usable polygon (" +
                  (set.problems.empty()
                       ? std::string("none has a polygon geometry")
                       : set.problems.front() +
                             (set.problems.size() > 1
                                  ? "; and " + std::to_string(set.problems.size() - 1) + " more"
                                  : std::string())) +
                  ")");
  // The source's extent, in its own units (for messages and the lon/lat test).
  double ext[4] = {1e300, 1e300, -1e300, -1e300};
  for (const auto& f : set.footprints) {
    ext[0] = std::min(ext[0], f.bbox[0]);
    ext[1] = std::min(ext[1], f.bbox[1]);
    ext[2] = std::max(ext[2], f.bbox[2]);
    ext[3] = std::max(ext[3], f.bbox[3]);
  }
  // To ENU: through the scene georef when the source has no CRS or the scene's; else
  // via WGS84. GeoJSON without a "crs" member is WGS84 for OGR (RFC 7946); legacy
  // files hold projected coordinates anyway: out of lon/lat range -> the scene's CRS.
  std::unique_ptr<geo::Transformer> other;
  try {
    if (!set.crs.empty() && crs_) {
      geo::Crs fcrs = geo::Crs::parse(set.crs);
      const bool same = fcrs.epsg() && crs_->epsg() && *fcrs.epsg() == *crs_->epsg();
      const bool not_lonlat =
          !fcrs.is_projected() && (std::abs(ext[0]) > 360 || std::abs(ext[2]) > 360 ||
                                   std::abs(ext[1]) > 90 || std::abs(ext[3]) > 90);
      if (not_lonlat)
        rep_.notes.push_back("footprints: " + src + " says " + set.crs +
                             " but its coordinates are not longitudes/latitudes; taken in " +
                             crs_->label());
      else if (!same)
        other = std::make_unique<geo::Transformer>(fcrs);
    } else if (set.crs.empty() && crs_) {
      rep_.notes.push_back("footprints: " + src + " has no CRS; taken in " + crs_->label());
    }
    const double z0 = georef_->origin_crs()[2];
    for (auto& f : set.footprints) {
      for (auto& poly : f.polygons)
        for (auto& ring : poly.rings)
          for (auto& v : ring) {
            Eigen::Vector3d e;
            if (other) {
              geo::LonLatH g = other->to_wgs84(Eigen::Vector3d(v[0], v[1], 0));
              g[2] = georef_->frame().origin()[2];
              e = georef_->from_geodetic(g);
            } else {
              e = georef_->to_local(Eigen::Vector3d(v[0], v[1], z0));
            }
            if (!std::isfinite(e[0]) || !std::isfinite(e[1]))
              throw IoError(src, "footprint '" + f.id + "' cannot be transformed to the scene CRS");
            // on a micrometre grid: the same footprint gives the same outline wherever
            // it lies (its source's coordinates, shifted, differ in their last bits)
            v = {std::round(e[0] * 1e6) / 1e6, std::round(e[1] * 1e6) / 1e6};
          }
      for (auto& poly : f.polygons) normalise(poly);
      f.update_bbox();
    }
  } catch (const geo::GeoError& e) {
    throw IoError(src, e.what());
  }
  const double buf = opt_.footprint_buffer;
  std::set<std::string> seen;
  for (auto& f : set.footprints) {
    if (f.bbox[2] + buf < bbox_enu_.min[0] || f.bbox[0] - buf > bbox_enu_.max[0] ||
        f.bbox[3] + buf < bbox_enu_.min[1] || f.bbox[1] - buf > bbox_enu_.max[1])
      continue;
    if (!seen.insert(f.id).second)
      throw IoError(src, "duplicate footprint id '" + f.id + "'" +
                             (opt_.footprints_id.empty()
                                  ? " (choose another with " + option_name("footprints_id") + ")"
                                  : std::string()));
    const bool inside = f.bbox[0] >= bbox_enu_.min[0] && f.bbox[2] <= bbox_enu_.max[0] &&
                        f.bbox[1] >= bbox_enu_.min[1] && f.bbox[3] <= bbox_enu_.max[1];
    fp_inside_.push_back(inside);
    fps_.push_back(std::move(f));
  }
  if (fps_.empty()) {
    char b[512];
    std::snprintf(b, sizeof b,
                  "none of its %zu footprints meets the data (footprints span %.3f %.3f .. %.3f "
                  "%.3f in %s; the points %.3f %.3f .. %.3f %.3f in %s): wrong CRS or wrong area?",
                  set.footprints.size(), ext[0], ext[1], ext[2], ext[3],
                  set.crs.empty() ? "no CRS" : set.crs.substr(0, 40).c_str(), bbox_crs_.min[0],
                  bbox_crs_.min[1], bbox_crs_.max[0], bbox_crs_.max[1],
                  crs_ ? crs_->label().c_str() : "the local frame");
    throw IoError(src, b);
  }
  rep_.footprints_in_scene = fps_.size();
  for (char c : fp_inside_) rep_.footprints_inside += c ? 1 : 0;
  // Bucket ranges stay within the data box: a huge footprint costs no more than the scene.
  const auto bucket = [&](double v) { return int(std::floor(v / fp_bucket_)); };
  const int bx_lo = bucket(bbox_enu_.min[0] - buf), bx_hi = bucket(bbox_enu_.max[0] + buf);
  const int by_lo = bucket(bbox_enu_.min[1] - buf), by_hi = bucket(bbox_enu_.max[1] + buf);
  for (std::size_t i = 0; i < fps_.size(); ++i) {
    const Vec2 c = fps_[i].centroid();
    fp_owned_[{int(std::floor(c[0] / cell_)), int(std::floor(c[1] / cell_))}].push_back(i);
    const auto& b = fps_[i].bbox;
    for (int bx = std::max(bx_lo, bucket(b[0] - buf)); bx <= std::min(bx_hi, bucket(b[2] + buf));
         ++bx)
      for (int by = std::max(by_lo, bucket(b[1] - buf)); by <= std::min(by_hi, bucket(b[3] + buf));
           ++by)
        fp_index_[{bx, by}].push_back(i);
  }
}

constexpr double kFpRasterCell = 1.0;           ///< m, cell of footprint_of's answer raster
constexpr std::int32_t kFpExact = -1;           ///< raster: the cell needs the exact test
constexpr std::int32_t kFpNone = -2;            ///< raster: no footprint for any point of it
constexpr std::size_t kFpRasterBuckets = 1024;  ///< rasters kept (10 KB each at 50 m / 1 m)

// A cell's answer is the exact test's for every point of it, or kFpExact. In the exact
// test's order (increasing index): a footprint whose box + buffer misses the cell is
// skipped for all its points; one whose boundary lies farther than the cell's
// half-diagonal from the cell's centre holds all of the cell (the answer, as the test
// stops at the first footprint holding the point) or none of it, and then is within the
// buffer of none of it when that distance exceeds the buffer too.
const std::vector<std::int32_t>& Splitter::fp_raster(const CellKey& bucket,
                                                     const std::vector<std::size_t>& candidates,
                                                     FpCache& fp) const {
  auto it = fp.raster.find(bucket);
  if (it != fp.raster.end()) return it->second;
  if (fp.raster.size() >= kFpRasterBuckets) fp.raster.clear();
  fp.queries.erase(bucket);
  const int n = int(std::ceil(fp_bucket_ / kFpRasterCell));
  const double buf = opt_.footprint_buffer;
  const double half = 0.5 * kFpRasterCell, reach = half * std::sqrt(2.0) + 1e-6;
  std::vector<std::int32_t> r(std::size_t(n) * std::size_t(n), kFpNone);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const Vec2 m{bucket.first * fp_bucket_ + (i + 0.5) * kFpRasterCell,
                   bucket.second * fp_bucket_ + (j + 0.5) * kFpRasterCell};
      std::int32_t answer = kFpNone;
      for (const std::size_t f : candidates) {
        const auto& b = fps_[f].bbox;
        if (m[0] + half < b[0] - buf || m[0] - half > b[2] + buf || m[1] + half < b[1] - buf ||
            m[1] - half > b[3] + buf)
          continue;
        double edge = std::numeric_limits<double>::infinity();
        for (const auto& poly : fps_[f].polygons)
          for (const auto& ring : poly.rings) edge = std::min(edge, distance_to_ring(ring, m));
        if (edge <= reach) {
          answer = kFpExact;
          break;
        }
        if (point_in_footprint(fps_[f], m)) {
          answer = std::int32_t(f);
          break;
        }
        if (edge - reach <= buf) {
          answer = kFpExact;
          break;
        }
      }
      r[std::size_t(j) * std::size_t(n) + std::size_t(i)] = answer;
    }
  return fp.raster.emplace(bucket, std::move(r)).first->second;
}

/// The footprint a point belongs to: the one containing it, else the nearest within
/// the buffer (ties to the first); SIZE_MAX when none. The bucket's raster answers
/// for most points; the points of cells it cannot answer for are tested.
std::size_t Splitter::footprint_of(const Vec2& q, FpCache& fp) const {
  const CellKey bk{int(std::floor(q[0] / fp_bucket_)), int(std::floor(q[1] / fp_bucket_))};
  if (bk != fp.last) {
    fp.last = bk;
    const auto it = fp_index_.find(bk);
    fp.candidates = it == fp_index_.end() ? nullptr : &it->second;
    const auto r = fp.raster.find(bk);
    fp.last_raster = r == fp.raster.end() ? nullptr : &r->second;
  }
  if (!fp.candidates) return SIZE_MAX;
  const std::vector<std::size_t>& candidates = *fp.candidates;
  // A raster costs about as much as testing one point per cell: built for a bucket once
  // it has been asked that often (sparse data, huge rings: the points are tested).
  const int n = int(std::ceil(fp_bucket_ / kFpRasterCell));
  if (!fp.last_raster && fps_.size() < std::size_t(INT32_MAX) &&
      ++fp.queries[bk] >= std::uint32_t(n * n))
    fp.last_raster = &fp_raster(bk, candidates, fp);
  if (fp.last_raster) {
    const std::vector<std::int32_t>& r = *fp.last_raster;
    const int i =
        std::clamp(int(std::floor((q[0] - bk.first * fp_bucket_) / kFpRasterCell)), 0, n - 1);
    const int j =
        std::clamp(int(std::floor((q[1] - bk.second * fp_bucket_) / kFpRasterCell)), 0, n - 1);
    const std::int32_t a = r[std::size_t(j) * std::size_t(n) + std::size_t(i)];
    if (a == kFpNone) return SIZE_MAX;
    if (a >= 0) return std::size_t(a);
  }
  const double buf = opt_.footprint_buffer;
  std::size_t best = SIZE_MAX;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i : candidates) {  // increasing index: ties go to the first footprint
    const auto& b = fps_[i].bbox;
    if (q[0] < b[0] - buf || q[0] > b[2] + buf || q[1] < b[1] - buf || q[1] > b[3] + buf) continue;
    const double d = distance_to_footprint(fps_[i], q);
    if (d < best_d) {
      best = i;
      best_d = d;
      if (d == 0) break;
    }
  }
  return best_d > buf ? SIZE_MAX : best;
}

// Mesh triangles are judged whole, by their geometry (no foliage test: the faces a
// footprint claims are all kept). A face no steeper than 60 degrees (roof, terrain)
// goes to the footprint holding the largest share of its xy projection when that share
// is at least kMeshMinShare; otherwise (eaves, overhangs) to the footprint nearest to its
// centroid within --footprint-buffer. A steeper face (wall) goes to the footprint that
// holds the point --footprint-buffer behind it (against its outward normal), preferring
// one that does not also hold the point as far in front of it: on a footprint edge
// shared by touching buildings the wall belongs to the building it bounds, not to the
// one it faces; else to the nearest footprint within the buffer. Faces whose samples
// all lie on the ground (DTM) are never claimed, except walls found by the rule above.
constexpr double kMeshMinShare = 0.5;      ///< share of a face's xy area inside a footprint
constexpr double kMeshWallCos = 0.5;       ///< |n_z| below this (steeper than 60 deg): a wall
constexpr double kMeshMinWallProbe = 0.2;  ///< m, the probe distance when the buffer is 0

std::size_t Splitter::mesh_footprint_of(const FaceRec& f, bool above_ground) const {
  const Vec3d p0{f.v[0][0], f.v[0][1], f.v[0][2]};
  const Vec3d p1{f.v[1][0], f.v[1][1], f.v[1][2]};
  const Vec3d p2{f.v[2][0], f.v[2][1], f.v[2][2]};
  const Eigen::Vector3d e1(p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]);
  const Eigen::Vector3d e2(p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]);
  const Eigen::Vector3d n = e1.cross(e2) * mesh_up_[std::size_t(f.id >> 40)];
  const double len = n.norm();
  const Vec2 c{(p0[0] + p1[0] + p2[0]) / 3, (p0[1] + p1[1] + p2[1]) / 3};
  const double buf = opt_.footprint_buffer;
  // Candidates: footprints whose buffered bbox meets the triangle's xy bbox, in index order.
  std::vector<std::size_t> cand;
  const double bx0 = std::min({p0[0], p1[0], p2[0]}), bx1 = std::max({p0[0], p1[0], p2[0]});
  const double by0 = std::min({p0[1], p1[1], p2[1]}), by1 = std::max({p0[1], p1[1], p2[1]});
  for (int bx = int(std::floor(bx0 / fp_bucket_)); bx <= int(std::floor(bx1 / fp_bucket_)); ++bx)
    for (int by = int(std::floor(by0 / fp_bucket_)); by <= int(std::floor(by1 / fp_bucket_));
         ++by) {
      const auto it = fp_index_.find({bx, by});
      if (it == fp_index_.end()) continue;
      for (std::size_t i : it->second) {
        const auto& b = fps_[i].bbox;
        if (bx1 < b[0] - buf || bx0 > b[2] + buf || by1 < b[1] - buf || by0 > b[3] + buf) continue;
        cand.push_back(i);
      }
    }
  if (cand.empty()) return SIZE_MAX;
  std::sort(cand.begin(), cand.end());
  cand.erase(std::unique(cand.begin(), cand.end()), cand.end());
  const auto nearest = [&](const Vec2& q) {
    std::size_t best = SIZE_MAX;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t i : cand) {
      const double d = distance_to_footprint(fps_[i], q);
      if (d < best_d) best = i, best_d = d;
    }
    return best_d > buf ? SIZE_MAX : best;
  };
  if (!(len > 0)) return above_ground ? nearest(c) : SIZE_MAX;
  if (std::abs(n[2]) >= kMeshWallCos * len) {  // roof, terrain: by area
    Ring xy{{p0[0], p0[1]}, {p1[0], p1[1]}, {p2[0], p2[1]}};
    if (signed_area(xy) < 0) std::swap(xy[1], xy[2]);
    const double a = std::abs(signed_area(xy));
    std::size_t best = SIZE_MAX;
    double best_a = 0;
    for (std::size_t i : cand) {
      const double ai = area_inside(fps_[i], xy);
      if (ai > best_a) best = i, best_a = ai;
    }
    if (!above_ground) return SIZE_MAX;
    if (best != SIZE_MAX && best_a >= kMeshMinShare * a) return best;
    return nearest(c);
  }
  // wall: the footprint it bounds
  const double h = std::hypot(n[0], n[1]);
  const double probe = std::max(buf, kMeshMinWallProbe);
  const Vec2 back{c[0] - probe * n[0] / h, c[1] - probe * n[1] / h};
  const Vec2 front{c[0] + probe * n[0] / h, c[1] + probe * n[1] / h};
  std::size_t inside = SIZE_MAX;
  for (std::size_t i : cand) {
    if (!point_in_footprint(fps_[i], back)) continue;
    if (!point_in_footprint(fps_[i], front)) return i;
    if (inside == SIZE_MAX) inside = i;
  }
  if (inside != SIZE_MAX) return inside;
  return above_ground ? nearest(c) : SIZE_MAX;
}

// The samples of every triangle whose footprint (mesh_footprint_of) is one of `mine`.
void Splitter::mesh_footprint_members(
    const RegionPoints& pts, const CellSegmentation& seg, const std::set<std::size_t>& mine,
    std::map<std::size_t, std::vector<std::uint32_t>>& members) const {
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> samples;
  std::unordered_map<std::uint64_t, bool> high;
  for (std::size_t k = 0; k < pts.pos.size(); ++k) {
    const std::uint64_t s = pts.src[k];
    samples[s].push_back(static_cast<std::uint32_t>(k));
    bool& h = high[s];
    h = h || (!seg.ground[k] && seg.hag[k] >= opt_.seg.ground_tolerance);
  }
  std::vector<std::uint64_t> tris;
  tris.reserve(samples.size());
  for (const auto& [s, v] : samples) tris.push_back(s);
  std::sort(tris.begin(), tris.end());  // sample order in each chunk: by triangle
  for (std::uint64_t s : tris) {
    const std::size_t f = mesh_footprint_of(pts.face(s), high[s]);
    if (f == SIZE_MAX || !mine.count(f)) continue;
    auto& dst = members[f];
    const auto& v = samples[s];
    dst.insert(dst.end(), v.begin(), v.end());
  }
}

// Trees on meshes: MVS meshes make crowns smooth closed blobs, which the point
// features (PCA scatter of small neighbourhoods) take for roofs. A building is made of
// planar faces of several m^2; a crown is curved at that scale. The triangles of a
// cluster are grown into planar regions over shared edges (a neighbour joins when its
// normal is within kMeshPlanarAngle of the region's plane and its vertices within
// kMeshPlanarTolerance of it; the plane is refitted as the region doubles); the share of
// the area in regions of >= kMeshPlanarRegionArea decides (< kMeshMinPlanarShare: a tree).
// Measured: mesh_city crowns 0.00-0.10, its building groups 0.87-0.93; noisier real meshes
// less: easy3d_building.off 0.34, the b9 urban block 0.47.
// Returns -1 (no decision) for triangle soups without shared edges.
constexpr double kMeshPlanarTolerance = 0.15;  ///< m (3 sigma of the 5 cm MVS noise)
constexpr double kMeshPlanarAngle = 30;        ///< degrees

double Splitter::mesh_planar_share(std::vector<std::uint64_t> tris, const RegionPoints& pts) const {
  std::sort(tris.begin(), tris.end());
  tris.erase(std::unique(tris.begin(), tris.end()), tris.end());
  const std::size_t n = tris.size();
  if (n == 0) return -1;
  std::vector<Eigen::Vector3d> nrm(n), cen(n);
  std::vector<std::array<Eigen::Vector3d, 3>> vtx(n);
  std::vector<double> area(n);
  // Edges by vertex position (welded at 1 mm): meshes written with a vertex per face corner
  // have neighbourhoods too.
  std::map<std::array<long long, 3>, std::uint64_t> vid;
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> edges;  // (v0 << 32 | v1), v0 < v1
  for (std::size_t i = 0; i < n; ++i) {
    const FaceRec& fr = pts.face(tris[i]);
    std::uint64_t id[3];
    for (int k = 0; k < 3; ++k) {
      const Vec3d p{fr.v[k][0], fr.v[k][1], fr.v[k][2]};
      vtx[i][std::size_t(k)] = Eigen::Vector3d(p[0], p[1], p[2]);
      const std::array<long long, 3> q{std::llround(p[0] * 1000), std::llround(p[1] * 1000),
                                       std::llround(p[2] * 1000)};
      id[k] = vid.emplace(q, vid.size()).first->second;
    }
    const Eigen::Vector3d c = (vtx[i][1] - vtx[i][0]).cross(vtx[i][2] - vtx[i][0]);
    area[i] = 0.5 * c.norm();
    nrm[i] = area[i] > 0 ? Eigen::Vector3d(c.normalized()) : Eigen::Vector3d(0, 0, 0);
    cen[i] = (vtx[i][0] + vtx[i][1] + vtx[i][2]) / 3;
    for (int k = 0; k < 3; ++k) {
      std::uint64_t a = id[k], b = id[(k + 1) % 3];
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      edges[(a << 32) | b].push_back(std::uint32_t(i));
    }
  }
  std::vector<std::vector<std::uint32_t>> adj(n);
  std::size_t shared = 0;
  for (const auto& [e, ts] : edges)
    for (std::size_t a = 0; a < ts.size(); ++a)
      for (std::size_t b = a + 1; b < ts.size(); ++b) {
        adj[ts[a]].push_back(ts[b]);
        adj[ts[b]].push_back(ts[a]);
        ++shared;
      }
  if (2 * shared < n) return -1;  // a triangle soup: no neighbourhoods to judge
  for (auto& a : adj) std::sort(a.begin(), a.end());
  const double cos_max = std::cos(kMeshPlanarAngle * M_PI / 180);
  std::vector<char> done(n, 0);
  double total = 0, planar = 0;
  for (std::size_t i = 0; i < n; ++i) total += area[i];
  std::vector<std::uint32_t> queue;
  for (std::size_t seed = 0; seed < n; ++seed) {
    if (done[seed] || area[seed] <= 0) continue;
    done[seed] = 1;
    queue.assign(1, std::uint32_t(seed));
    Eigen::Vector3d pn = nrm[seed], pc = cen[seed];
    double w = 0, fit_w = 0;
    Eigen::Vector3d s1(0, 0, 0);
    Eigen::Matrix3d s2 = Eigen::Matrix3d::Zero();
    const auto add = [&](std::size_t t) {
      for (const auto& v : vtx[t]) {
        s1 += area[t] * v;
        s2 += area[t] * v * v.transpose();
      }
      w += 3 * area[t];
    };
    add(seed);
    fit_w = w;
    double region = 0;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::size_t t = queue[q];
      region += area[t];
      for (std::uint32_t u : adj[t]) {
        if (done[u] || area[u] <= 0) continue;
        if (nrm[u].dot(pn) < cos_max) continue;
        bool near = true;
        for (const auto& v : vtx[u])
          near = near && std::abs((v - pc).dot(pn)) <= kMeshPlanarTolerance;
        if (!near) continue;
        done[u] = 1;
        queue.push_back(u);
        add(u);
        if (w >= 2 * fit_w && queue.size() >= 4) {  // refit the plane
          const Eigen::Vector3d mean = s1 / w;
          const Eigen::Matrix3d cov = s2 / w - mean * mean.transpose();
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
          Eigen::Vector3d nn = es.eigenvectors().col(0);
          if (nn.dot(pn) < 0) nn = -nn;
          pn = nn;
          pc = mean;
          fit_w = w;
        }
      }
    }
    if (region >= kMeshPlanarRegionArea) planar += region;
  }
  return total > 0 ? planar / total : -1;
}

}  // namespace citylod::tiler::split_detail
