// Format detection, reader factory and the whole-file helpers.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "readers_internal.hpp"

namespace citylod::io {

const char* format_name(Format f) {
  switch (f) {
    case Format::ply:
      return "PLY";
    case Format::obj:
      return "OBJ";
    case Format::off:
      return "OFF";
    case Format::xyz:
      return "XYZ";
    case Format::las:
      return "LAS";
    case Format::laz:
      return "LAZ";
    case Format::unknown:
      break;
  }
  return "unknown";
}

const char* las_class_name(int code) {
  switch (code) {
    case 0:
      return "never classified";
    case 1:
      return "unclassified";
    case 2:
      return "ground";
    case 3:
      return "low vegetation";
    case 4:
      return "medium vegetation";
    case 5:
      return "high vegetation";
    case 6:
      return "building";
    case 7:
      return "low point (noise)";
    case 8:
      return "model key-point";
    case 9:
      return "water";
    case 10:
      return "rail";
    case 11:
      return "road surface";
    case 12:
      return "overlap";
    case 13:
      return "wire guard";
    case 14:
      return "wire conductor";
    case 15:
      return "transmission tower";
    case 16:
      return "wire connector";
    case 17:
      return "bridge deck";
    case 18:
      return "high noise";
    case 26:
      return "civil structure (AHN)";
    default:
      return "";
  }
}

void PointSet::append(const PointSet& o) {
  const bool was_empty = positions.empty();
  auto merge = [&](auto& mine, const auto& theirs, std::size_t theirs_n) {
    if (was_empty) {
      mine = theirs;
    } else if (mine.size() == positions.size() && theirs.size() == theirs_n && !theirs.empty()) {
      mine.insert(mine.end(), theirs.begin(), theirs.end());
    } else {
      mine.clear();
    }
  };
  const std::size_t n = o.positions.size();
  merge(normals, o.normals, n);
  merge(colors, o.colors, n);
  merge(classes, o.classes, n);
  positions.insert(positions.end(), o.positions.begin(), o.positions.end());
}

bool PointSet::consistent() const {
  const std::size_t n = positions.size();
  return (normals.empty() || normals.size() == n) && (colors.empty() || colors.size() == n) &&
         (classes.empty() || classes.size() == n);
}

TriangleMesh triangulate_fan(const PolygonMesh& mesh) {
  TriangleMesh t;
  t.vertices = mesh.vertices;
  for (const auto& f : mesh.faces)
    for (std::size_t k = 1; k + 1 < f.size(); ++k) t.triangles.push_back({f[0], f[k], f[k + 1]});
  return t;
}

TriangleMesh triangulate_polygons(const PolygonMesh& mesh) {
  TriangleMesh t;
  t.vertices = mesh.vertices;
  std::vector<Vec3d> corners;
  for (const auto& f : mesh.faces) {
    corners.clear();
    if (f.size() > 3)
      for (std::uint32_t v : f) corners.push_back(mesh.vertices[v]);
    triangulate_face(corners.data(), f.data(), f.size(), t.triangles);
  }
  return t;
}

void triangulate_face(const Vec3d* corners, const std::uint32_t* f, std::size_t n,
                      std::vector<std::array<std::uint32_t, 3>>& out) {
  if (n < 3) return;
  if (n == 3) {
    out.push_back({f[0], f[1], f[2]});
    return;
  }
  // Newell normal; project along its dominant axis, CCW about it.
  double nx = 0, ny = 0, nz = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3d& a = corners[i];
    const Vec3d& b = corners[(i + 1) % n];
    nx += (a[1] - b[1]) * (a[2] + b[2]);
    ny += (a[2] - b[2]) * (a[0] + b[0]);
    nz += (a[0] - b[0]) * (a[1] + b[1]);
  }
  const double an[3] = {std::fabs(nx), std::fabs(ny), std::fabs(nz)};
  const int k = an[0] >= an[1] && an[0] >= an[2] ? 0 : (an[1] >= an[2] ? 1 : 2);
  const double sign = (k == 0 ? nx : k == 1 ? ny : nz) < 0 ? -1.0 : 1.0;
  const int u = (k + 1) % 3, w = (k + 2) % 3;
  thread_local std::vector<std::array<double, 2>> q;  // scratch, reused face to face
  thread_local std::vector<std::size_t> ring;
  q.resize(n);
  for (std::size_t i = 0; i < n; ++i) q[i] = {corners[i][size_t(u)], sign * corners[i][size_t(w)]};
  auto cross = [&](std::size_t a, std::size_t b, std::size_t c) {
    return (q[b][0] - q[a][0]) * (q[c][1] - q[a][1]) - (q[b][1] - q[a][1]) * (q[c][0] - q[a][0]);
  };
  bool convex = true;
  for (std::size_t i = 0; i < n && convex; ++i)
    convex = cross((i + n - 1) % n, i, (i + 1) % n) >= 0;
  if (convex) {  // the fan from the first vertex, as for any convex face
    for (std::size_t i = 1; i + 1 < n; ++i) out.push_back({f[0], f[i], f[i + 1]});
    return;
  }
  ring.resize(n);
  for (std::size_t i = 0; i < n; ++i) ring[i] = i;
  while (ring.size() > 3) {
    bool clipped = false;
    for (std::size_t i = 0; i < ring.size() && !clipped; ++i) {
      const std::size_t a = ring[(i + ring.size() - 1) % ring.size()], b = ring[i],
                        c = ring[(i + 1) % ring.size()];
      if (!(cross(a, b, c) > 0)) continue;  // reflex or flat corner
      bool empty = true;
      for (std::size_t j : ring) {
        if (j == a || j == b || j == c || q[j] == q[a] || q[j] == q[b] || q[j] == q[c]) continue;
        // inside or on the ear's boundary: a vertex on the diagonal c-a (a
        // thin sliver of the polygon running along it) forbids the ear too
        if (cross(a, b, j) >= 0 && cross(b, c, j) >= 0 && cross(c, a, j) >= 0) {
          empty = false;  // another vertex inside the ear
          break;
        }
      }
      if (!empty) continue;
      out.push_back({f[a], f[b], f[c]});
      ring.erase(ring.begin() + std::ptrdiff_t(i));
      clipped = true;
    }
    if (!clipped) break;
  }
  for (std::size_t i = 1; i + 1 < ring.size(); ++i)
    out.push_back({f[ring[0]], f[ring[i]], f[ring[i + 1]]});
}

