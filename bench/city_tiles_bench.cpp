// 3D Tiles assembly of a city: a real work directory (e.g. the Delft tile's,
// from `citylod tile`) replicated on a grid with shifted chunk origins until it
// holds >= N buildings, then `assemble` on it (in this process).
//
//   city_tiles_bench WORK [--buildings N] [--out DIR] [--threads T] [--building-models]
//                    [--min-tile-extent M] [--min-leaf-bytes B] [--max-tiles-per-file N]
//                    [--extent-factor F]
//
// Prints one line of key=value: buildings, tiles, content tiles, depth, bytes of
// tile glbs, largest glb, bytes of every tileset JSON and the largest one,
// bytes of buildings/*.glb (each kept model stored once), tile bytes / that,
// wall time and peak RSS (getrusage, this process). The copies share the
// original's LOD directories through symlinks (nothing is recomputed).
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/workdir.hpp"

namespace fs = std::filesystem;
using namespace citylod;

namespace {

int run(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: city_tiles_bench WORK [--buildings N] [--out DIR] [--threads T] "
                 "[--building-models]\n");
    return 2;
  }
  const std::string work = argv[1];
  std::size_t want = 10000;
  std::string out = "city_tiles_bench.out";
  tiler::AssembleParams p;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--buildings")
      want = std::stoul(next());
    else if (a == "--out")
      out = next();
    else if (a == "--threads")
      p.threads = std::stoi(next());
    else if (a == "--min-tile-extent")
      p.min_tile_extent_m = std::stod(next());
    else if (a == "--min-leaf-bytes")
      p.min_leaf_bytes = std::stoul(next());
    else if (a == "--max-tiles-per-file")
      p.max_tiles_per_file = std::stoul(next());
    else if (a == "--extent-factor")
      p.tile_extent_factor = std::stod(next());
    else if (a == "--building-models")
      p.building_models = true;
    else {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    }
  }
  const tiler::Manifest src = tiler::read_manifest(work);
  std::vector<const tiler::ChunkRecord*> real = tiler::buildings_to_model(src, work);
  real.erase(std::remove_if(real.begin(), real.end(),
                            [&](const tiler::ChunkRecord* c) {
                              return !fs::exists(tiler::lod_report_path(work, c->id));
                            }),
             real.end());
  if (real.empty()) {
    std::fprintf(stderr, "%s: no building with LOD models\n", work.c_str());
    return 1;
  }
  // grid of copies: spacing = the scene's xy extent + 20 m
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const auto* c : real) {
    x0 = std::min(x0, c->bbox_min[0]);
    y0 = std::min(y0, c->bbox_min[1]);
    x1 = std::max(x1, c->bbox_max[0]);
    y1 = std::max(y1, c->bbox_max[1]);
  }
  const std::size_t copies = (want + real.size() - 1) / real.size();
  const std::size_t side = std::size_t(std::ceil(std::sqrt(double(copies))));
  const double dx = x1 - x0 + 20, dy = y1 - y0 + 20;
  const fs::path city = out + ".work";
  fs::remove_all(city);
  fs::create_directories(city / "lod");
  tiler::Manifest m;
  m.scene = src.scene;
  for (std::size_t k = 0; k < copies; ++k) {
    const double ox = double(k % side) * dx, oy = double(k / side) * dy;
    for (const auto* c : real) {
      tiler::ChunkRecord r = *c;
      r.id = "c" + std::to_string(k) + "-" + c->id;
      r.origin[0] += ox;
      r.origin[1] += oy;
      r.bbox_min[0] += ox;
      r.bbox_min[1] += oy;
      r.bbox_max[0] += ox;
      r.bbox_max[1] += oy;
      for (auto& v : r.outline) {
        v[0] += ox;
        v[1] += oy;
      }
      fs::create_directory_symlink(fs::absolute(tiler::lod_dir(work, c->id)),
                                   tiler::lod_dir(city.string(), r.id));
      m.chunks.push_back(std::move(r));
    }
  }
  std::sort(m.chunks.begin(), m.chunks.end(),
            [](const auto& a, const auto& b) { return a.id < b.id; });
  tiler::write_manifest(city.string(), m);

  const auto t0 = std::chrono::steady_clock::now();
  const tiler::AssembleStats st = tiler::assemble(city.string(), out, p);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  std::size_t json_files = 0, json_bytes = 0, json_max = 0;
  for (const auto& e : fs::recursive_directory_iterator(out)) {
    const std::string name = e.path().filename().string();
    if (!e.is_regular_file() || e.path().extension() != ".json" || name == "buildings.json" ||
        name == "schema.json")
      continue;
    ++json_files;
    json_bytes += e.file_size();
    json_max = std::max<std::size_t>(json_max, e.file_size());
  }
  std::printf(
      "buildings=%zu models_kept=%zu tiles=%zu content_tiles=%zu depth=%d tile_glb_bytes=%zu "
      "largest_glb=%zu tileset_json_files=%zu tileset_json_bytes=%zu largest_tileset_json=%zu "
      "building_glb_bytes=%zu tile_bytes_per_model_once=%.2f seconds=%.1f peak_rss_mib=%.0f "
      "tileset_files=%zu\n",
      st.buildings, st.models_kept, st.tiles, st.content_tiles, st.depth, st.glb_bytes,
      st.max_glb_bytes, json_files, json_bytes, json_max, st.building_glb_bytes,
      st.building_glb_bytes ? double(st.glb_bytes) / double(st.building_glb_bytes) : 0.0, secs,
      double(ru.ru_maxrss) / 1024.0, st.tileset_files);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "city_tiles_bench: error: %s\n", e.what());
    return 1;
  }
}
