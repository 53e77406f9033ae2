// PLY reader: ascii, binary_little_endian, binary_big_endian; any property
// order and types; vertex (x y z [nx ny nz] [red green blue] [classification])
// and face (list vertex_indices | vertex_index) elements; others skipped.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "readers_internal.hpp"

namespace citylod::io::detail {
namespace {

enum class PlyType { i8, u8, i16, u16, i32, u32, f32, f64 };

bool parse_type(const std::string& s, PlyType& t) {
  static const struct {
    const char* name;
    PlyType type;
  } table[] = {{"char", PlyType::i8},    {"int8", PlyType::i8},     {"uchar", PlyType::u8},
               {"uint8", PlyType::u8},   {"short", PlyType::i16},   {"int16", PlyType::i16},
               {"ushort", PlyType::u16}, {"uint16", PlyType::u16},  {"int", PlyType::i32},
               {"int32", PlyType::i32},  {"uint", PlyType::u32},    {"uint32", PlyType::u32},
               {"float", PlyType::f32},  {"float32", PlyType::f32}, {"double", PlyType::f64},
               {"float64", PlyType::f64}};
  for (const auto& e : table)
    if (s == e.name) {
      t = e.type;
      return true;
    }
  return false;
}

std::size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::i8:
    case PlyType::u8:
      return 1;
    case PlyType::i16:
    case PlyType::u16:
      return 2;
    case PlyType::i32:
    case PlyType::u32:
    case PlyType::f32:
      return 4;
    case PlyType::f64:
      return 8;
  }
  return 0;
}

bool is_float(PlyType t) {
  return t == PlyType::f32 || t == PlyType::f64;
}