namespace detail {

std::size_t ReaderBase::read_faces(FaceBatch*, std::size_t) {
  throw IoError(info_.path,
                std::string(info_.format_name) + " file has no faces (a point cloud, not a mesh)");
}

void ReaderBase::read_all_faces(std::vector<std::vector<std::uint32_t>>& faces) {
  FaceBatch b;
  while (read_faces(&b, std::size_t(1) << 16) > 0)
    for (std::size_t i = 0; i < b.size(); ++i)
      faces.emplace_back(b.face(i), b.face(i) + b.face_size(i));
}

std::string bad_index_message(std::uint64_t face, std::int64_t index, std::uint64_t vertex_count) {
  return "face #" + std::to_string(face) + " references vertex " + std::to_string(index) +
         " but the file has only " + std::to_string(vertex_count) + " vertices";
}

std::uint8_t color_to_u8(double v, bool is_float) {
  if (!(v == v)) return 0;
  if (is_float) v *= 255.0;
  v = std::round(v);
  return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
}

namespace {

bool starts_with(const std::string& s, const char* p) {
  return s.rfind(p, 0) == 0;
}

Format sniff(const std::string& path) {
  InputFile in(path, 4096);
  if (in.size() == 0) in.fail("empty file");
  char head[4096];
  std::size_t n = in.read_some(head, sizeof head);
  std::string s(head, n);
  if (starts_with(s, "LASF")) {
    if (n > 104 && (static_cast<unsigned char>(s[104]) & 0xC0)) return Format::laz;
    return extension_of(path) == "laz" ? Format::laz : Format::las;
  }
  if (starts_with(s, "ply\n") || starts_with(s, "ply\r")) return Format::ply;
  if (std::memchr(head, '\0', n)) return Format::unknown;  // binary, no known magic
  // Text: look at the first non-comment line.
  std::size_t i = 0;
  while (i < n) {
    std::size_t e = s.find_first_of("\r\n", i);
    if (e == std::string::npos) e = n;
    std::string line = s.substr(i, e - i);
    i = e + 1;
    std::size_t b = line.find_first_not_of(" \t");
    if (b == std::string::npos || line[b] == '#' || line.compare(b, 2, "//") == 0) continue;
    line = line.substr(b);
    std::vector<std::string_view> tok;
    if (split_tokens(line, tok) == 0) return Format::unknown;
    std::string kw(tok[0]);
    auto p = kw.find("OFF");
    if (p != std::string::npos && p + 3 == kw.size() &&
        kw.substr(0, p).find_first_not_of("CNST4n") == std::string::npos)
      return Format::off;
    static const char* obj_kw[] = {"v", "vn", "vt", "vp", "f",      "o",
                                   "g", "s",  "l",  "p",  "mtllib", "usemtl"};
    for (const char* k : obj_kw)
      if (kw == k) return Format::obj;
    double d;
    bool numeric = true;
    for (auto t : tok) numeric = numeric && parse_double(t, d);
    if (numeric) return Format::xyz;
    // A CSV header line ("X,Y,Z,...") followed by numbers.
    std::string l = lower(line);
    if (tok.size() >= 3 &&
        (starts_with(l, "x,y,z") || starts_with(l, "x y z") || starts_with(l, "//x")))
      return Format::xyz;
    return Format::unknown;
  }
  return Format::unknown;
}

}  // namespace
}  // namespace detail

