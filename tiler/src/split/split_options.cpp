// `citylod split`'s options: --memory-limit sizes, SplitOptions::validate() and the
// canonical text of the options that the manifest records (the up-to-date check).
#include <cctype>
#include <cmath>
#include <locale>
#include <regex>
#include <sstream>
#include <stdexcept>

#include "citylod/tiler/option_names.hpp"
#include "split_internal.hpp"

namespace citylod::tiler {

namespace split_detail {

/// "X,Y[,Z]" (commas or blanks) -> numbers; nullopt when malformed or not finite.
std::optional<io::Vec3d> parse_triple(const std::string& s) {
  std::string t = s;
  for (auto& c : t)
    if (c == ',') c = ' ';
  std::istringstream in(t);
  in.imbue(std::locale::classic());
  io::Vec3d v{0, 0, 0};
  int n = 0;
  double d;
  while (in >> d) {
    if (n == 3 || !std::isfinite(d)) return std::nullopt;
    v[std::size_t(n++)] = d;
  }
  if (!in.eof() || n < 2) return std::nullopt;
  return v;
}

}  // namespace split_detail

using split_detail::parse_triple;

std::uint64_t parse_memory_size(const std::string& s) {
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(s, &used);
  } catch (const std::exception&) {
    throw std::invalid_argument(option_name("memory_limit") + ": '" + s +
                                "' is not a size (e.g. 2G, 512M)");
  }
  std::string unit = s.substr(used);
  for (auto& c : unit) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  double mul = 1;
  if (unit.empty() || unit == "B")
    mul = 1;
  else if (unit == "K" || unit == "KB" || unit == "KIB")
    mul = 1024.0;
  else if (unit == "M" || unit == "MB" || unit == "MIB")
    mul = 1024.0 * 1024;
  else if (unit == "G" || unit == "GB" || unit == "GIB")
    mul = 1024.0 * 1024 * 1024;
  else if (unit == "T" || unit == "TB" || unit == "TIB")
    mul = 1024.0 * 1024 * 1024 * 1024;
  else
    throw std::invalid_argument(option_name("memory_limit") + ": unknown unit '" + unit + "' in '" +
                                s + "'");
  if (!(v > 0) || !std::isfinite(v))
    throw std::invalid_argument(option_name("memory_limit") + ": must be positive");
  // 2^64 bytes and more do not fit the count (the conversion would wrap round)
  if (!(v * mul < 18446744073709551616.0))
    throw std::invalid_argument(option_name("memory_limit") + ": '" + s +
                                "' is more than the largest size there is (16E = 2^64 bytes)");
  return static_cast<std::uint64_t>(v * mul);
}

SplitOptions::Geoid parse_geoid(const std::string& word) {
  if (word.empty()) return SplitOptions::Geoid::none;
  if (word == to_string(SplitOptions::Geoid::egm96)) return SplitOptions::Geoid::egm96;
  throw std::invalid_argument(option_name("geoid") + ": only 'egm96' is supported, got '" + word +
                              "'");
}

const char* to_string(SplitOptions::Geoid g) {
  return g == SplitOptions::Geoid::egm96 ? "egm96" : "";
}

geo::VerticalMode parse_vertical(const std::string& word) {
  for (geo::VerticalMode m :
       {geo::VerticalMode::Auto, geo::VerticalMode::Ellipsoidal, geo::VerticalMode::Orthometric})
    if (word == geo::to_string(m)) return m;
  if (word.empty()) return geo::VerticalMode::Auto;
  throw std::invalid_argument(option_name("vertical") +
                              ": expected auto, ellipsoidal or orthometric, got '" + word + "'");
}

