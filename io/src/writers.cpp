// PLY and OBJ writers (atomic: temp file + rename).
#include "citylod/io/writers.hpp"

#include <cstdio>
#include <cstring>
#include <string>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/error.hpp"

namespace citylod::io {
namespace {

// Buffered appends to an AtomicFile, or to memory (no file: bytes() holds them all).
class Out {
 public:
  explicit Out(AtomicFile& f) : f_(&f) { buf_.reserve(1 << 20); }
  Out() = default;
  ~Out() = default;
  void raw(const void* p, std::size_t n) {
    buf_.append(static_cast<const char*>(p), n);
    if (f_ && buf_.size() >= (1 << 20)) flush();
  }
  template <typename T>
  void bin(T v) {
    raw(&v, sizeof v);  // little-endian hosts
  }
  void str(const std::string& s) { raw(s.data(), s.size()); }
  void num(double v) {
    char b[32];
    int n = std::snprintf(b, sizeof b, "%.17g", v);
    raw(b, static_cast<std::size_t>(n));
  }
  void numf(float v) {
    char b[32];
    int n = std::snprintf(b, sizeof b, "%.9g", static_cast<double>(v));
    raw(b, static_cast<std::size_t>(n));
  }
  void ch(char c) { raw(&c, 1); }
  void flush() {
    if (!f_) return;
    f_->write(buf_.data(), buf_.size());
    buf_.clear();
  }
  std::string& bytes() { return buf_; }