Format detect_format(const std::string& path) {
  Format f = detail::sniff(path);
  if (f != Format::unknown) return f;
  // Fall back to the extension: the reader then reports what is wrong with
  // the content (e.g. "not a PLY file (first line is not 'ply')").
  const std::string ext = extension_of(path);
  if (ext == "ply") return Format::ply;
  if (ext == "obj") return Format::obj;
  if (ext == "off") return Format::off;
  if (ext == "las") return Format::las;
  if (ext == "laz") return Format::laz;
  if (ext == "xyz" || ext == "pts" || ext == "csv" || ext == "txt") return Format::xyz;
  return Format::unknown;
}

namespace detail {

std::unique_ptr<ReaderBase> open_reader(const std::string& path) {
  return open_reader(path, detect_format(path));
}

std::unique_ptr<ReaderBase> open_reader(const std::string& path, Format f) {
  switch (f) {
    case Format::ply:
      return open_ply(path);
    case Format::obj:
      return open_obj(path);
    case Format::off:
      return open_off(path);
    case Format::xyz:
      return open_xyz(path);
    case Format::las:
    case Format::laz:
      return open_las(path);
    case Format::unknown:
      break;
  }
  throw IoError(path, "not a point cloud or mesh file (unrecognised format)");
}

}  // namespace detail

std::unique_ptr<PointReader> PointReader::open(const std::string& path) {
  return detail::open_reader(path);
}

FileInfo read_header(const std::string& path) {
  return detail::open_reader(path)->info();
}

namespace {
/// A coordinate that is Inf or NaN (text "inf", 1e999, a binary NaN) is a defect of the file.
void check_finite(const std::vector<Vec3d>& ps, std::uint64_t first, const std::string& path) {
  for (std::size_t i = 0; i < ps.size(); ++i)
    if (!std::isfinite(ps[i][0]) || !std::isfinite(ps[i][1]) || !std::isfinite(ps[i][2]))
      throw IoError(path, "point " + std::to_string(first + i) +
                              " has a coordinate that is not a finite number");
}
}  // namespace

FileInfo scan_file(const std::string& path, ProgressFn progress, void* user) {
  auto r = detail::open_reader(path);
  FileInfo info = r->info();
  PointSet batch;
  BBox3 box;
  std::uint64_t counts[256] = {};
  std::uint64_t n = 0;
  while (r->read(batch, 1 << 18) > 0) {
    check_finite(batch.positions, n, path);
    for (const auto& p : batch.positions) box.add(p);
    for (std::uint8_t c : batch.classes) ++counts[c];
    n += batch.size();
    if (progress && !progress(r->progress(), "reading", user)) throw IoError(path, "cancelled");
  }
  r->check_tail();
  const FileInfo& after = r->info();  // text formats learn their counts while streaming
  info.point_count = n;
  info.face_count = after.face_count;
  info.max_face_corners = after.max_face_corners;
  info.has_faces = after.has_faces;
  info.has_colors = after.has_colors;
  info.bbox = box;
  info.bbox_from_header = false;
  info.scanned = true;
  info.class_counts.clear();
  if (info.has_classes)
    for (int c = 0; c < 256; ++c)
      if (counts[c]) info.class_counts[c] = counts[c];
  if (progress) progress(1.0, "reading", user);
  return info;
}