template <typename T>
T load(const unsigned char* p, bool swap) {
  unsigned char b[sizeof(T)];
  if (swap) {
    for (std::size_t i = 0; i < sizeof(T); ++i) b[i] = p[sizeof(T) - 1 - i];
  } else {
    std::memcpy(b, p, sizeof(T));
  }
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

double decode(const unsigned char* p, PlyType t, bool swap) {
  switch (t) {
    case PlyType::i8:
      return static_cast<double>(static_cast<std::int8_t>(*p));
    case PlyType::u8:
      return static_cast<double>(*p);
    case PlyType::i16:
      return load<std::int16_t>(p, swap);
    case PlyType::u16:
      return load<std::uint16_t>(p, swap);
    case PlyType::i32:
      return load<std::int32_t>(p, swap);
    case PlyType::u32:
      return load<std::uint32_t>(p, swap);
    case PlyType::f32:
      return load<float>(p, swap);
    case PlyType::f64:
      return load<double>(p, swap);
  }
  return 0;
}

struct PlyProp {
  std::string name;
  PlyType type = PlyType::f32;
  bool is_list = false;
  PlyType count_type = PlyType::u8;
  std::size_t offset = 0;  // byte offset in a fixed-size binary record
};

struct PlyElement {
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProp> props;
  bool fixed = true;         // no list property
  std::size_t stride = 0;    // record size if fixed
  std::size_t min_size = 0;  // smallest possible binary record
};

enum class Encoding { ascii, le, be };

constexpr std::uint64_t kMaxListCount = 1u << 20;

class PlyReader final : public ReaderBase {
 public:
  explicit PlyReader(const std::string& path) : in_(path) {
    info_.path = path;
    info_.format = Format::ply;
    info_.format_name = "PLY";
    if (in_.size() == 0) in_.fail("empty file");
    parse_header();
    position_at_vertices();
  }

  std::size_t read(PointSet& batch, std::size_t max_points) override {
    batch.clear();
    const auto& ve = elements_[vertex_el_];
    std::uint64_t left = ve.count - points_read_;
    std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(left, max_points));
    if (enc_ == Encoding::ascii) {
      // Never size a batch from an unchecked count: a record needs >= 2 bytes per property.
      const std::uint64_t rest = in_.size() - std::min(in_.size(), in_.tell());
      n = static_cast<std::size_t>(std::min<std::uint64_t>(n, rest / (2 * ve.props.size()) + 1));
    }
    if (n == 0) return 0;
    batch.positions.resize(n);
    if (has_normals_) batch.normals.resize(n);
    if (has_colors_) batch.colors.resize(n);
    if (class_ >= 0) batch.classes.resize(n);
    if (enc_ == Encoding::ascii) {
      for (std::size_t i = 0; i < n; ++i) read_ascii_vertex(batch, i);
    } else {
      const std::size_t chunk_records = std::max<std::size_t>(1, (4u << 20) / ve.stride);
      std::size_t i = 0;
      while (i < n) {
        std::size_t k = std::min(chunk_records, n - i);
        buf_.resize(k * ve.stride);
        std::size_t got = in_.read_some(buf_.data(), buf_.size());
        if (got < buf_.size()) {
          truncated(points_read_ + i + got / ve.stride);
        }
        for (std::size_t r = 0; r < k; ++r)
          decode_binary_vertex(buf_.data() + r * ve.stride, batch, i + r);
        i += k;
      }
    }
    points_read_ += n;
    return n;
  }

  double progress() const override {
    std::uint64_t span = in_.size() > data_start_ ? in_.size() - data_start_ : 1;
    std::uint64_t done = in_.tell() > data_start_ ? in_.tell() - data_start_ : 0;
    return std::min(1.0, static_cast<double>(done) / static_cast<double>(span));
  }

  void check_tail() override {
    while (tail_batch(nullptr, std::size_t(1) << 16) > 0) {
    }
  }

  std::size_t read_faces(FaceBatch* out, std::size_t max_faces) override {
    if (face_el_ < 0) in_.fail("PLY file has no face element (a point cloud, not a mesh)");
    return tail_batch(out, max_faces);
  }

 private:
  void parse_header() {
    std::string line;
    std::vector<std::string_view> tok;
    if (!in_.getline(line, 4096) || line != "ply") {
      in_.fail("not a PLY file (first line is not 'ply')");
    }
    bool have_format = false;
    for (int lines = 0;; ++lines) {
      if (lines > 100000) in_.fail("PLY header too long");
      if (!in_.getline(line, 65536)) in_.fail("truncated: PLY header has no end_header");
      split_tokens(line, tok);
      if (tok.empty()) continue;
      std::string_view kw = tok[0];
      if (kw == "end_header") break;
      if (kw == "comment" || kw == "obj_info") continue;
      if (kw == "format") {
        if (tok.size() < 3) in_.fail("bad PLY format line: '" + line + "'");
        if (tok[1] == "ascii")
          enc_ = Encoding::ascii;
        else if (tok[1] == "binary_little_endian")
          enc_ = Encoding::le;
        else if (tok[1] == "binary_big_endian")
          enc_ = Encoding::be;
        else
          in_.fail("unknown PLY format '" + std::string(tok[1]) + "'");
        info_.encoding = std::string(tok[1]);
        info_.version = std::string(tok[2]);
        have_format = true;
      } else if (kw == "element") {
        PlyElement e;
        if (tok.size() < 3 || !parse_u64(tok[2], e.count))
          in_.fail("bad PLY element line: '" + line + "'");
        e.name = std::string(tok[1]);
        elements_.push_back(std::move(e));
      } else if (kw == "property") {
        if (elements_.empty()) in_.fail("PLY property before any element");
        PlyProp p;
        if (tok.size() >= 5 && tok[1] == "list") {
          p.is_list = true;
          if (!parse_type(std::string(tok[2]), p.count_type) ||
              !parse_type(std::string(tok[3]), p.type) || is_float(p.count_type))
            in_.fail("bad PLY list property: '" + line + "'");
          p.name = std::string(tok[4]);
        } else if (tok.size() >= 3) {
          if (!parse_type(std::string(tok[1]), p.type))
            in_.fail("unknown PLY property type in '" + line + "'");
          p.name = std::string(tok[2]);
        } else {
          in_.fail("bad PLY property line: '" + line + "'");
        }
        elements_.back().props.push_back(std::move(p));
      } else {
        in_.fail("unexpected PLY header line: '" + line + "'");
      }
    }
    if (!have_format) in_.fail("PLY header has no format line");
    data_start_ = in_.tell();
    swap_ = enc_ == Encoding::be;

    for (std::size_t i = 0; i < elements_.size(); ++i) {
      auto& e = elements_[i];
      std::size_t off = 0;
      for (auto& p : e.props) {
        p.offset = off;
        if (p.is_list) {
          e.fixed = false;
          e.min_size += type_size(p.count_type);
        } else {
          off += type_size(p.type);
          e.min_size += type_size(p.type);
        }
      }
      e.stride = off;
      if (e.name == "vertex" && vertex_el_ < 0) vertex_el_ = static_cast<int>(i);
      if (e.name == "face" && face_el_ < 0) face_el_ = static_cast<int>(i);
    }
    if (vertex_el_ < 0) in_.fail("PLY file has no vertex element");
    auto& ve = elements_[vertex_el_];
    if (!ve.fixed) in_.fail("PLY vertex element has a list property (not supported)");
    auto find = [&](std::initializer_list<const char*> names) -> int {
      for (const char* n : names)
        for (std::size_t k = 0; k < ve.props.size(); ++k)
          if (ve.props[k].name == n) return static_cast<int>(k);
      return -1;
    };
    xyz_ = {find({"x"}), find({"y"}), find({"z"})};
    if (xyz_[0] < 0 || xyz_[1] < 0 || xyz_[2] < 0) in_.fail("PLY vertex element lacks x, y or z");
    nrm_ = {find({"nx", "normal_x"}), find({"ny", "normal_y"}), find({"nz", "normal_z"})};
    has_normals_ = nrm_[0] >= 0 && nrm_[1] >= 0 && nrm_[2] >= 0;
    rgb_ = {find({"red", "r", "diffuse_red"}), find({"green", "g", "diffuse_green"}),
            find({"blue", "b", "diffuse_blue"})};
    has_colors_ = rgb_[0] >= 0 && rgb_[1] >= 0 && rgb_[2] >= 0;
    class_ = find({"classification", "class"});
    for (std::size_t k = 0; k < ve.props.size(); ++k) {
      int ik = static_cast<int>(k);
      bool used = std::find(xyz_.begin(), xyz_.end(), ik) != xyz_.end() ||
                  (has_normals_ && std::find(nrm_.begin(), nrm_.end(), ik) != nrm_.end()) ||
                  (has_colors_ && std::find(rgb_.begin(), rgb_.end(), ik) != rgb_.end()) ||
                  ik == class_;
      if (!used) info_.extra_attributes.push_back(ve.props[k].name);
    }
    info_.point_count = ve.count;
    info_.has_normals = has_normals_;
    info_.has_colors = has_colors_;
    info_.has_classes = class_ >= 0;
    if (face_el_ >= 0) {
      auto& fe = elements_[face_el_];
      for (std::size_t k = 0; k < fe.props.size(); ++k)
        if (fe.props[k].is_list &&
            (fe.props[k].name == "vertex_indices" || fe.props[k].name == "vertex_index"))
          face_prop_ = static_cast<int>(k);
      if (face_prop_ < 0)
        in_.fail("PLY face element has no list property vertex_indices/vertex_index");
      if (is_float(fe.props[face_prop_].type)) in_.fail("PLY face indices are floating point");
      if (face_el_ < vertex_el_)
        in_.fail("PLY face element precedes the vertex element (not supported)");
      info_.has_faces = true;
      info_.face_count = fe.count;
    }
  }

  [[noreturn]] void truncated(std::uint64_t holds) {
    in_.fail("truncated: header declares " + std::to_string(elements_[vertex_el_].count) +
             " points but the file holds only " + std::to_string(holds));
  }

  // Skips elements before the vertex element and checks sizes against the file.
  void position_at_vertices() {
    const std::uint64_t remaining = in_.size() - std::min(in_.size(), data_start_);
    if (enc_ != Encoding::ascii) {
      // Lower bound of the bytes the header promises, without overflow.
      std::uint64_t need = 0;
      for (std::size_t i = 0; i < elements_.size(); ++i) {
        const auto& e = elements_[i];
        if (e.min_size && e.count > (remaining - std::min(remaining, need)) / e.min_size) {
          if (static_cast<int>(i) == vertex_el_) {
            truncated((remaining - std::min(remaining, need)) / e.stride);
          }
          if (static_cast<int>(i) < vertex_el_) {
            in_.fail("truncated: header declares " + std::to_string(e.count) + " " + e.name +
                     " records but the file is too short for them");
          }
          in_.fail("truncated: header declares " + std::to_string(e.count) + " " +
                   (static_cast<int>(i) == face_el_ ? "faces" : e.name + " records") +
                   " but the file is too short for them");
        }
        need += e.count * e.min_size;
      }
    }
    for (int i = 0; i < vertex_el_; ++i) skip_element(elements_[i]);
  }

  void skip_element(const PlyElement& e) {
    if (enc_ != Encoding::ascii && e.fixed) {
      in_.seek(in_.tell() + e.count * e.stride);
      return;
    }
    for (std::uint64_t r = 0; r < e.count; ++r) {
      for (const auto& p : e.props) {
        if (p.is_list) {
          std::uint64_t n = read_list_count(p, e, r);
          for (std::uint64_t k = 0; k < n; ++k) read_scalar(p.type, e, r);
        } else {
          read_scalar(p.type, e, r);
        }
      }
    }
  }

  // --- scalar access shared by ascii / binary streaming paths ---
  std::string_view next_token(const PlyElement& e, std::uint64_t record) {
    while (tok_i_ >= toks_.size()) {
      if (!in_.getline(line_)) {
        if (&e == &elements_[vertex_el_]) truncated(record);
        in_.fail("truncated: header declares " + std::to_string(e.count) + " " +
                 (e.name == "face" ? std::string("faces") : e.name + " records") +
                 " but the file holds only " + std::to_string(record));
      }
      split_tokens(line_, toks_);
      tok_i_ = 0;
    }
    return toks_[tok_i_++];
  }

  double read_scalar(PlyType t, const PlyElement& e, std::uint64_t record) {
    if (enc_ == Encoding::ascii) {
      std::string_view s = next_token(e, record);
      double v;
      if (!parse_double(s, v))
        in_.fail("invalid number '" + std::string(s.substr(0, 32)) + "' in " + e.name + " #" +
                 std::to_string(record));
      return v;
    }
    unsigned char b[8];
    std::size_t sz = type_size(t);
    if (in_.read_some(b, sz) != sz) {
      if (&e == &elements_[vertex_el_]) truncated(record);
      in_.fail("truncated: header declares " + std::to_string(e.count) + " " +
               (e.name == "face" ? std::string("faces") : e.name + " records") +
               " but the file holds only " + std::to_string(record));
    }
    return decode(b, t, swap_);
  }

  std::uint64_t read_list_count(const PlyProp& p, const PlyElement& e, std::uint64_t record) {
    double c = read_scalar(p.count_type, e, record);
    if (!(c >= 0) || c > static_cast<double>(kMaxListCount) || c != std::floor(c))
      in_.fail("bad list length " + std::to_string(c) + " in " + e.name + " #" +
               std::to_string(record));
    return static_cast<std::uint64_t>(c);
  }

  void read_ascii_vertex(PointSet& b, std::size_t i) {
    const auto& ve = elements_[vertex_el_];
    const std::uint64_t rec = points_read_ + i;
    if (vals_.size() < ve.props.size()) vals_.resize(ve.props.size());
    for (std::size_t k = 0; k < ve.props.size(); ++k)
      vals_[k] = read_scalar(ve.props[k].type, ve, rec);
    store(b, i, rec, [&](int k) { return vals_[static_cast<std::size_t>(k)]; });
  }

  void decode_binary_vertex(const unsigned char* rec, PointSet& b, std::size_t i) {
    const auto& ve = elements_[vertex_el_];
    store(b, i, points_read_ + i, [&](int k) {
      const auto& p = ve.props[static_cast<std::size_t>(k)];
      return decode(rec + p.offset, p.type, swap_);
    });
  }

  template <typename Get>
  void store(PointSet& b, std::size_t i, std::uint64_t rec, Get get) {
    const auto& ve = elements_[vertex_el_];
    auto& pos = b.positions[i];
    for (int a = 0; a < 3; ++a) pos[a] = get(xyz_[a]);
    std::string bad = check_finite(pos.data(), rec);
    if (!bad.empty()) in_.fail(bad);
    if (has_normals_)
      for (int a = 0; a < 3; ++a) b.normals[i][a] = static_cast<float>(get(nrm_[a]));
    if (has_colors_)
      for (int a = 0; a < 3; ++a) {
        const auto& p = ve.props[static_cast<std::size_t>(rgb_[a])];
        double v = get(rgb_[a]);
        if (p.type == PlyType::u16 || p.type == PlyType::i16) v = v / 257.0;
        b.colors[i][a] = color_to_u8(v, is_float(p.type));
      }
    if (class_ >= 0) {
      double c = get(class_);
      b.classes[i] = static_cast<std::uint8_t>(c >= 0 && c <= 255 ? c : 0);
    }
  }

  // The elements after the vertex element, in steps: the first call reads the rest of the
  // vertices and skips the elements before the faces; each call then reads up to
  // `max_faces` faces (validated; stored in `out` unless null); after the last face the
  // elements behind it are skipped and trailing data refused. Returns the faces read, 0 at
  // the end.
  std::size_t tail_batch(FaceBatch* out, std::size_t max_faces) {
    if (out) out->clear();
    if (tail_done_) return 0;
    if (!tail_started_) {
      tail_started_ = true;
      if (points_read_ != elements_[vertex_el_].count) {
        PointSet sink;
        while (read(sink, 1 << 16) > 0) {
        }
      }
      const int stop = face_el_ >= 0 ? face_el_ : static_cast<int>(elements_.size());
      for (int i = vertex_el_ + 1; i < stop; ++i) skip_element(elements_[std::size_t(i)]);
    }
    std::size_t got = 0;
    if (face_el_ >= 0) {
      const auto& e = elements_[std::size_t(face_el_)];
      const std::uint64_t nv = elements_[vertex_el_].count;
      for (; face_next_ < e.count && got < max_faces; ++face_next_, ++got) {
        const std::uint64_t r = face_next_;
        for (std::size_t k = 0; k < e.props.size(); ++k) {
          const auto& p = e.props[k];
          if (!p.is_list) {
            read_scalar(p.type, e, r);
            continue;
          }
          std::uint64_t n = read_list_count(p, e, r);
          if (static_cast<int>(k) != face_prop_) {
            for (std::uint64_t j = 0; j < n; ++j) read_scalar(p.type, e, r);
            continue;
          }
          if (n > info_.max_face_corners) info_.max_face_corners = static_cast<std::uint32_t>(n);
          for (std::uint64_t j = 0; j < n; ++j) {
            double v = read_scalar(p.type, e, r);
            if (!(v >= 0) || v >= static_cast<double>(nv) || v != std::floor(v))
              in_.fail(bad_index_message(r, static_cast<std::int64_t>(v), nv));
            if (out) out->corners.push_back(static_cast<std::uint32_t>(v));
          }
          if (out) out->offsets.push_back(out->corners.size());
        }
      }
      if (face_next_ < e.count) return got;
      for (std::size_t i = std::size_t(face_el_) + 1; i < elements_.size(); ++i)
        skip_element(elements_[i]);
    }
    tail_done_ = true;
    // Trailing data: the header's counts understate the file.
    if (enc_ == Encoding::ascii) {
      if (tok_i_ < toks_.size())
        in_.fail("trailing data after the elements the header declares (header counts lie)");
      std::string l;
      std::vector<std::string_view> t;
      while (in_.getline(l))
        if (split_tokens(l, t) > 0)
          in_.fail("trailing data after the elements the header declares (header counts lie)");
    } else {
      std::uint64_t extra = in_.size() - std::min(in_.size(), in_.tell());
      const auto& last = elements_.back();
      std::size_t tolerance = std::max<std::size_t>(last.min_size, 2);
      if (extra >= tolerance)
        in_.fail("trailing data: " + std::to_string(extra) +
                 " bytes after the elements the header declares (header counts lie)");
    }
    return got;
  }

  InputFile in_;
  std::vector<PlyElement> elements_;
  Encoding enc_ = Encoding::ascii;
  bool swap_ = false;
  std::uint64_t data_start_ = 0;
  int vertex_el_ = -1, face_el_ = -1, face_prop_ = -1;
  std::array<int, 3> xyz_{}, nrm_{}, rgb_{};
  bool has_normals_ = false, has_colors_ = false;
  int class_ = -1;
  bool tail_started_ = false, tail_done_ = false;
  std::uint64_t face_next_ = 0;
  std::vector<unsigned char> buf_;
  std::vector<double> vals_;
  std::string line_;
  std::vector<std::string_view> toks_;
  std::size_t tok_i_ = 0;
};

}  // namespace

std::unique_ptr<ReaderBase> open_ply(const std::string& path) {
  return std::make_unique<PlyReader>(path);
}

}  // namespace citylod::io::detail
