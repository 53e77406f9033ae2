// Pass 2 of the split: every input streamed into the scene frame and spilled to the
// cells of the grid (spill.hpp); meshes as their triangles' samples (which the passes
// after segment like points) and the triangles themselves (the face files).
#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>

#include "citylod/geo/georef.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "split_internal.hpp"

namespace citylod::tiler::split_detail {

namespace {

constexpr double kMeshSamplesPerM2 = 4.0;  ///< triangle samples per m^2 (plus each centroid)

/// A mesh's triangle samples (centroid + ~kMeshSamplesPerM2 per m^2) waiting to be
/// spilled: the samples are segmented like points and vote for their triangle's
/// building. One random sequence per mesh file.
struct TriangleSamples {
  io::PointSet ps;
  std::vector<std::uint64_t> tri_of;  // sample -> triangle, per batch
  std::uint64_t rng = 0x9E3779B97F4A7C15ULL;
  double uni() {
    rng = rng * 6364136223846793005ULL + 1442695040888963407ULL;
    return double(rng >> 11) / double(1ull << 53);
  }
};

/// The samples of triangle `t` (corners `cv`) into `s`.
void sample_triangle(const std::array<VertexStore::Vertex, 3>& cv, std::uint64_t t, bool normals,
                     bool colors, TriangleSamples& s) {
  const Vec3d& p0 = cv[0].pos;
  const Vec3d& p1 = cv[1].pos;
  const Vec3d& p2 = cv[2].pos;
  const Eigen::Vector3d e1(p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]);
  const Eigen::Vector3d e2(p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]);
  const double area = 0.5 * e1.cross(e2).norm();
  const std::size_t n = 1 + static_cast<std::size_t>(std::min(1e6, area * kMeshSamplesPerM2));
  for (std::size_t k = 0; k < n; ++k) {
    double u = 1.0 / 3, v = 1.0 / 3;
    if (k > 0) {
      u = s.uni();
      v = s.uni();
      if (u + v > 1) u = 1 - u, v = 1 - v;
    }
    s.ps.positions.push_back({p0[0] + u * e1[0] + v * e2[0], p0[1] + u * e1[1] + v * e2[1],
                              p0[2] + u * e1[2] + v * e2[2]});
    if (normals) s.ps.normals.push_back(cv[0].normal);
    if (colors) s.ps.colors.push_back(cv[0].color);
    s.tri_of.push_back(t);
  }
}

}  // namespace

// ---------------------------------------------------------------------- pass 2
void Splitter::pass2_spill(Spiller& spill) {
  for (const auto& in : inputs_) {
    if (!in.info.has_normals) has_normals_ = false;
    if (!in.info.has_colors) has_colors_ = false;
    if (!in.info.has_classes) has_classes_ = false;
  }
  io::BBox3 seen_crs;
  const double n_in = static_cast<double>(inputs_.size());
  const std::string label = inputs_label(inputs_);
  for (std::size_t ii = 0; ii < inputs_.size(); ++ii) {
    const double a = 0.05 + 0.45 * double(ii) / n_in, b = 0.05 + 0.45 * double(ii + 1) / n_in;
    if (inputs_[ii].mesh)
      ingest_mesh(ii, a, b, spill, seen_crs);
    else
      ingest_points(inputs_[ii], a, b, spill, seen_crs);
  }
  spill.flush();
  spill.release();
  if (faces_) faces_->flush();
  if (bbox_enu_.empty()) throw IoError(label, "no points");
  check_area_of_use(seen_crs, label);
  choose_class_mode();
  rep_.bbox = bbox_enu_;
  rep_.spill_bytes = spill.bytes();
}