PointSet read_points(const std::string& path) {
  auto r = detail::open_reader(path);
  PointSet all, batch;
  while (r->read(batch, 1 << 20) > 0) {
    check_finite(batch.positions, all.size(), path);
    all.append(batch);
  }
  return all;
}

namespace {

void read_mesh_impl(const std::string& path, PolygonMesh& mesh, std::vector<Vec3f>& normals,
                    std::vector<Rgb8>& colors, Format known = Format::unknown) {
  const Format f = known == Format::unknown ? detect_format(path) : known;
  if (f == Format::obj) {
    detail::read_obj_mesh(path, mesh, normals);
    check_finite(mesh.vertices, 0, path);
    return;
  }
  auto r = detail::open_reader(path, f);
  if (f != Format::ply && f != Format::off)
    throw IoError(path, std::string(format_name(r->info().format)) +
                            " files hold no faces (a point cloud, not a mesh)");
  PointSet all, batch;
  while (r->read(batch, 1 << 20) > 0) all.append(batch);
  r->read_all_faces(mesh.faces);
  check_finite(all.positions, 0, path);
  mesh.vertices = std::move(all.positions);
  normals = std::move(all.normals);
  colors = std::move(all.colors);
}

}  // namespace

PolygonMesh read_polygon_mesh(const std::string& path) {
  PolygonMesh m;
  std::vector<Vec3f> n;
  std::vector<Rgb8> c;
  read_mesh_impl(path, m, n, c);
  return m;
}

struct MeshReader::Impl {
  std::string path;
  std::unique_ptr<detail::ReaderBase> reader;        // vertices; PLY/OFF faces too
  std::unique_ptr<detail::ObjFaceStream> obj_faces;  // OBJ faces (second pass)
  bool obj = false;
  std::uint64_t vertices = 0;
};

MeshReader::MeshReader() : impl_(std::make_unique<Impl>()) {}
MeshReader::~MeshReader() = default;

std::unique_ptr<MeshReader> MeshReader::open(const std::string& path) {
  const Format f = detect_format(path);
  std::unique_ptr<MeshReader> m(new MeshReader());
  m->impl_->path = path;
  m->impl_->obj = f == Format::obj;
  m->impl_->reader = detail::open_reader(path, f);
  if (f != Format::ply && f != Format::off && f != Format::obj)
    throw IoError(path, std::string(format_name(m->impl_->reader->info().format)) +
                            " files hold no faces (a point cloud, not a mesh)");
  m->info_ = m->impl_->reader->info();
  return m;
}

std::size_t MeshReader::read_vertices(PointSet& batch, std::size_t max_vertices) {
  Impl& m = *impl_;
  if (m.obj_faces) {
    batch.clear();
    return 0;
  }
  const std::size_t n = m.reader->read(batch, max_vertices);
  check_finite(batch.positions, m.vertices, m.path);
  m.vertices += n;
  if (m.obj) {  // as read_mesh(): OBJ colours are not kept, vn belong to face corners
    batch.colors.clear();
    batch.normals.clear();
  }
  return n;
}

std::size_t MeshReader::read_faces(FaceBatch& batch, std::size_t max_faces) {
  Impl& m = *impl_;
  if (!m.obj) {
    const std::size_t n = m.reader->read_faces(&batch, max_faces);
    info_.max_face_corners = m.reader->info().max_face_corners;
    return n;
  }
  if (!m.obj_faces) {
    PointSet sink;
    while (read_vertices(sink, std::size_t(1) << 16) > 0) {
    }
    info_ = m.reader->info();  // OBJ learns its counts while streaming (and checks the indices)
    if (info_.face_count == 0)
      throw IoError(m.path, "OBJ file has no faces (a point cloud, not a mesh)");
    m.obj_faces = std::make_unique<detail::ObjFaceStream>(m.path, m.vertices);
    m.reader.reset();
  }
  return m.obj_faces->read(batch, max_faces);
}

TriangleMesh read_mesh(const std::string& path) {
  return read_mesh(path, Format::unknown);
}

TriangleMesh read_mesh(const std::string& path, Format format) {
  PolygonMesh m;
  std::vector<Vec3f> n;
  std::vector<Rgb8> c;
  read_mesh_impl(path, m, n, c, format);
  TriangleMesh t = triangulate_polygons(m);
  t.normals = std::move(n);
  t.colors = std::move(c);
  return t;
}

}  // namespace citylod::io
