// Wavefront OBJ reader: "v x y z [r g b]", "vn", "f v v/vt v/vt/vn v//vn"
// (negative = relative indices); every other statement is ignored.
#include <algorithm>
#include <cmath>

#include "readers_internal.hpp"

namespace citylod::io::detail {
namespace {

// Parses the vertex part of an "f" corner ("12", "12/4", "12/4/7", "12//7").
bool parse_corner(std::string_view c, std::int64_t& v, std::int64_t& vn) {
  vn = 0;
  auto s1 = c.find('/');
  if (!parse_i64(c.substr(0, s1), v)) return false;
  if (s1 == std::string_view::npos) return true;
  auto s2 = c.find('/', s1 + 1);
  if (s2 == std::string_view::npos) return true;
  std::string_view n = c.substr(s2 + 1);
  return n.empty() || parse_i64(n, vn);
}

// The 0-based vertex index of corner `v` of face #`face` (1-based; negative: relative to
// the `seen` "v" lines before the face). A forward reference (v > seen) is returned for
// the caller to check against the vertex count; 0 and a relative index reaching before
// the first vertex fail `in`.
std::int64_t obj_vertex_index(const InputFile& in, std::int64_t v, std::uint64_t seen,
                              std::uint64_t face) {
  if (v < 0) {
    if (static_cast<std::uint64_t>(-v) > seen) in.fail(bad_index_message(face, v, seen));
    return static_cast<std::int64_t>(seen) + v;
  }
  if (v == 0) in.fail(bad_index_message(face, 0, seen) + " (OBJ indices start at 1)");
  return v - 1;
}

bool parse_vertex(const std::vector<std::string_view>& tok, Vec3d& p, Rgb8* rgb, bool& has_rgb) {
  if (tok.size() < 4) return false;
  for (int a = 0; a < 3; ++a)
    if (!parse_double(tok[static_cast<std::size_t>(a) + 1], p[a])) return false;
  has_rgb = false;
  if (tok.size() >= 7 && rgb) {
    double c[3];
    if (parse_double(tok[4], c[0]) && parse_double(tok[5], c[1]) && parse_double(tok[6], c[2])) {
      bool is_float = c[0] <= 1.0 && c[1] <= 1.0 && c[2] <= 1.0;
      for (int a = 0; a < 3; ++a) (*rgb)[a] = color_to_u8(c[a], is_float);
      has_rgb = true;
    }
  }
  return true;
}

// Streams "v" lines as points; counts faces and checks their indices.
class ObjReader final : public ReaderBase {
 public:
  explicit ObjReader(const std::string& path) : in_(path) {
    info_.path = path;
    info_.format = Format::obj;
    info_.format_name = "OBJ";
    info_.encoding = "ascii";
    if (in_.size() == 0) in_.fail("empty file");
  }

  std::size_t read(PointSet& b, std::size_t max_points) override {
    b.clear();
    std::string line;
    while (b.positions.size() < max_points && in_.getline(line)) {
      ++line_no_;
      split_tokens(line, tok_);
      if (tok_.empty()) continue;
      if (tok_[0] == "v") {
        Vec3d p;
        Rgb8 c{};
        bool has_rgb = false;
        if (!parse_vertex(tok_, p, &c, has_rgb))
          in_.fail("bad vertex at line " + std::to_string(line_no_));
        std::string bad = check_finite(p.data(), vertices_);
        if (!bad.empty()) in_.fail(bad);
        if (vertices_ == 0) colors_ = has_rgb;
        if (colors_ && !has_rgb) {
          // Inconsistent colours: drop the attribute for this batch onwards.
          colors_ = false;
          b.colors.clear();
        }
        b.positions.push_back(p);
        if (colors_) b.colors.push_back(c);
        ++vertices_;
      } else if (tok_[0] == "f") {
        ++faces_;
        max_corners_ = std::max<std::uint64_t>(max_corners_, tok_.size() - 1);
        for (std::size_t k = 1; k < tok_.size(); ++k) {
          std::int64_t v, vn;
          if (!parse_corner(tok_[k], v, vn))
            in_.fail("bad face at line " + std::to_string(line_no_));
          obj_vertex_index(in_, v, vertices_, faces_ - 1);
          if (v > 0 && static_cast<std::uint64_t>(v) > max_index_) {
            max_index_ = static_cast<std::uint64_t>(v);
            max_index_face_ = faces_ - 1;
          }
        }
      }
    }
    points_read_ += b.positions.size();
    if (b.positions.empty()) finish();
    return b.positions.size();
  }

  double progress() const override {
    return in_.size()
               ? std::min(1.0, static_cast<double>(in_.tell()) / static_cast<double>(in_.size()))
               : 1.0;
  }

  void check_tail() override {
    PointSet sink;
    while (read(sink, 1 << 16) > 0) {
    }
  }

 private:
  void finish() {
    if (finished_) return;
    finished_ = true;
    if (vertices_ == 0 && faces_ == 0) in_.fail("not an OBJ file (no 'v' or 'f' statements)");
    if (max_index_ > vertices_)
      in_.fail(
          bad_index_message(max_index_face_, static_cast<std::int64_t>(max_index_), vertices_) +
          " (OBJ indices start at 1)");
    info_.point_count = vertices_;
    info_.face_count = faces_;
    info_.max_face_corners = static_cast<std::uint32_t>(std::min<std::uint64_t>(max_corners_, ~0u));
    info_.has_faces = faces_ > 0;
    info_.has_colors = colors_;
  }

