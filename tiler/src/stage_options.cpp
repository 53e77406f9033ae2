// The shared option declarations / parsing of the split, lod and assemble
// stages (see stage_options.hpp).
#include "stage_options.hpp"

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "citylod/io/atomic_file.hpp"
#include "citylod/io/workdir.hpp"
#include "lod_stage.hpp"

#include <chrono>
#include <filesystem>
#include <set>

namespace citylod::tiler {

namespace {
std::string num(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return std::string(b);
}
}  // namespace

// ------------------------------------------------------------ split
void declare_split_options(ArgParser& args) {
  const SplitOptions d;
  args.option("crs", 0, "CRS", "CRS of the input: EPSG:nnnn, WKT or PROJ string (default: from the LAS file)")
      .option("origin", 0, "LAT,LON,H", "data in local ENU metres at this origin (degrees, ellipsoidal m)")
      .option("geoid", 0, "MODEL", "input heights are orthometric on MODEL (egm96)")
      .option("footprints", 0, "FILE", "building footprints (GeoJSON Polygon/MultiPolygon with an id property)")
      .option("footprint-buffer", 0, "M", "points this close outside a footprint belong to it",
              num(d.footprint_buffer))
      .option("memory-limit", 'm', "SIZE", "memory budget, e.g. 512M, 2G", "2G")
      .option("cell-size", 0, "M", "grid cell size", num(d.cell_size))
      .option("halo", 0, "M", "margin loaded around each cell", num(d.halo))
      .option("max-halo", 0, "M", "halo growth limit for buildings larger than the halo", num(d.max_halo))
      .option("min-height", 0, "M", "building points lie this high above the ground", num(d.seg.min_height))
      .option("min-area", 0, "M2", "smaller clusters are not buildings", num(d.seg.min_area))
      .option("cluster-tolerance", 0, "M", "clustering distance", num(d.seg.cluster_tolerance))
      .option("dtm-window", 0, "M", "ground filter window (without a ground class)", num(d.seg.dtm_window))
      .flag("ignore-classes", 0, "segment as if the input had no LAS classes");
}

SplitOptions parse_split_options(const ArgParser& args, const std::vector<std::string>& inputs,
                                 const std::string& work_dir) {
  SplitOptions o;
  o.inputs = inputs;
  o.work_dir = work_dir;
  o.crs = args.get("crs");
  o.origin = args.get("origin");
  o.geoid = args.get("geoid");
  o.footprints = args.get("footprints");
  o.footprint_buffer = args.get_double("footprint-buffer");
  o.cell_size = args.get_double("cell-size");
  o.halo = args.get_double("halo");
  o.max_halo = std::max(args.get_double("max-halo"), o.halo);
  o.seg.min_height = args.get_double("min-height");
  o.seg.min_area = args.get_double("min-area");
  o.seg.cluster_tolerance = args.get_double("cluster-tolerance");
  o.seg.dtm_window = args.get_double("dtm-window");
  o.ignore_classes = args.has("ignore-classes");
  try {
    o.memory_limit = parse_memory_size(args.get("memory-limit"));
    o.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return o;
}

// ------------------------------------------------------------ lod
void declare_lod_param_options(ArgParser& args) {
  args.option("set", 's', "NAME=VALUE[,...]", "override parameters, e.g. planes.epsilon=0.2,tree.merge_k=8");
  args.option("config", 'c', "FILE", "JSON object of parameters (as written to params.json)");
}

void apply_lod_settings(lod::LodParams& p, const std::string& list) {
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    const auto eq = item.find('=');
    if (eq == std::string::npos) throw UsageError("--set expects NAME=VALUE, got '" + item + "'");
    try {
      p.set(item.substr(0, eq), item.substr(eq + 1));
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--set: ") + e.what());
    }
  }
}

void apply_lod_config(lod::LodParams& p, const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error(path + ": cannot open the config file");
  nlohmann::json j;
  try {
    f >> j;
  } catch (const std::exception& e) {
    throw std::runtime_error(path + ": not valid JSON (" + e.what() + ")");
  }
  if (!j.is_object()) throw std::runtime_error(path + ": expected a JSON object of parameters");
  for (const auto& [k, v] : j.items()) {
    try {
      p.set(k, v.is_string() ? v.get<std::string>() : v.dump());
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(path + ": " + e.what());
    }
  }
}

lod::LodParams city_lod_params() {
  lod::LodParams p;
  p.closure.terrain = "cut";
  p.closure.footprint_walls = true;
  return p;
}

lod::LodParams parse_lod_params(const ArgParser& args, lod::LodParams params) {
  if (args.has("config")) apply_lod_config(params, args.get("config"));
  if (args.has("set")) apply_lod_settings(params, args.get("set"));
  return params;
}

// ------------------------------------------------------------ assemble
void declare_assemble_options(ArgParser& args) {
  args.option("max-triangles", 0, "N", "triangle budget of one tile glb", "250000");
  args.option("max-bytes", 0, "BYTES", "geometry byte budget of one tile glb", "4194304");
  args.option("extent-factor", 0, "F",
              "children of a tile with error e span at most F*e metres each (0 = only the budgets split)", "50");
  args.option("min-change", 0, "M",
              "keep an interpolation model only if it differs by >= M metres (Hausdorff) from its "
              "kept neighbours",
              "0.1");
  args.option("hausdorff-tolerance", 0, "M", "accuracy of the Hausdorff distances between models, metres", "0.1");
  args.flag("quantize", 0, "KHR_mesh_quantization: int16 positions and normals (smaller glbs)");
  args.flag("no-building-models", 0, "do not write buildings/*.glb (the viewer's LOD slider needs them)");
  args.flag("skip-missing", 0, "skip buildings without LOD models (warning) instead of failing");
}

AssembleParams parse_assemble_options(const ArgParser& args) {
  AssembleParams p;
  const auto max_tris = args.get_int("max-triangles");
  const auto max_bytes = args.get_int("max-bytes");
  if (max_tris < 1) throw UsageError("--max-triangles must be >= 1");
  if (max_bytes < 1024) throw UsageError("--max-bytes must be >= 1024");
  p.max_tile_triangles = std::size_t(max_tris);
  p.max_tile_bytes = std::size_t(max_bytes);
  p.tile_extent_factor = args.get_double("extent-factor");
  p.min_change_m = args.get_double("min-change");
  p.hausdorff_tolerance_m = args.get_double("hausdorff-tolerance");
  p.quantize = args.has("quantize");
  p.building_models = !args.has("no-building-models");
  p.skip_missing = args.has("skip-missing");
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  return p;
}

// ------------------------------------------------------------ city runs
namespace fs = std::filesystem;

namespace {
nlohmann::json read_json(const std::string& path) {
  std::ifstream f(path);
  if (!f) return nlohmann::json::object();
  try {
    nlohmann::json j;
    f >> j;
    return j.is_object() ? j : nlohmann::json::object();
  } catch (...) {
    return nlohmann::json::object();
  }
}
std::string report_path(const std::string& work, const std::string& id) {
  return (fs::path(io::lod_dir(work, id)) / "report.json").string();
}
int model_step(const nlohmann::json& m, int index) { return m.value("step", index); }
}  // namespace

std::string overrides_path(const std::string& work_dir) { return (fs::path(work_dir) / "overrides.json").string(); }

Overrides read_overrides(const std::string& work_dir) {
  Overrides o;
  const std::string path = overrides_path(work_dir);
  if (!fs::exists(path)) return o;
  const nlohmann::json j = read_json(path);
  if (j.empty()) throw std::runtime_error(path + ": not valid JSON");
  if (!j.is_object() || !j.contains("buildings") || !j["buildings"].is_object())
    throw std::runtime_error(path + ": not a citylod overrides file");
  for (const auto& [id, b] : j["buildings"].items()) {
    BuildingOverride bo;
    if (b.contains("set"))
      for (const auto& [k, v] : b["set"].items()) bo.set[k] = v.is_string() ? v.get<std::string>() : v.dump();
    if (b.contains("select"))
      for (const auto& s : b["select"]) bo.select.push_back(s.get<int>());
    o[id] = bo;
  }
  return o;
}

void write_overrides(const std::string& work_dir, const Overrides& o) {
  nlohmann::json j;
  j["buildings"] = nlohmann::json::object();
  for (const auto& [id, b] : o) {
    if (b.set.empty() && b.select.empty()) continue;
    nlohmann::json e = nlohmann::json::object();
    if (!b.set.empty()) e["set"] = b.set;
    if (!b.select.empty()) e["select"] = b.select;
    j["buildings"][id] = e;
  }
  io::atomic_write_file(overrides_path(work_dir), j.dump(2) + "\n");
}

lod::LodParams params_for(const lod::LodParams& global, const Overrides& o, const std::string& id) {
  lod::LodParams p = global;
  auto it = o.find(id);
  if (it != o.end())
    for (const auto& [k, v] : it->second.set) p.set(k, v);
  return p;
}

namespace {
struct StageProgress {
  Progress* bar = nullptr;
  std::size_t offset = 0, total = 0;
};
void city_progress(std::size_t done, std::size_t, void* self) {
  auto* s = static_cast<StageProgress*>(self);
  s->bar->set_done(s->offset + done);
}
}  // namespace

CityLodReport run_city_lod(const std::string& work_dir, const lod::LodParams& global, int threads,
                           const std::string& force_id) {
  const auto t0 = std::chrono::steady_clock::now();
  CityLodReport rep;
  const io::Manifest m = io::read_manifest(work_dir);
  for (const auto& c : m.chunks) rep.total += c.status == "skipped" ? 0 : 1;
  // run_lod_stage applies WORK/overrides.json per building.
  Progress bar("lod", rep.total, "buildings");
  StageProgress sp{&bar, 0, rep.total};
  std::size_t ok = 0, fallback = 0, failed = 0;
  std::vector<std::pair<std::string, std::string>> problems;
  LodStageOptions o;
  o.work_dir = work_dir;
  o.params = global;
  o.threads = std::max(1, threads);
  if (!force_id.empty()) o.only = {force_id};  // recompute this one; the others are untouched
  const LodStageReport r = run_lod_stage(o, &city_progress, &sp);
  rep.computed = r.computed;
  rep.reused = force_id.empty() ? r.reused : rep.total - r.computed;
  bar.finish();
  for (const auto& c : m.chunks) {
    if (c.status == "skipped") continue;
    const nlohmann::json j = read_json(report_path(work_dir, c.id));
    const std::string st = j.value("status", "failed");
    if (st == "ok") ++ok;
    else if (st == "fallback") ++fallback;
    else ++failed;
    if (st != "ok") problems.emplace_back(c.id, j.value("reason", std::string("no report")));
  }
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::ostringstream msg;
  msg << "lod: " << rep.total << " buildings (" << rep.computed << " computed, " << rep.reused
      << " reused): " << ok << " ok, " << fallback << " fallback, " << failed << " failed in " << rep.seconds << " s";
  log_info(msg.str());
  for (const auto& [id, why] : problems) log_warn("lod: " + id + ": " + why);
  return rep;
}

std::vector<std::string> apply_model_selections(const std::string& work_dir, const Overrides& overrides) {
  std::vector<std::string> warnings;
  const io::Manifest m = io::read_manifest(work_dir);
  for (const auto& c : m.chunks) {
    const std::string path = report_path(work_dir, c.id);
    if (!fs::exists(path)) continue;
    nlohmann::json j = read_json(path);
    if (!j.is_object() || !j.contains("models")) continue;
    const std::string before = j.dump(2) + "\n";
    const nlohmann::json all = j.contains("models_all") ? j["models_all"] : j["models"];
    auto it = overrides.find(c.id);
    std::vector<int> sel = it == overrides.end() ? std::vector<int>{} : it->second.select;
    if (!sel.empty()) {
      nlohmann::json chosen = nlohmann::json::array();
      bool anchor = false;
      std::set<int> found;
      for (std::size_t i = 0; i < all.size(); ++i) {
        const int step = model_step(all[i], int(i));
        if (std::find(sel.begin(), sel.end(), step) == sel.end()) continue;
        chosen.push_back(all[i]);
        found.insert(step);
        anchor |= all[i].value("kind", std::string("anchor")) != "interpolation";
      }
      if (found.size() != std::set<int>(sel.begin(), sel.end()).size() || !anchor) {
        warnings.push_back(c.id + ": model selection ignored (" +
                           (anchor ? std::string("unknown steps") : std::string("no anchor model selected")) +
                           " for the current models; run 'citylod rebuild --select' again)");
        sel.clear();
      } else {
        j["models"] = chosen;
        j["models_all"] = all;
        j["selected_steps"] = sel;
      }
    }
    if (sel.empty()) {
      j["models"] = all;
      j.erase("models_all");
      j.erase("selected_steps");
    }
    const std::string after = j.dump(2) + "\n";
    if (after != before) io::atomic_write_file(path, after);
  }
  return warnings;
}

nlohmann::json building_records(const std::string& work_dir, const Overrides& overrides) {
  nlohmann::json out = nlohmann::json::array();
  const io::Manifest m = io::read_manifest(work_dir);
  for (const auto& c : m.chunks) {
    nlohmann::json b;
    b["id"] = c.id;
    b["source"] = c.source;
    if (c.status == "skipped") {
      b["status"] = "skipped";
      b["reason"] = c.reason.empty() ? std::string("skipped by split") : c.reason;
      b["models"] = 0;
    } else {
      const nlohmann::json j = read_json(report_path(work_dir, c.id));
      if (j.empty()) {
        b["status"] = "failed";
        b["reason"] = "no report.json (LOD stage did not finish this building)";
        b["models"] = 0;
      } else {
        b["status"] = j.value("status", std::string("failed"));
        const std::string reason = j.value("reason", std::string());
        if (!reason.empty()) b["reason"] = reason;
        b["models"] = j.contains("models") && j["models"].is_array() ? j["models"].size() : 0;
        if (b["models"] == 0 && reason.empty()) b["reason"] = "no models";
      }
    }
    auto it = overrides.find(c.id);
    if (it != overrides.end()) {
      if (!it->second.set.empty()) b["set"] = it->second.set;
      if (!it->second.select.empty()) b["select"] = it->second.select;
    }
    out.push_back(b);
  }
  return out;
}

nlohmann::json assemble_params_json(const AssembleParams& p) {
  return {{"max_tile_triangles", p.max_tile_triangles}, {"max_tile_bytes", p.max_tile_bytes},
          {"tile_extent_factor", p.tile_extent_factor}, {"min_change_m", p.min_change_m},
          {"hausdorff_tolerance_m", p.hausdorff_tolerance_m}, {"quantize", p.quantize},
          {"building_models", p.building_models}, {"skip_missing", p.skip_missing}};
}

AssembleParams assemble_params_from_json(const nlohmann::json& j) {
  AssembleParams p;
  p.max_tile_triangles = j.value("max_tile_triangles", p.max_tile_triangles);
  p.max_tile_bytes = j.value("max_tile_bytes", p.max_tile_bytes);
  p.tile_extent_factor = j.value("tile_extent_factor", p.tile_extent_factor);
  p.min_change_m = j.value("min_change_m", p.min_change_m);
  p.hausdorff_tolerance_m = j.value("hausdorff_tolerance_m", p.hausdorff_tolerance_m);
  p.quantize = j.value("quantize", p.quantize);
  p.building_models = j.value("building_models", p.building_models);
  p.skip_missing = j.value("skip_missing", p.skip_missing);
  p.validate();
  return p;
}

}  // namespace citylod::tiler
