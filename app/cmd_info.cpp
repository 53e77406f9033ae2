// `citylod info FILE...`: what a point cloud or mesh file holds.
#include <cstdio>
#include <nlohmann/json.hpp>

#include "citylod/io/reader.hpp"
#include "citylod/io/verify.hpp"
#include "cli.hpp"

namespace citylod::app {
namespace {

std::string fmt(const char* f, double v) {
  if (v == 0) v = 0;  // no "-0"
  char b[64];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

std::string vec(const io::Vec3d& v, const char* f) {
  return fmt(f, v[0]) + " " + fmt(f, v[1]) + " " + fmt(f, v[2]);
}

std::vector<std::string> attributes(const io::FileInfo& i) {
  std::vector<std::string> a;
  if (i.has_normals) a.push_back("normals");
  if (i.has_colors) a.push_back("colors");
  if (i.has_classes) a.push_back("classification");
  return a;
}

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

std::string unit_text(const io::FileInfo& i) {
  std::string u = i.linear_unit;
  if (u == "foot") u += " (international foot)";
  if (i.linear_unit_m > 0) u += ", " + fmt("%.10g", i.linear_unit_m) + " m";
  return u;
}

void print_text(const io::FileInfo& i) {
  auto row = [](const char* k, const std::string& v) { std::printf("  %-15s %s\n", k, v.c_str()); };
  std::printf("%s\n", i.path.c_str());
  std::string format = i.format_name;
  if (!i.version.empty()) format += " " + i.version;
  if (!i.encoding.empty()) format += " (" + i.encoding + ")";
  row("format:", format);
  if (i.compressed) row("compressed:", "LASzip");
  if (i.las_point_format >= 0)
    row("point format:", std::to_string(i.las_point_format) + " (" +
                             std::to_string(i.las_record_length) + " bytes per point)");
  row(i.has_faces ? "vertices:" : "points:", std::to_string(i.point_count));
  if (i.has_faces) row("faces:", std::to_string(i.face_count));
  if (!i.bbox.empty()) {
    const char* src = i.bbox_from_header ? " (from header)" : "";
    row("bbox min:", vec(i.bbox.min, "%.3f") + src);
    row("bbox max:", vec(i.bbox.max, "%.3f") + src);
    io::Vec3d ext{i.bbox.max[0] - i.bbox.min[0], i.bbox.max[1] - i.bbox.min[1],
                  i.bbox.max[2] - i.bbox.min[2]};
    row("extent:", vec(ext, "%.3f"));
  }
  auto attrs = attributes(i);
  row("attributes:", attrs.empty() ? "none (positions only)" : join(attrs));
  if (!i.extra_attributes.empty()) row("other fields:", join(i.extra_attributes));
  if (i.las_point_format >= 0) {
    row("scale:", vec(i.scale, "%g"));
    row("offset:", vec(i.offset, "%.10g"));
  }
  if (!i.class_counts.empty()) {
    std::printf("  classes:\n");
    for (const auto& [code, n] : i.class_counts) {
      double pct =
          i.point_count ? 100.0 * static_cast<double>(n) / static_cast<double>(i.point_count) : 0;
      const char* name = io::las_class_name(code);
      std::printf("    %3d %-22s %10llu  %5.1f%%\n", code, *name ? name : "(unassigned)",
                  static_cast<unsigned long long>(n), pct);
    }
  }
  if (i.las_point_format >= 0 || i.has_crs()) {
    if (!i.has_crs()) {
      row("crs:", "none in file");
    } else {
      std::string c = i.crs_name.empty() ? "(unnamed)" : i.crs_name;
      if (i.epsg) c += " (EPSG:" + std::to_string(i.epsg) + ")";
      row("crs:", c);
      if (i.vertical_epsg) row("vertical crs:", "EPSG:" + std::to_string(i.vertical_epsg));
      if (!i.linear_unit.empty()) row("linear unit:", unit_text(i));
      if (!i.vertical_unit.empty()) row("vertical unit:", i.vertical_unit);
      if (!i.crs_wkt.empty())
        row("wkt:", i.crs_wkt.size() > 60 ? i.crs_wkt.substr(0, 57) + "..." : i.crs_wkt);
    }
  }
  if (!i.system_id.empty()) row("system id:", i.system_id);
  if (!i.generating_software.empty()) row("software:", i.generating_software);
}

nlohmann::json to_json(const io::FileInfo& i) {
  nlohmann::json j;
  j["path"] = i.path;
  j["format"] = i.format_name;
  j["version"] = i.version;
  j["encoding"] = i.encoding;
  j["point_count"] = i.point_count;
  j["face_count"] = i.face_count;
  j["has_faces"] = i.has_faces;
  j["scanned"] = i.scanned;
  if (!i.bbox.empty()) {
    j["bbox"] = {{"min", i.bbox.min}, {"max", i.bbox.max}, {"from_header", i.bbox_from_header}};
  }
  j["attributes"] = attributes(i);
  j["other_fields"] = i.extra_attributes;
  j["compressed"] = i.compressed;
  if (i.las_point_format >= 0) {
    j["las"] = {{"point_format", i.las_point_format},
                {"record_length", i.las_record_length},
                {"scale", i.scale},
                {"offset", i.offset},
                {"system_id", i.system_id},
                {"generating_software", i.generating_software}};
    nlohmann::json classes = nlohmann::json::array();
    for (const auto& [code, n] : i.class_counts)
      classes.push_back({{"code", code}, {"name", io::las_class_name(code)}, {"count", n}});
    j["classes"] = classes;
  }
  if (i.has_crs()) {
    nlohmann::json c;
    c["name"] = i.crs_name;
    c["epsg"] = i.epsg ? nlohmann::json(i.epsg) : nlohmann::json(nullptr);
    c["vertical_epsg"] =
        i.vertical_epsg ? nlohmann::json(i.vertical_epsg) : nlohmann::json(nullptr);
    c["linear_unit"] = i.linear_unit;
    c["linear_unit_m"] = i.linear_unit_m;
    c["vertical_unit"] = i.vertical_unit;
    c["wkt"] = i.crs_wkt;
    j["crs"] = c;
  } else {
    j["crs"] = nullptr;
  }
  return j;
}

}  // namespace

int cmd_info(ArgParser& args) {
  args.usage("FILE...")
      .describe(
          "Streams each file (bounded memory) and prints its format, point/vertex and face counts, "
          "bounding box,\n"
          "attributes, LAS point format, scale/offset, class counts and CRS. Formats: PLY, OBJ, "
          "OFF, XYZ/PTS,\n"
          "LAS 1.0-1.4, LAZ and COPC.")
      .flag("json", 'j', "print JSON (one object, or an array for several files)")
      .flag("header-only", 0, "read only the header: no streaming, bbox and counts as declared")
      .flag("verify", 0,
            "LAS/LAZ: decode every point record and print their count, the bbox of the decoded "
            "coordinates and the SHA-256 of the records (LAS record layout, file order)")
      .positional("FILE", "point cloud or mesh file(s)", Arity::one_or_more);
  if (!args.parse()) return 0;
  const bool json = args.has("json");
  nlohmann::json all = nlohmann::json::array();
  int failures = 0;
  bool first = true;
  for (const auto& path : args.positionals()) {
    try {
      io::FileInfo info;
      if (args.has("header-only")) {
        info = io::read_header(path);
      } else {
        Progress progress("scanning " + path);
        info = io::scan_file(path, &Progress::callback, &progress);
        progress.finish();
      }
      io::PointRecordDigest d;
      const bool verify = args.has("verify");
      if (verify) {
        Progress progress("verifying " + path);
        d = io::verify_point_records(path, &Progress::callback, &progress);
        progress.finish();
      }
      if (json) {
        all.push_back(to_json(info));
        if (verify)
          all.back()["verify"] = {{"records", d.count},
                                  {"bbox_min", d.bbox.min},
                                  {"bbox_max", d.bbox.max},
                                  {"sha256", d.sha256}};
      } else {
        if (!first) std::printf("\n");
        print_text(info);
        if (verify) {
          std::printf("  %-15s %llu\n",
                      "verify records:", static_cast<unsigned long long>(d.count));
          std::printf("  %-15s %s\n", "verify min:", vec(d.bbox.min, "%.3f").c_str());
          std::printf("  %-15s %s\n", "verify max:", vec(d.bbox.max, "%.3f").c_str());
          std::printf("  %-15s %s\n", "sha256:", d.sha256.c_str());
        }
        std::fflush(stdout);
      }
      first = false;
    } catch (const io::IoError& e) {
      log_error(e.what());
      ++failures;
    }
  }
  if (json && !all.empty())
    std::printf("%s\n", (args.positionals().size() == 1 ? all[0] : all).dump(2).c_str());
  return failures ? 1 : 0;
}

}  // namespace citylod::app