  InputFile in_;
  std::vector<std::string_view> tok_;
  std::uint64_t line_no_ = 0, vertices_ = 0, faces_ = 0, max_index_ = 0, max_index_face_ = 0;
  std::uint64_t max_corners_ = 0;
  bool colors_ = false, finished_ = false;
};

}  // namespace

std::unique_ptr<ReaderBase> open_obj(const std::string& path) {
  return std::make_unique<ObjReader>(path);
}

ObjFaceStream::ObjFaceStream(const std::string& path, std::uint64_t vertex_count)
    : in_(path), total_(vertex_count) {}

std::size_t ObjFaceStream::read(FaceBatch& out, std::size_t max_faces) {
  out.clear();
  std::size_t got = 0;
  while (got < max_faces && in_.getline(line_)) {
    ++line_no_;
    split_tokens(line_, tok_);
    if (tok_.empty()) continue;
    if (tok_[0] == "v") {
      ++seen_;
      continue;
    }
    if (tok_[0] != "f") continue;
    const std::uint64_t face = faces_++;
    for (std::size_t k = 1; k < tok_.size(); ++k) {
      std::int64_t v, n;
      if (!parse_corner(tok_[k], v, n)) in_.fail("bad face at line " + std::to_string(line_no_));
      const std::int64_t i = obj_vertex_index(in_, v, seen_, face);
      if (static_cast<std::uint64_t>(i) >= total_)
        in_.fail(bad_index_message(face, v, total_) + " (OBJ indices start at 1)");
      if (i > 0xFFFFFFFFll) in_.fail(bad_index_message(face, v, total_));
      out.corners.push_back(static_cast<std::uint32_t>(i));
    }
    out.offsets.push_back(out.corners.size());
    ++got;
  }
  return got;
}

void read_obj_mesh(const std::string& path, PolygonMesh& mesh, std::vector<Vec3f>& normals) {
  InputFile in(path);
  if (in.size() == 0) in.fail("empty file");
  mesh = {};
  normals.clear();
  std::vector<Vec3f> vn;
  std::vector<std::int64_t> vn_of_vertex;  // index into vn per vertex (-1 none)
  std::string line;
  std::vector<std::string_view> tok;
  std::uint64_t line_no = 0;
  std::vector<std::uint32_t> poly;
  std::uint64_t max_index = 0, max_index_face = 0;
  while (in.getline(line)) {
    ++line_no;
    split_tokens(line, tok);
    if (tok.empty()) continue;
    if (tok[0] == "v") {
      Vec3d p;
      bool has_rgb;
      if (!parse_vertex(tok, p, nullptr, has_rgb))
        in.fail("bad vertex at line " + std::to_string(line_no));
      std::string bad = check_finite(p.data(), mesh.vertices.size());
      if (!bad.empty()) in.fail(bad);
      mesh.vertices.push_back(p);
      vn_of_vertex.push_back(-1);
    } else if (tok[0] == "vn") {
      Vec3d n{0, 0, 0};
      if (tok.size() < 4 || !parse_double(tok[1], n[0]) || !parse_double(tok[2], n[1]) ||
          !parse_double(tok[3], n[2]))
        in.fail("bad normal at line " + std::to_string(line_no));
      vn.push_back({static_cast<float>(n[0]), static_cast<float>(n[1]), static_cast<float>(n[2])});
    } else if (tok[0] == "f") {
      const std::size_t face = mesh.faces.size();
      const std::uint64_t nv = mesh.vertices.size();
      poly.clear();
      for (std::size_t k = 1; k < tok.size(); ++k) {
        std::int64_t v, n;
        if (!parse_corner(tok[k], v, n)) in.fail("bad face at line " + std::to_string(line_no));
        if (v > 0 && static_cast<std::uint64_t>(v) > max_index) {
          max_index = static_cast<std::uint64_t>(v);  // forward references: checked at the end
          max_index_face = face;
        }
        v = obj_vertex_index(in, v, nv, face);
        if (v > 0xFFFFFFFFll) in.fail(bad_index_message(face, v, nv));
        if (n != 0) {
          std::int64_t ni = n < 0 ? static_cast<std::int64_t>(vn.size()) + n : n - 1;
          if (ni < 0 || static_cast<std::uint64_t>(ni) >= vn.size())
            in.fail("face #" + std::to_string(face) + " references normal " + std::to_string(n) +
                    " but only " + std::to_string(vn.size()) + " normals precede it");
          if (static_cast<std::uint64_t>(v) < nv) vn_of_vertex[static_cast<std::size_t>(v)] = ni;
        }
        poly.push_back(static_cast<std::uint32_t>(v));
      }
      mesh.faces.push_back(poly);
    }
  }
  if (mesh.vertices.empty() && mesh.faces.empty())
    in.fail("not an OBJ file (no 'v' or 'f' statements)");
  if (max_index > mesh.vertices.size())
    in.fail(bad_index_message(max_index_face, static_cast<std::int64_t>(max_index),
                              mesh.vertices.size()) +
            " (OBJ indices start at 1)");
  if (mesh.faces.empty()) in.fail("OBJ file has no faces (a point cloud, not a mesh)");
  bool all_normals = !vn.empty() && std::all_of(vn_of_vertex.begin(), vn_of_vertex.end(),
                                                [](std::int64_t i) { return i >= 0; });
  if (all_normals) {
    normals.resize(mesh.vertices.size());
    for (std::size_t i = 0; i < normals.size(); ++i)
      normals[i] = vn[static_cast<std::size_t>(vn_of_vertex[i])];
  }
}

}  // namespace citylod::io::detail