 private:
  AtomicFile* f_ = nullptr;
  std::string buf_;
};

void check_points(const std::string& path, std::size_t n, std::size_t normals, std::size_t colors,
                  std::size_t classes) {
  if ((normals && normals != n) || (colors && colors != n) || (classes && classes != n))
    throw IoError(path, "cannot write: attribute arrays and positions differ in size");
}

void vertex_header(Out& o, std::size_t n, const PlyWriteOptions& opt, bool normals, bool colors,
                   bool classes) {
  o.str("ply\nformat ");
  o.str(opt.binary ? "binary_little_endian" : "ascii");
  o.str(" 1.0\n");
  if (!opt.comment.empty()) o.str("comment " + opt.comment + "\n");
  o.str("element vertex " + std::to_string(n) + "\n");
  const char* t = opt.double_precision ? "double" : "float";
  for (const char* a : {"x", "y", "z"}) o.str(std::string("property ") + t + " " + a + "\n");
  if (normals) o.str("property float nx\nproperty float ny\nproperty float nz\n");
  if (colors) o.str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
  if (classes) o.str("property uchar classification\n");
}

void vertex_record(Out& o, const PlyWriteOptions& opt, const Vec3d& p, const Vec3f* n,
                   const Rgb8* c, const std::uint8_t* cls) {
  if (opt.binary) {
    for (double v : p) {
      if (opt.double_precision)
        o.bin(v);
      else
        o.bin(static_cast<float>(v));
    }
    if (n)
      for (float v : *n) o.bin(v);
    if (c)
      for (std::uint8_t v : *c) o.bin(v);
    if (cls) o.bin(*cls);
    return;
  }
  for (int a = 0; a < 3; ++a) {
    if (a) o.ch(' ');
    if (opt.double_precision)
      o.num(p[a]);
    else
      o.numf(static_cast<float>(p[a]));
  }
  if (n)
    for (float v : *n) {
      o.ch(' ');
      o.numf(v);
    }
  if (c)
    for (std::uint8_t v : *c) o.str(" " + std::to_string(v));
  if (cls) o.str(" " + std::to_string(*cls));
  o.ch('\n');
}

template <typename Faces>
void write_ply_mesh(const std::string& path, const std::vector<Vec3d>& vertices,
                    const std::vector<Vec3f>& normals, const std::vector<Rgb8>& colors,
                    const Faces& faces, const PlyWriteOptions& opt) {
  check_points(path, vertices.size(), normals.size(), colors.size(), 0);
  for (const auto& f : faces) {
    if (f.size() > 255) throw IoError(path, "cannot write: a face has more than 255 vertices");
    for (auto i : f)
      if (i >= vertices.size()) throw IoError(path, "cannot write: face index out of range");
  }
  AtomicFile file(path);
  Out o(file);
  vertex_header(o, vertices.size(), opt, !normals.empty(), !colors.empty(), false);
  o.str("element face " + std::to_string(faces.size()) +
        "\nproperty list uchar int vertex_indices\nend_header\n");
  for (std::size_t i = 0; i < vertices.size(); ++i)
    vertex_record(o, opt, vertices[i], normals.empty() ? nullptr : &normals[i],
                  colors.empty() ? nullptr : &colors[i], nullptr);
  for (const auto& f : faces) {
    if (opt.binary) {
      o.bin(static_cast<std::uint8_t>(f.size()));
      for (auto i : f) o.bin(static_cast<std::int32_t>(i));
    } else {
      o.str(std::to_string(f.size()));
      for (auto i : f) o.str(" " + std::to_string(i));
      o.ch('\n');
    }
  }
  o.flush();
  file.commit();
}

template <typename Faces>
void write_obj_impl(const std::string& path, const std::vector<Vec3d>& vertices,
                    const std::vector<Vec3f>& normals, const Faces& faces) {
  check_points(path, vertices.size(), normals.size(), 0, 0);
  for (const auto& f : faces)
    for (auto i : f)
      if (i >= vertices.size()) throw IoError(path, "cannot write: face index out of range");
  AtomicFile file(path);
  Out o(file);
  o.str("# written by citylod\n");
  for (const auto& v : vertices) {
    o.str("v ");
    o.num(v[0]);
    o.ch(' ');
    o.num(v[1]);
    o.ch(' ');
    o.num(v[2]);
    o.ch('\n');
  }
  for (const auto& n : normals) {
    o.str("vn ");
    o.numf(n[0]);
    o.ch(' ');
    o.numf(n[1]);
    o.ch(' ');
    o.numf(n[2]);
    o.ch('\n');
  }
  const bool with_n = !normals.empty();
  for (const auto& f : faces) {
    o.ch('f');
    for (auto i : f) {
      std::string s = std::to_string(static_cast<std::uint64_t>(i) + 1);
      o.str(" " + s);
      if (with_n) o.str("//" + s);
    }
    o.ch('\n');
  }
  o.flush();
  file.commit();
}

void write_points(Out& o, const std::string& path, const PointSet& pts,
                  const PlyWriteOptions& opt) {
  check_points(path, pts.positions.size(), pts.normals.size(), pts.colors.size(),
               pts.classes.size());
  vertex_header(o, pts.size(), opt, pts.has_normals(), pts.has_colors(), pts.has_classes());
  o.str("end_header\n");
  for (std::size_t i = 0; i < pts.size(); ++i)
    vertex_record(o, opt, pts.positions[i], pts.has_normals() ? &pts.normals[i] : nullptr,
                  pts.has_colors() ? &pts.colors[i] : nullptr,
                  pts.has_classes() ? &pts.classes[i] : nullptr);
}

}  // namespace

void write_ply(const std::string& path, const PointSet& pts, const PlyWriteOptions& opt) {
  check_points(path, pts.positions.size(), pts.normals.size(), pts.colors.size(),
               pts.classes.size());
  AtomicFile file(path);
  Out o(file);
  write_points(o, path, pts, opt);
  o.flush();
  file.commit();
}

std::string ply_bytes(const std::string& path, const PointSet& pts, const PlyWriteOptions& opt) {
  Out o;
  write_points(o, path, pts, opt);
  return std::move(o.bytes());
}

void write_ply(const std::string& path, const TriangleMesh& mesh, const PlyWriteOptions& opt) {
  write_ply_mesh(path, mesh.vertices, mesh.normals, mesh.colors, mesh.triangles, opt);
}

void write_ply(const std::string& path, const PolygonMesh& mesh, const PlyWriteOptions& opt) {
  write_ply_mesh(path, mesh.vertices, {}, {}, mesh.faces, opt);
}

void write_obj(const std::string& path, const TriangleMesh& mesh) {
  write_obj_impl(path, mesh.vertices, mesh.normals, mesh.triangles);
}

void write_obj(const std::string& path, const PolygonMesh& mesh) {
  write_obj_impl(path, mesh.vertices, {}, mesh.faces);
}

}  // namespace citylod::io