/// A point cloud streamed in batches; `a`..`b`: its share of the split's progress.
void Splitter::ingest_points(const InputInfo& in, double a, double b, Spiller& spill,
                             io::BBox3& seen_crs) {
  auto reader = io::PointReader::open(in.path);
  io::PointSet batch;
  std::uint64_t first = 0;
  while (true) {
    const std::size_t got = reader->read(batch, 1 << 16);
    if (got == 0) break;
    to_scene(in, batch.positions, seen_crs);
    spill_points(in, batch, first, spill);
    first += got;
    stages_.report(a, b, reader->progress(), "ingest");
  }
  if (first == 0) throw IoError(in.path, "no points (empty file)");
  rep_.points += first;
}

// A mesh file is streamed: its vertices are kept (ENU doubles, plus the file's own
// coordinates when it has polygons to triangulate, plus the attributes the split
// uses; in memory up to half of --memory-limit, else paged from a file through a
// cache of that size), its faces are read in batches, sampled and spilled to their
// cells.
void Splitter::ingest_mesh(std::size_t input, double a, double b, Spiller& spill,
                           io::BBox3& seen_crs) {
  const InputInfo& in = inputs_[input];
  const bool polygons = in.info.max_face_corners > 3;
  const std::uint64_t vertex_budget =
      opt_.mesh_vertex_budget > 0 ? opt_.mesh_vertex_budget : opt_.memory_limit / 2;
  auto reader = io::MeshReader::open(in.path);
  VertexStore mv({polygons, has_normals_, has_colors_}, in.info.point_count, vertex_budget,
                 staging_->scratch("vertices_" + std::to_string(input)).string());
  read_mesh_vertices(in, *reader, mv, seen_crs);
  if (mv.paged())
    rep_.notes.push_back(in.path + ": " + std::to_string(mv.size()) + " vertices (" +
                         fmt("%.0f", double(mv.size() * mv.record_bytes()) / 1048576) +
                         " MiB) paged from the work directory while the faces stream");
  double up = 0;
  const std::uint64_t t = ingest_mesh_faces(input, a, b, *reader, mv, spill, up);
  mesh_up_.resize(input + 1);
  mesh_up_[input] = up < 0 ? -1.0 : 1.0;
  if (up < 0 && !opt_.footprints.empty())
    rep_.notes.push_back(in.path +
                         ": faces point down (clockwise seen from above); taken as "
                         "reversed for the wall-to-footprint test");
  rep_.points += mv.size();
  rep_.triangles += t;
  stages_.report(a, b, 1.0, "ingest");
}

/// A mesh's vertices into `mv` (scene frame; the file's own coordinates too when it has
/// polygons to triangulate); a normal or colour missing from any batch: none kept.
void Splitter::read_mesh_vertices(const InputInfo& in, io::MeshReader& reader, VertexStore& mv,
                                  io::BBox3& seen_crs) {
  const bool polygons = in.info.max_face_corners > 3;
  io::PointSet vb;
  std::vector<Vec3d> file;
  bool all_normals = true, all_colors = true;
  while (reader.read_vertices(vb, 1 << 16) > 0) {
    all_normals = all_normals && vb.has_normals();
    all_colors = all_colors && vb.has_colors();
    if (polygons) file = vb.positions;  // triangulated in these, as read_mesh()
    to_scene(in, vb.positions, seen_crs);
    mv.append(vb.positions.data(), polygons ? file.data() : nullptr,
              all_normals && vb.has_normals() ? vb.normals.data() : nullptr,
              all_colors && vb.has_colors() ? vb.colors.data() : nullptr, vb.size());
  }
  mv.finish();
  if (!all_normals) has_normals_ = false;
  if (!all_colors) has_colors_ = false;
}