void SplitOptions::validate() const {
  auto positive = [](double v, const std::string& name) {
    if (!(v > 0) || !std::isfinite(v))
      throw std::invalid_argument(name + " must be a positive number");
  };
  const auto crs_name = option_name("crs"), origin_name = option_name("origin");
  if (inputs.empty()) throw std::invalid_argument("no input file");
  if (work_dir.empty()) throw std::invalid_argument(option_name("work_dir") + " WORK is required");
  if (!crs.empty() && !origin.empty())
    throw std::invalid_argument(crs_name + " and " + origin_name + " exclude each other (" +
                                origin_name + " is for data in a local metric frame)");
  if (geoid != Geoid::none && !origin.empty())
    throw std::invalid_argument(option_name("geoid") + " needs a CRS; with " + origin_name +
                                " heights are relative to the given ellipsoidal H");
  if (vertical != geo::VerticalMode::Auto && !origin.empty())
    throw std::invalid_argument(option_name("vertical") + " needs a CRS; with " + origin_name +
                                " heights are relative to the given ellipsoidal H");
  if (geoid != Geoid::none && vertical == geo::VerticalMode::Ellipsoidal)
    throw std::invalid_argument(option_name("geoid") + " egm96 (orthometric heights) contradicts " +
                                option_name("vertical") + " ellipsoidal");
  if (footprints.empty() && (!footprints_layer.empty() || !footprints_id.empty()))
    throw std::invalid_argument(option_name("footprints_layer") + " / " +
                                option_name("footprints_id") + " need " +
                                option_name("footprints"));
  if (!offset.empty() && !parse_triple(offset))
    throw std::invalid_argument(option_name("offset") + ": expected X,Y or X,Y,Z (numbers), got '" +
                                offset + "'");
  positive(cell_size, option_name("cell_size"));
  positive(halo, option_name("halo"));
  positive(seg.cluster_tolerance, option_name("cluster_tolerance"));
  positive(seg.dtm_resolution, "the DTM resolution");
  if (max_halo < halo)
    throw std::invalid_argument(option_name("max_halo") + " must be >= " + option_name("halo"));
  if (footprint_buffer < 0)
    throw std::invalid_argument(option_name("footprint_buffer") + " must be >= 0");
  if (memory_limit < (64ull << 20))
    throw std::invalid_argument(option_name("memory_limit") + " must be at least 64M");
  if (seg.min_height < 0) throw std::invalid_argument(option_name("min_height") + " must be >= 0");
  if (seg.min_area < 0) throw std::invalid_argument(option_name("min_area") + " must be >= 0");
}

std::string SplitOptions::canonical() const {
  std::ostringstream o;
  o.precision(17);
  // a "PG:" connection string's password stays out of the manifest
  static const std::regex pw(R"((password\s*=\s*)('[^']*'|\S+))", std::regex::icase);
  o << "v=3;crs=" << crs << ";origin=" << origin << ";geoid=" << to_string(geoid)
    << ";footprints=" << std::regex_replace(footprints, pw, "$1***")
    << ";footprint_buffer=" << footprint_buffer << ";memory_limit=" << memory_limit
    << ";cell=" << cell_size << ";halo=" << halo << ";max_halo=" << max_halo
    << ";ignore_classes=" << ignore_classes << ";min_footprint_points=" << min_footprint_points
    << ";dtm_res=" << seg.dtm_resolution << ";dtm_window=" << seg.dtm_window
    << ";ground_tol=" << seg.ground_tolerance << ";min_height=" << seg.min_height
    << ";tol=" << seg.cluster_tolerance << ";min_pts=" << seg.min_cluster_points
    << ";min_area=" << seg.min_area << ";min_bh=" << seg.min_building_height
    << ";k=" << seg.feature_neighbours << ";max_scatter=" << seg.max_scatter
    << ";max_veg=" << seg.max_vegetation_ratio << ";min_planar=" << seg.min_planar_fraction
    << ";min_width=" << seg.min_width << ";low=" << seg.low_height << ","
    << seg.low_max_vegetation_ratio << "," << seg.low_min_planar_fraction;
  // v=2: heights follow the CRS by default (RD New -> NAP); v=1 work directories split again
  o << ";vertical=" << geo::to_string(vertical) << ";footprints_layer=" << footprints_layer
    << ";footprints_id=" << footprints_id
    << ";unmatched=" << (unmatched == Unmatched::segment ? "segment" : "drop");
  if (!offset.empty()) o << ";offset=" << offset;
  return o.str();
}

}  // namespace citylod::tiler
