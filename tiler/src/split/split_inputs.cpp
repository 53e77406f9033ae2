// The split's inputs: folders expanded to their scene files, each input's file
// fingerprint (the up-to-date check) and sidecars (FILE.prj, ContextCapture
// metadata.xml), and pass 1: headers, bounding boxes, what the scene is made of.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <optional>
#include <set>
#include <stdexcept>

#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "split_internal.hpp"

namespace citylod::tiler::split_detail {

/// "<size>:<mtime ns>" of a file; IoError when it does not exist.
std::string fingerprint(const std::string& path) {
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw IoError(path, "no such file");
  if (fs::is_directory(st)) throw IoError(path, "is a directory, not a point cloud or mesh file");
  const auto size = fs::file_size(path, ec);
  if (ec) throw IoError(path, "cannot stat: " + ec.message());
  const auto mtime = fs::last_write_time(path, ec).time_since_epoch().count();
  return std::to_string(size) + ":" + std::to_string(static_cast<long long>(mtime));
}

Eigen::AlignedBox3d to_eigen(const io::BBox3& b) {
  return Eigen::AlignedBox3d(Eigen::Vector3d(b.min[0], b.min[1], b.min[2]),
                             Eigen::Vector3d(b.max[0], b.max[1], b.max[2]));
}

std::string inputs_label(const std::vector<InputInfo>& in) {
  std::string s = in.front().path;
  if (in.size() > 1) s += " (+" + std::to_string(in.size() - 1) + " more)";
  return s;
}

// ---------------------------------------------------------------------- inputs, sidecars
std::vector<std::string> expand_inputs(const std::vector<std::string>& inputs) {
  static const std::set<std::string> exts{"ply", "obj", "off", "las", "laz", "xyz", "pts"};
  std::vector<std::string> out;
  for (const auto& p : inputs) {
    std::error_code ec;
    if (!fs::is_directory(p, ec)) {
      out.push_back(p);
      continue;
    }
    std::vector<std::string> found;
    for (fs::recursive_directory_iterator it(p, ec), end; !ec && it != end; it.increment(ec)) {
      std::error_code e2;
      if (it->is_regular_file(e2) && exts.count(io::extension_of(it->path().string())))
        found.push_back(it->path().string());
    }
    if (ec) throw IoError(p, "cannot list the folder: " + ec.message());
    if (found.empty()) throw IoError(p, "no PLY, OBJ, OFF, LAS, LAZ or XYZ file in this folder");
    std::sort(found.begin(), found.end());
    out.insert(out.end(), found.begin(), found.end());
  }
  return out;
}

namespace {

std::string read_small_file(const fs::path& p) {
  std::error_code ec;
  const auto size = fs::file_size(p, ec);
  if (ec) throw IoError(p.string(), "cannot read: " + ec.message());
  if (size > (1u << 20)) throw IoError(p.string(), "too large for a metadata file (> 1 MiB)");
  std::FILE* f = std::fopen(p.c_str(), "rb");
  if (!f) throw IoError(p.string(), std::string("cannot open: ") + std::strerror(errno));
  std::string s(size, '\0');
  const std::size_t got = std::fread(s.data(), 1, s.size(), f);
  std::fclose(f);
  if (got != s.size()) throw IoError(p.string(), "cannot read");
  return s;
}

/// The text of <tag>...</tag> (blanks trimmed); nullopt when absent.
std::optional<std::string> xml_element(const std::string& doc, const std::string& tag) {
  const std::size_t a = doc.find("<" + tag + ">");
  if (a == std::string::npos) return std::nullopt;
  const std::size_t b = doc.find("</" + tag + ">", a);
  if (b == std::string::npos) return std::nullopt;
  std::string v = doc.substr(a + tag.size() + 2, b - a - tag.size() - 2);
  const auto blank = [](unsigned char c) { return std::isspace(c) != 0; };
  while (!v.empty() && blank(static_cast<unsigned char>(v.back()))) v.pop_back();
  std::size_t k = 0;
  while (k < v.size() && blank(static_cast<unsigned char>(v[k]))) ++k;
  return v.substr(k);
}

}  // namespace

void read_sidecars(InputInfo& in, std::set<std::string>& used) {
  const fs::path file(in.path);
  fs::path prj = file;
  prj.replace_extension(".prj");
  std::error_code ec;
  if (fs::is_regular_file(prj, ec)) {
    in.sidecar_crs = read_small_file(prj);
    while (!in.sidecar_crs.empty() &&
           std::isspace(static_cast<unsigned char>(in.sidecar_crs.back())))
      in.sidecar_crs.pop_back();
    if (in.sidecar_crs.empty()) throw IoError(prj.string(), "empty .prj file");
    used.insert(fs::absolute(prj).lexically_normal().string());
  }
  fs::path dir = fs::absolute(file).lexically_normal().parent_path();
  for (int up = 0; up < 3 && !dir.empty(); ++up, dir = dir.parent_path()) {
    const fs::path xml = dir / "metadata.xml";
    if (!fs::is_regular_file(xml, ec)) {
      if (dir == dir.root_path()) break;
      continue;
    }
    const std::string doc = read_small_file(xml);
    if (doc.find("<ModelMetadata") == std::string::npos) break;  // someone else's metadata.xml
    used.insert(xml.string());
    const auto srs = xml_element(doc, "SRS");
    if (srs && !srs->empty() && in.sidecar_crs.empty()) {
      if (srs->rfind("ENU:", 0) == 0) {
        const auto ll = parse_triple(srs->substr(4));
        if (!ll) throw IoError(xml.string(), "<SRS>" + *srs + "</SRS>: expected ENU:LAT,LON");
        in.sidecar_origin = srs->substr(4) + ",0";
      } else {
        in.sidecar_crs = *srs;
      }
    }
    if (const auto o = xml_element(doc, "SRSOrigin")) {
      const auto v = parse_triple(*o);
      if (!v) throw IoError(xml.string(), "<SRSOrigin>" + *o + "</SRSOrigin>: expected X,Y,Z");
      in.offset = *v;
    }
    break;
  }
}

// ---------------------------------------------------------------------- pass 1
void Splitter::pass1_headers() {
  for (auto& in : inputs_) {  // paths, sidecars and offsets from run()
    in.info = io::read_header(in.path);
    in.mesh = in.info.has_faces;
    // OBJ and text files have no header counts: their scan below decides
    if (in.info.point_count == 0 && in.info.format != io::Format::obj &&
        in.info.format != io::Format::xyz)
      throw IoError(in.path, "no points (empty file)");
  }
  // Bounding boxes: the LAS header's, or streamed (also validates the file).
  const double n = static_cast<double>(inputs_.size());
  for (std::size_t i = 0; i < inputs_.size(); ++i) {
    InputInfo& in = inputs_[i];
    if (!(in.info.bbox_from_header && !in.info.bbox.empty())) {
      struct Ctx {
        Stages* s;
        double a, b;
      } ctx{&stages_, 0.05 * double(i) / n, 0.05 * double(i + 1) / n};
      in.info = io::scan_file(
          in.path,
          [](double f, const char*, void* u) {
            auto* c = static_cast<Ctx*>(u);
            c->s->report(c->a, c->b, f, "scan");
            return true;
          },
          &ctx);
      in.mesh = in.info.has_faces;
      if (in.info.point_count == 0) throw IoError(in.path, "no points (empty file)");
    }
    for (int a = 0; a < 3; ++a) {
      in.info.bbox.min[std::size_t(a)] += in.offset[std::size_t(a)];
      in.info.bbox.max[std::size_t(a)] += in.offset[std::size_t(a)];
      if (!std::isfinite(in.info.bbox.min[a]) || !std::isfinite(in.info.bbox.max[a]))
        throw IoError(in.path, "bounding box is not finite");
    }
    bbox_crs_.add(in.info.bbox);
    // a region holds points, or a mesh's samples (>= one a face) and faces: ~3 per face
    total_points_ += in.mesh ? 3 * in.info.face_count : in.info.point_count;
  }
  const bool any_mesh =
      std::any_of(inputs_.begin(), inputs_.end(), [](const auto& i) { return i.mesh; });
  const bool any_points =
      std::any_of(inputs_.begin(), inputs_.end(), [](const auto& i) { return !i.mesh; });
  if (any_mesh && any_points)
    throw std::invalid_argument("mixing meshes and point clouds in one split is not supported");
  mesh_scene_ = any_mesh;
}

}  // namespace citylod::tiler::split_detail