/// A mesh's faces in batches, triangulated: each triangle's samples to the point spill
/// and the triangle to the face files. Returns the triangles; `up`: the signed xy area
/// of the whole mesh. A city surface (terrain and roofs seen from above) has a positive
/// one when its faces point up/out: the wall rule of mesh_footprint_of() needs the
/// outward side of each face.
std::uint64_t Splitter::ingest_mesh_faces(std::size_t input, double a, double b,
                                          io::MeshReader& reader, const VertexStore& mv,
                                          Spiller& spill, double& up) {
  const InputInfo& in = inputs_[input];
  const bool polygons = in.info.max_face_corners > 3;
  TriangleSamples samples;
  std::uint64_t t = 0;  // triangle index in the file (after triangulation)
  io::FaceBatch fb;
  std::vector<std::array<std::uint32_t, 3>> tris;
  std::vector<Vec3d> corners;  // a polygon's corners (file coordinates)
  std::uint64_t faces_read = 0;
  while (reader.read_faces(fb, 1 << 16) > 0) {
    faces_read += fb.size();
    tris.clear();
    for (std::size_t f = 0; f < fb.size(); ++f) {
      const std::uint32_t* face = fb.face(f);
      const std::size_t n = fb.face_size(f);
      corners.clear();
      for (std::size_t k = 0; n > 3 && k < n; ++k) {  // triangles read as they are
        const VertexStore::Vertex c = mv.get(face[k]);
        corners.push_back(polygons ? c.file : c.pos);
      }
      io::triangulate_face(corners.data(), face, n, tris);
    }
    for (const auto& tri : tris) {
      const std::array<VertexStore::Vertex, 3> cv{mv.get(tri[0]), mv.get(tri[1]), mv.get(tri[2])};
      sample_triangle(cv, t, has_normals_, has_colors_, samples);
      if (samples.ps.size() >= (1u << 16)) {
        spill_samples(in, samples.ps, samples.tri_of, input, spill);
        samples.tri_of.clear();
      }
      const Vec3d& p0 = cv[0].pos;
      const Vec3d& p1 = cv[1].pos;
      const Vec3d& p2 = cv[2].pos;
      up += (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0]);
      spill_face(tri, cv, t, input);
      ++t;
    }
    stages_.report(a, b,
                   double(faces_read) / double(std::max<std::uint64_t>(1, in.info.face_count)),
                   "ingest");
  }
  if (!samples.ps.empty()) spill_samples(in, samples.ps, samples.tri_of, input, spill);
  return t;
}

/// Coordinates of an input (its offset added) into the scene frame; `seen_crs` grows
/// by them as read.
void Splitter::to_scene(const InputInfo& in, std::vector<Vec3d>& v, io::BBox3& seen_crs) {
  if (v.empty()) return;
  if (in.offset != Vec3d{0, 0, 0})
    for (auto& p : v) p = {p[0] + in.offset[0], p[1] + in.offset[1], p[2] + in.offset[2]};
  for (const auto& p : v) seen_crs.add(p);
  Eigen::Map<Eigen::Matrix3Xd> m(v[0].data(), 3, static_cast<Eigen::Index>(v.size()));
  try {
    georef_->to_local_inplace(m);
  } catch (const geo::GeoError& e) {
    throw IoError(in.path, e.what());
  }
}

/// Point k of a batch as a spill record (position, normal, colour); grows the ENU bbox.
SpillRec Splitter::spill_rec(const io::PointSet& batch, std::size_t k) {
  const Vec3d& p = batch.positions[k];
  bbox_enu_.add(p);
  SpillRec r{};
  r.x = p[0];
  r.y = p[1];
  r.z = p[2];
  if (has_normals_) {
    r.nx = batch.normals[k][0];
    r.ny = batch.normals[k][1];
    r.nz = batch.normals[k][2];
  }
  if (has_colors_) {
    r.r = batch.colors[k][0];
    r.g = batch.colors[k][1];
    r.b = batch.colors[k][2];
  }
  return r;
}

/// A batch of a point cloud (its first point: number `first_src` of the file).
void Splitter::spill_points(const InputInfo& in, const io::PointSet& batch, std::uint64_t first_src,
                            Spiller& spill) {
  for (std::size_t k = 0; k < batch.size(); ++k) {
    const Vec3d& p = batch.positions[k];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw IoError(in.path, "point #" + std::to_string(first_src + k) +
                                 " has no valid local coordinates (CRS transform failed)");
    SpillRec r = spill_rec(batch, k);
    if (has_classes_) {
      r.cls = batch.classes[k];
      ++class_hist_[r.cls];
    }
    r.src = kNoSrc;
    spill.add(r);
  }
}

