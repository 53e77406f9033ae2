// OFF reader: OFF / NOFF / COFF / CNOFF / NCOFF (ascii). Vertex lines are
// "x y z [nx ny nz] [r g b [a]]", faces "n i1 ... in [colour]". '#' comments.
#include <algorithm>
#include <cmath>

#include "readers_internal.hpp"

namespace citylod::io::detail {
namespace {

class OffReader final : public ReaderBase {
 public:
  explicit OffReader(const std::string& path) : in_(path) {
    info_.path = path;
    info_.format = Format::off;
    info_.format_name = "OFF";
    info_.encoding = "ascii";
    if (in_.size() == 0) in_.fail("empty file");
    std::string first;
    if (!next_line(first)) in_.fail("empty file");
    split_tokens(first, tok_);
    std::string kw = tok_.empty() ? std::string() : std::string(tok_[0]);
    std::size_t p = kw.find("OFF");
    if (p == std::string::npos || p + 3 != kw.size()) in_.fail("not an OFF file (no OFF keyword)");
    std::string prefix = kw.substr(0, p);
    for (char c : prefix) {
      if (c == 'N')
        normals_ = true;
      else if (c == 'C')
        colors_ = true;
      else if (c == 'S' && prefix.find("ST") != std::string::npos)
        texcoords_ = true;
      else if (c == 'T') {
      } else
        in_.fail("unsupported OFF variant '" + kw + "'");
    }
    if (kw != "OFF") info_.version = kw;  // variant: NOFF, COFF, ...
    std::vector<std::string_view> counts(tok_.begin() + 1, tok_.end());
    if (!counts.empty() && counts[0] == "BINARY") in_.fail("binary OFF is not supported");
    std::string line;
    if (counts.empty()) {
      if (!next_line(line)) in_.fail("truncated: OFF header has no vertex/face counts");
      split_tokens(line, counts);
    }
    std::uint64_t nv = 0, nf = 0;
    if (counts.size() < 2 || !parse_u64(counts[0], nv) || !parse_u64(counts[1], nf))
      in_.fail("bad OFF counts line (expected 'nvertices nfaces nedges')");
    // No allocation depends on these counts: records are streamed and a
    // short file is reported with the number of records it really holds.
    info_.point_count = nv;
    info_.face_count = nf;
    info_.has_faces = nf > 0;
    info_.has_normals = normals_;
    info_.has_colors = colors_;
    data_start_ = in_.tell();
  }

  std::size_t read(PointSet& b, std::size_t max_points) override {
    b.clear();
    std::size_t n = static_cast<std::size_t>(
        std::min<std::uint64_t>(info_.point_count - points_read_, max_points));
    std::string line;
    for (std::size_t i = 0; i < n; ++i) {
      std::uint64_t idx = points_read_ + i;
      if (!next_line(line)) truncated_vertices(info_.point_count, idx);
      split_tokens(line, tok_);
      std::size_t need = 3 + (normals_ ? 3 : 0) + (colors_ ? 3 : 0);
      if (tok_.size() < need) in_.fail("vertex #" + std::to_string(idx) + " has too few values");
      double v[10];
      for (std::size_t k = 0; k < need; ++k)
        if (!parse_double(tok_[k], v[k]))
          in_.fail("invalid number '" + std::string(tok_[k].substr(0, 32)) + "' in vertex #" +
                   std::to_string(idx));
      Vec3d p{v[0], v[1], v[2]};
      std::string bad = check_finite(p.data(), idx);
      if (!bad.empty()) in_.fail(bad);
      b.positions.push_back(p);
      std::size_t c = 3;
      if (normals_) {
        b.normals.push_back(
            {static_cast<float>(v[3]), static_cast<float>(v[4]), static_cast<float>(v[5])});
        c = 6;
      }
      if (colors_) {
        bool is_float = false;
        for (std::size_t k = c; k < c + 3; ++k)
          if (tok_[k].find('.') != std::string_view::npos) is_float = true;
        b.colors.push_back({color_to_u8(v[c], is_float), color_to_u8(v[c + 1], is_float),
                            color_to_u8(v[c + 2], is_float)});
      }
    }
    points_read_ += n;
    return n;
  }

  double progress() const override {
    std::uint64_t span = in_.size() > data_start_ ? in_.size() - data_start_ : 1;
    return std::min(1.0, static_cast<double>(in_.tell() - std::min(in_.tell(), data_start_)) /
                             static_cast<double>(span));
  }

  void check_tail() override {
    while (faces(nullptr, std::size_t(1) << 16) > 0) {
    }
  }
  std::size_t read_faces(FaceBatch* out, std::size_t max_faces) override {
    if (info_.face_count == 0) in_.fail("OFF file has no faces (a point cloud, not a mesh)");
    return faces(out, max_faces);
  }

 private:
  // Next non-empty, non-comment line.
  bool next_line(std::string& line) {
    while (in_.getline(line)) {
      auto h = line.find('#');
      if (h != std::string::npos) line.resize(h);
      if (line.find_first_not_of(" \t\r\f\v") != std::string::npos) return true;
    }
    return false;
  }

  [[noreturn]] void truncated_vertices(std::uint64_t declared, std::uint64_t holds) {
    in_.fail("truncated: header declares " + std::to_string(declared) +
             " points but the file holds only " + std::to_string(holds));
  }

  // The next up to `max_faces` faces (validated; stored in `out` unless null), after the
  // rest of the vertices. Returns how many, 0 at the end.
  std::size_t faces(FaceBatch* out, std::size_t max_faces) {
    if (out) out->clear();
    PointSet sink;
    while (read(sink, 1 << 16) > 0) {
    }
    const std::uint64_t nv = info_.point_count;
    std::string line;
    std::size_t got = 0;
    for (; face_next_ < info_.face_count && got < max_faces; ++face_next_, ++got) {
      const std::uint64_t f = face_next_;
      if (!next_line(line))
        in_.fail("truncated: header declares " + std::to_string(info_.face_count) +
                 " faces but the file holds only " + std::to_string(f));
      split_tokens(line, tok_);
      std::uint64_t n = 0;
      if (tok_.empty() || !parse_u64(tok_[0], n) || n + 1 > tok_.size())
        in_.fail("bad face #" + std::to_string(f) + ": '" + line.substr(0, 60) + "'");
      if (n > info_.max_face_corners) info_.max_face_corners = static_cast<std::uint32_t>(n);
      for (std::uint64_t k = 1; k <= n; ++k) {
        std::int64_t idx;
        if (!parse_i64(tok_[k], idx)) in_.fail("bad vertex index in face #" + std::to_string(f));
        if (idx < 0 || static_cast<std::uint64_t>(idx) >= nv)
          in_.fail(bad_index_message(f, idx, nv));
        if (out) out->corners.push_back(static_cast<std::uint32_t>(idx));
      }
      if (out) out->offsets.push_back(out->corners.size());
    }
    return got;
  }

  InputFile in_;
  bool normals_ = false, colors_ = false, texcoords_ = false;
  std::uint64_t data_start_ = 0, face_next_ = 0;
  std::vector<std::string_view> tok_;
};

}  // namespace

std::unique_ptr<ReaderBase> open_off(const std::string& path) {
  return std::make_unique<OffReader>(path);
}

}  // namespace citylod::io::detail
