// XYZ / PTS / CSV text point clouds: one point per line, whitespace or comma
// separated: "x y z", "x y z nx ny nz", "x y z r g b", "x y z i" (PTS
// intensity), "x y z i r g b" (Leica PTS), "x y z r g b nx ny nz" or
// "x y z nx ny nz r g b". A line with a single integer is a PTS point count.
// '#' and '//' lines are comments; one non-numeric header line is skipped.
#include <algorithm>
#include <cmath>

#include "readers_internal.hpp"

namespace citylod::io::detail {
namespace {

bool is_comment(std::string_view l) {
  auto p = l.find_first_not_of(" \t");
  if (p == std::string_view::npos) return true;
  return l[p] == '#' || l.substr(p, 2) == "//";
}

bool all_numeric(const std::vector<std::string_view>& tok) {
  double d;
  for (auto t : tok)
    if (!parse_double(t, d)) return false;
  return !tok.empty();
}

bool colour_like(const std::vector<std::vector<double>>& rows, std::size_t c) {
  bool any_big = false;
  for (const auto& r : rows) {
    if (r.size() < c + 3) return false;
    for (std::size_t k = c; k < c + 3; ++k) {
      if (r[k] < 0 || r[k] > 255 || r[k] != std::floor(r[k])) return false;
      if (r[k] > 1) any_big = true;
    }
  }
  return any_big;
}

class XyzReader final : public ReaderBase {
 public:
  explicit XyzReader(const std::string& path) : in_(path) {
    info_.path = path;
    info_.format = Format::xyz;
    info_.format_name = extension_of(path) == "pts" ? "PTS" : "XYZ";
    info_.encoding = "ascii";
    if (in_.size() == 0) in_.fail("empty file");
    detect_layout();
    in_.seek(0);
  }

  std::size_t read(PointSet& b, std::size_t max_points) override {
    b.clear();
    std::string line;
    while (b.positions.size() < max_points && in_.getline(line)) {
      ++line_no_;
      if (line_no_ == header_line_ || is_comment(line)) continue;
      split_tokens(line, tok_);
      if (tok_.empty()) continue;
      std::uint64_t idx = points_read_ + b.positions.size();
      if (tok_.size() == 1) {
        std::uint64_t n;
        if (!parse_u64(tok_[0], n))
          in_.fail("bad line " + std::to_string(line_no_) + ": '" + line.substr(0, 60) + "'");
        declared_ += n;
        has_declared_ = true;
        continue;
      }
      if (tok_.size() < min_cols_)
        in_.fail("line " + std::to_string(line_no_) + ": expected " + std::to_string(min_cols_) +
                 " values, found " + std::to_string(tok_.size()));
      for (std::size_t k = 0; k < min_cols_; ++k)
        if (!parse_double(tok_[k], v_[k]))
          in_.fail("invalid number '" + std::string(tok_[k].substr(0, 32)) + "' at line " +
                   std::to_string(line_no_));
      Vec3d p{v_[0], v_[1], v_[2]};
      std::string bad = check_finite(p.data(), idx);
      if (!bad.empty()) in_.fail(bad);
      b.positions.push_back(p);
      if (nrm_ >= 0)
        b.normals.push_back({static_cast<float>(v_[nrm_]), static_cast<float>(v_[nrm_ + 1]),
                             static_cast<float>(v_[nrm_ + 2])});
      if (rgb_ >= 0)
        b.colors.push_back({color_to_u8(v_[rgb_], false), color_to_u8(v_[rgb_ + 1], false),
                            color_to_u8(v_[rgb_ + 2], false)});
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

 private:
  void detect_layout() {
    std::string line;
    std::vector<std::vector<double>> rows;
    std::uint64_t no = 0;
    std::size_t cols = 0;
    while (rows.size() < 256 && in_.getline(line, 65536)) {
      ++no;
      if (is_comment(line)) continue;
      split_tokens(line, tok_);
      if (tok_.empty()) continue;
      if (!all_numeric(tok_)) {
        if (rows.empty() && header_line_ == 0 && tok_.size() >= 3) {
          header_line_ = no;  // e.g. "X,Y,Z,R,G,B"
          continue;
        }
        if (rows.empty()) in_.fail("not a point cloud or mesh file (unrecognised format)");
        continue;  // reported with its line number when streaming reaches it
      }
      if (tok_.size() == 1) continue;  // PTS count
      if (tok_.size() < 3) continue;   // reported when streaming reaches it
      if (cols == 0) cols = tok_.size();
      std::vector<double> r(tok_.size());
      for (std::size_t k = 0; k < tok_.size(); ++k) parse_double(tok_[k], r[k]);
      rows.push_back(std::move(r));
    }
    if (rows.empty()) in_.fail("no points with x y z values (not a point cloud?)");
    min_cols_ = 3;
    if (cols == 6) {
      if (colour_like(rows, 3))
        rgb_ = 3;
      else
        nrm_ = 3;
      min_cols_ = 6;
    } else if (cols == 7) {
      if (colour_like(rows, 4)) rgb_ = 4;  // x y z intensity r g b
      min_cols_ = 7;
    } else if (cols >= 9) {
      if (colour_like(rows, 3)) {
        rgb_ = 3;
        nrm_ = 6;
      } else {
        nrm_ = 3;
        if (colour_like(rows, 6)) rgb_ = 6;
      }
      min_cols_ = 9;
    }
    if (cols == 4 || cols == 7) info_.extra_attributes.push_back("intensity");
    info_.has_normals = nrm_ >= 0;
    info_.has_colors = rgb_ >= 0;
  }

  void finish() {
    if (finished_) return;
    finished_ = true;
    if (has_declared_ && declared_ != points_read_) {
      if (declared_ > points_read_)
        in_.fail("truncated: header declares " + std::to_string(declared_) +
                 " points but the file holds only " + std::to_string(points_read_));
      in_.fail("header declares " + std::to_string(declared_) + " points but the file holds " +
               std::to_string(points_read_));
    }
    info_.point_count = points_read_;
  }

  InputFile in_;
  std::vector<std::string_view> tok_;
  std::uint64_t line_no_ = 0, header_line_ = 0, declared_ = 0;
  bool has_declared_ = false, finished_ = false;
  std::size_t min_cols_ = 3;
  int nrm_ = -1, rgb_ = -1;
  double v_[16] = {};
};

}  // namespace

std::unique_ptr<ReaderBase> open_xyz(const std::string& path) {
  return std::make_unique<XyzReader>(path);
}

}  // namespace citylod::io::detail