/// Mesh samples: `refs[k]` is the triangle of sample k. Empties the batch.
void Splitter::spill_samples(const InputInfo& in, io::PointSet& batch,
                             const std::vector<std::uint64_t>& refs, std::size_t input,
                             Spiller& spill) {
  for (std::size_t k = 0; k < batch.size(); ++k) {
    const Vec3d& p = batch.positions[k];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2]))
      throw IoError(in.path,
                    "triangle #" + std::to_string(refs[k]) + " has no valid local coordinates");
    SpillRec r = spill_rec(batch, k);
    r.src = (std::uint64_t(input) << 40) | refs[k];
    spill.add(r);
  }
  batch.clear();
}

// A mesh triangle to the face files of every cell its xy box meets (a region then holds
// every triangle of its samples).
void Splitter::spill_face(const std::array<std::uint32_t, 3>& tri,
                          const std::array<VertexStore::Vertex, 3>& v, std::uint64_t t,
                          std::size_t input) {
  FaceRec f{};
  f.id = (std::uint64_t(input) << 40) | t;
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (std::size_t k = 0; k < 3; ++k) {
    const std::uint32_t vi = tri[k];
    f.vid[k] = (std::uint64_t(input) << 40) | vi;
    const Vec3d& p = v[k].pos;
    for (std::size_t a = 0; a < 3; ++a) f.v[k][a] = p[a];
    if (has_normals_)
      for (std::size_t a = 0; a < 3; ++a) f.n[k][a] = v[k].normal[a];
    if (has_colors_)
      for (std::size_t a = 0; a < 3; ++a) f.rgb[k][a] = v[k].color[a];
    x0 = std::min(x0, p[0]), x1 = std::max(x1, p[0]);
    y0 = std::min(y0, p[1]), y1 = std::max(y1, p[1]);
  }
  const CellKey lo = key_at(x0, y0, cell_), hi = key_at(x1, y1, cell_);
  for (int i = lo.first; i <= hi.first; ++i)
    for (int j = lo.second; j <= hi.second; ++j) faces_->add({i, j}, f);
}

/// A LAS header box that lies: check the area of use again with the real box.
void Splitter::check_area_of_use(const io::BBox3& seen_crs, const std::string& label) {
  if (!crs_) return;
  const double ex =
      std::max(bbox_crs_.max[0] - bbox_crs_.min[0], bbox_crs_.max[1] - bbox_crs_.min[1]);
  const double tol = 1e-6 * std::max(1.0, ex) + 0.01;
  bool outside = false;
  for (int a = 0; a < 3; ++a)
    if (seen_crs.min[a] < bbox_crs_.min[a] - tol || seen_crs.max[a] > bbox_crs_.max[a] + tol)
      outside = true;
  if (!outside) return;
  rep_.notes.push_back("points lie outside the header bounding box of " + label);
  try {
    geo::TransformOptions to;
    geo::Transformer t(*crs_, to);
    t.check_in_area(to_eigen(seen_crs));
  } catch (const geo::GeoError& e) {
    throw IoError(label, e.what());
  }
}

/// How classes can be used.
void Splitter::choose_class_mode() {
  if (opt_.ignore_classes || !has_classes_)
    mode_ = ClassMode::none;
  else if (class_hist_[2] > 0 && class_hist_[6] > 0)
    mode_ = ClassMode::buildings;
  else if (class_hist_[2] > 0)
    mode_ = ClassMode::ground;
  else
    mode_ = ClassMode::none;
  rep_.class_mode = class_mode_name(mode_);
}

}  // namespace citylod::tiler::split_detail
