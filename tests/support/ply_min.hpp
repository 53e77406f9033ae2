// Minimal readers for test data (lod tests cannot use io/): PLY (ascii and
// binary_little_endian; vertex x/y/z [nx/ny/nz], faces as vertex_indices lists),
// OFF (triangles/polygons fanned), and LAS point records (xyz + class) through
// support/las_read.hpp.
// Header-only, for tests only: no validation beyond what the tests need.
#pragma once

#include "citylod/lod/types.hpp"
#include "support/las_read.hpp"

#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace citylod::test {

namespace ply_detail {
inline int type_size(const std::string& t) {
  if (t == "char" || t == "uchar" || t == "int8" || t == "uint8") return 1;
  if (t == "short" || t == "ushort" || t == "int16" || t == "uint16") return 2;
  if (t == "int" || t == "uint" || t == "float" || t == "int32" || t == "uint32" || t == "float32")
    return 4;
  if (t == "double" || t == "float64") return 8;
  throw std::runtime_error("ply: unknown type " + t);
}
inline double read_bin(const char* p, const std::string& t) {
  if (t == "char" || t == "int8") return *reinterpret_cast<const std::int8_t*>(p);
  if (t == "uchar" || t == "uint8") return *reinterpret_cast<const std::uint8_t*>(p);
  std::int16_t s;
  std::uint16_t us;
  std::int32_t i;
  std::uint32_t ui;
  float f;
  double d;
  if (t == "short" || t == "int16") {
    std::memcpy(&s, p, 2);
    return s;
  }
  if (t == "ushort" || t == "uint16") {
    std::memcpy(&us, p, 2);
    return us;
  }
  if (t == "int" || t == "int32") {
    std::memcpy(&i, p, 4);
    return i;
  }
  if (t == "uint" || t == "uint32") {
    std::memcpy(&ui, p, 4);
    return ui;
  }
  if (t == "float" || t == "float32") {
    std::memcpy(&f, p, 4);
    return f;
  }
  std::memcpy(&d, p, 8);
  return d;
}
struct Prop {
  std::string name, type, count_type;
  bool list = false;
};
struct Elem {
  std::string name;
  long count = 0;
  std::vector<Prop> props;
};
}  // namespace ply_detail

/// Reads a PLY point cloud or triangle mesh into a BuildingInput.
inline lod::BuildingInput read_ply_min(const std::string& path) {
  using namespace ply_detail;
  std::ifstream f(path, std::ios::binary);
  if (!f) throw std::runtime_error("cannot open " + path);
  std::string line, format;
  std::vector<Elem> elems;
  while (std::getline(f, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream ls(line);
    std::string w;
    ls >> w;
    if (w == "format")
      ls >> format;
    else if (w == "element") {
      Elem e;
      ls >> e.name >> e.count;
      elems.push_back(e);
    } else if (w == "property") {
      Prop p;
      std::string t;
      ls >> t;
      if (t == "list") {
        p.list = true;
        ls >> p.count_type >> p.type >> p.name;
      } else {
        p.type = t;
        ls >> p.name;
      }
      elems.back().props.push_back(p);
    } else if (w == "end_header")
      break;
  }
  const bool ascii = format == "ascii";
  if (!ascii && format != "binary_little_endian")
    throw std::runtime_error("ply: unsupported format " + format);
  lod::BuildingInput in;
  for (const Elem& e : elems) {
    int ix = -1, iy = -1, iz = -1, inx = -1, iny = -1, inz = -1, ilist = -1;
    for (int k = 0; k < static_cast<int>(e.props.size()); ++k) {
      const std::string& n = e.props[k].name;
      if (n == "x")
        ix = k;
      else if (n == "y")
        iy = k;
      else if (n == "z")
        iz = k;
      else if (n == "nx")
        inx = k;
      else if (n == "ny")
        iny = k;
      else if (n == "nz")
        inz = k;
      else if (e.props[k].list && (n == "vertex_indices" || n == "vertex_index"))
        ilist = k;
    }
    std::vector<double> vals(e.props.size());
    std::vector<long> idx;
    char buf[8];
    for (long r = 0; r < e.count; ++r) {
      for (std::size_t k = 0; k < e.props.size(); ++k) {
        const Prop& p = e.props[k];
        if (p.list) {
          double cnt;
          if (ascii)
            f >> cnt;
          else {
            f.read(buf, type_size(p.count_type));
            cnt = read_bin(buf, p.count_type);
          }
          if (static_cast<int>(k) == ilist) idx.clear();
          for (long j = 0; j < static_cast<long>(cnt); ++j) {
            double v;
            if (ascii)
              f >> v;
            else {
              f.read(buf, type_size(p.type));
              v = read_bin(buf, p.type);
            }
            if (static_cast<int>(k) == ilist) idx.push_back(static_cast<long>(v));
          }
        } else if (ascii) {
          f >> vals[k];
        } else {
          f.read(buf, type_size(p.type));
          vals[k] = read_bin(buf, p.type);
        }
      }
      if (e.name == "vertex") {
        in.points.emplace_back(vals[ix], vals[iy], vals[iz]);
        if (inx >= 0 && iny >= 0 && inz >= 0)
          in.normals.emplace_back(vals[inx], vals[iny], vals[inz]);
      } else if (e.name == "face" && ilist >= 0) {
        for (std::size_t j = 1; j + 1 < idx.size(); ++j)
          in.triangles.push_back({int(idx[0]), int(idx[j]), int(idx[j + 1])});
      }
    }
  }
  if (!f) throw std::runtime_error("ply: truncated " + path);
  return in;
}

/// Reads an OFF mesh (polygons fanned into triangles).
inline lod::BuildingInput read_off_min(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("cannot open " + path);
  std::string head;
  f >> head;
  long nv, nf, ne;
  f >> nv >> nf >> ne;
  lod::BuildingInput in;
  for (long i = 0; i < nv; ++i) {
    double x, y, z;
    f >> x >> y >> z;
    in.points.emplace_back(x, y, z);
  }
  for (long i = 0; i < nf; ++i) {
    int n;
    f >> n;
    std::vector<int> ids(n);
    for (auto& v : ids) f >> v;
    std::string rest;
    std::getline(f, rest);
    for (int j = 1; j + 1 < n; ++j) in.triangles.push_back({ids[0], ids[j], ids[j + 1]});
  }
  if (!f) throw std::runtime_error("off: truncated " + path);
  return in;
}

/// Reads a LAS file's xyz (support/las_read.hpp), keeping points of `cls` (or all
/// with cls < 0), re-centred on `origin_out` (set to the bbox centre of the kept points).
inline lod::BuildingInput read_las_min(const std::string& path, int cls,
                                       lod::Vec3* origin_out = nullptr) {
  const auto las = read_las(path);
  if (!las) throw std::runtime_error("cannot read " + path + " as LAS");
  std::vector<lod::Vec3> pts;
  for (std::uint64_t i = 0; i < las->point_count &&
                            las->point_offset + (i + 1) * las->record_length <= las->bytes.size();
       ++i) {
    const LasRecord r = las->point(i);
    if (cls >= 0 && r.cls != cls) continue;
    pts.emplace_back(r.xyz[0], r.xyz[1], r.xyz[2]);
  }
  lod::Vec3 lo = pts.empty() ? lod::Vec3::Zero() : pts[0], hi = lo;
  for (const auto& p : pts) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const lod::Vec3 c = 0.5 * (lo + hi);
  lod::BuildingInput in;
  for (const auto& p : pts) in.points.push_back(p - c);
  if (origin_out) *origin_out = c;
  return in;
}

}  // namespace citylod::test
