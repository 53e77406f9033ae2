// `citylod tile` -> DIR/buildings.city.jsonl and `citylod cityjson WORK` on
// the real Delft tile: one feature per building of the tileset, the LOD chain,
// semantics, valid solids (checked independently on the polygons), RD + NAP
// coordinates (against the LAS header and roofer's models of the same
// footprints), and the subcommand's usage and errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "support/cityjson_check.hpp"
#include "support/cli_run.hpp"
#include "support/val3dity.hpp"

namespace fs = std::filesystem;

namespace {

using namespace citylod::test;
using nlohmann::json;

struct Box3 {
  double lo[3] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                  std::numeric_limits<double>::infinity()};
  double hi[3] = {-std::numeric_limits<double>::infinity(),
                  -std::numeric_limits<double>::infinity(),
                  -std::numeric_limits<double>::infinity()};
  void add(const std::array<double, 3>& p) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], p[size_t(k)]);
      hi[k] = std::max(hi[k], p[size_t(k)]);
    }
  }
};

/// Box of the vertices one geometry (Solid or MultiSolid) uses.
Box3 geometry_box(const json& g, const std::vector<std::array<double, 3>>& v) {
  Box3 b;
  const auto add_solid = [&](const json& solid) {
    for (const auto& shell : solid)
      for (const auto& surf : shell)
        for (const auto& ring : surf)
          for (const auto& i : ring) b.add(v[i.get<std::size_t>()]);
  };
  if (g["type"] == "MultiSolid")
    for (const auto& solid : g["boundaries"]) add_solid(solid);
  else
    add_solid(g["boundaries"]);
  return b;
}

/// LAS 1.2 header bounds: max x, min x, max y, min y, max z, min z at byte 179.
Box3 las_bounds(const fs::path& las) {
  std::ifstream f(las, std::ios::binary);
  char buf[48];
  f.seekg(179);
  f.read(buf, sizeof buf);
  double d[6];
  std::memcpy(d, buf, sizeof d);
  Box3 b;
  b.add({d[1], d[3], d[5]});
  b.add({d[0], d[2], d[4]});
  return b;
}

const fs::path kDelft = fs::path(CITYLOD_SHARED_DATA) / "delft";
const fs::path kFootprints =
    fs::path(CITYLOD_SOURCE_DIR) / "tests" / "fixtures" / "delft_bgt_pand.geojson";

TEST(CityJsonCli, DelftTileOneValidChainPerBuilding) {
  const fs::path las = kDelft / "ahn3_cropped_2.las";
  if (!fs::exists(las)) GTEST_SKIP() << "shared data missing: " << las;
  const fs::path d = tmp_dir("cityjson_delft");
  const CliRun t = run("tile " + q(las) + " --crs EPSG:28992 --footprints " + q(kFootprints) +
                       " --threads 2 --out " + q(d / "out"));
  ASSERT_EQ(t.code, 0) << t.out;
  const fs::path file = d / "out" / "buildings.city.jsonl";
  ASSERT_TRUE(fs::exists(file)) << t.out;
  const CjSeq seq = read_cjseq(file.string());
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  EXPECT_EQ(seq.header["metadata"]["referenceSystem"],
            "https://www.opengis.net/def/crs/EPSG/0/28992");

  // one feature per building of the tileset
  std::ifstream bj(d / "out" / "tileset" / "buildings.json");
  const json tiles_index = json::parse(bj);
  std::set<std::string> in_tiles, in_cityjson;
  for (const auto& [id, b] : tiles_index["buildings"].items()) in_tiles.insert(id);
  std::size_t multi = 0, semantics = 0, solids = 0, valid = 0, chain_matches = 0, snapped = 0,
              left_out = 0;
  const Box3 bounds = las_bounds(las);
  std::map<std::string, Box3> finest_box;
  for (const auto& f : seq.features) {
    const json& o = f["CityObjects"][f["id"].get<std::string>()];
    const std::string cid = o["attributes"]["citylod_id"];
    in_cityjson.insert(cid);
    // the footprint's own attributes travel with the building (here its "id")
    EXPECT_EQ(o["attributes"].value("id", std::string()), f["id"].get<std::string>()) << cid;
    for (const auto& p : chain_problems(f)) ADD_FAILURE() << cid << ": " << p;
    const auto chain = feature_chain(f);  // the Building's LoDs + its +LodTreeModel objects
    multi += chain.size() >= 2;
    // the same chain as the tileset but for the models no welding makes valid
    // (left out, counted in the tile's output): the same steps in order
    const json& kept = tiles_index["buildings"][cid]["models"];
    std::size_t at = 0;
    for (const auto& m : kept)
      if (at < chain.size() && m["step"] == chain[at].second["step"]) ++at;
    chain_matches += at == chain.size();
    left_out += kept.size() - chain.size();
    bool all_sem = true;
    const auto v = feature_vertices(seq.header, f);
    const auto vrel = feature_vertices(seq.header, f, true);
    for (std::size_t g = 0; g < chain.size(); ++g) {
      const json& geom = chain[g].first;
      std::set<std::string> types;
      for (const auto& s : geom["semantics"]["surfaces"]) types.insert(s["type"]);
      all_sem = all_sem && types.count("RoofSurface") && types.count("WallSurface") &&
                types.count("GroundSurface");
      ++solids;
      const SolidCheck c = check_geometry(geom, vrel);
      valid += c.valid();
      EXPECT_TRUE(c.valid()) << cid << " geometry " << g << ": closed/oriented "
                             << c.closed_oriented << ", pinched " << c.pinched << ", volume "
                             << c.volume;
      EXPECT_EQ(chain[g].second["valid"], c.valid()) << cid << " " << g;
      // in RD + NAP: within the input's bounds (a wall's top may be 0.25 m above a point)
      const Box3 b = geometry_box(geom, v);
      for (int k = 0; k < 2; ++k) {
        EXPECT_GE(b.lo[k], bounds.lo[k] - 30) << cid;  // footprints may stick out of the tile
        EXPECT_LE(b.hi[k], bounds.hi[k] + 30) << cid;
      }
      EXPECT_GE(b.lo[2], bounds.lo[2] - 1) << cid;
      EXPECT_LE(b.hi[2], bounds.hi[2] + 1) << cid;
      if (g + 1 == chain.size()) finest_box[cid] = b;
    }
    // the finest model is the Building's LoD2.2, a fallback (extruded
    // footprint) LoD1.2; the Building's first geometry is LoD1.2
    const json& geoms = o["geometry"];
    ASSERT_FALSE(geoms.empty()) << cid;
    EXPECT_EQ(geoms.back()["lod"], o["attributes"]["citylod_status"] == "fallback" ? "1.2" : "2.2")
        << cid;
    EXPECT_EQ(geoms.front()["lod"], "1.2") << cid;
    snapped += std::count_if(o["attributes"]["citylod_models"].begin(),
                             o["attributes"]["citylod_models"].end(),
                             [](const json& m) { return m.contains("snapped_m"); });
    semantics += all_sem;
  }
  EXPECT_EQ(in_cityjson, in_tiles);
  EXPECT_EQ(seq.features.size(), in_tiles.size());
  const double n = double(seq.features.size());
  ASSERT_GT(n, 0);
  EXPECT_EQ(chain_matches, seq.features.size());
  EXPECT_NE(t.out.find(std::to_string(left_out) + " models left out as invalid"), std::string::npos)
      << t.out;
  EXPECT_LE(left_out, 2u);  // of ~90 (measured: 2 interpolations of one building)
  EXPECT_GE(double(multi), 0.8 * n);
  EXPECT_GE(double(semantics), 0.95 * n);
  EXPECT_EQ(valid, solids);

  // roofer's LoD2.2 of the same BGT footprints (other ids): the nearest one's
  // box has the same centre and top, so x, y and the NAP heights are right
  const fs::path roofer = kDelft / "roofer" / "ahn3_cropped_2_roofer.city.jsonl";
  std::vector<double> dxy, dz;
  if (fs::exists(roofer)) {
    const CjSeq r = read_cjseq(roofer.string());
    std::vector<Box3> rb;
    for (const auto& f : r.features) {
      const auto v = feature_vertices(r.header, f);
      for (const auto& [id, o] : f["CityObjects"].items())
        for (const auto& g : o.value("geometry", json::array()))
          if (g["lod"] == "2.2") rb.push_back(geometry_box(g, v));
    }
    for (const auto& [cid, b] : finest_box) {
      double best = std::numeric_limits<double>::infinity(), best_dz = 0;
      for (const Box3& x : rb) {
        const double dist = std::hypot((b.lo[0] + b.hi[0] - x.lo[0] - x.hi[0]) / 2,
                                       (b.lo[1] + b.hi[1] - x.lo[1] - x.hi[1]) / 2);
        if (dist < best) {
          best = dist;
          best_dz = std::fabs(b.hi[2] - x.hi[2]);
        }
      }
      dxy.push_back(best);
      dz.push_back(best_dz);
    }
    std::sort(dxy.begin(), dxy.end());
    std::sort(dz.begin(), dz.end());
    ASSERT_FALSE(dxy.empty());
    EXPECT_LT(dxy[dxy.size() / 2], 0.5);
    EXPECT_LT(dz[dz.size() / 2], 0.5);
  }
  std::printf(
      "Delft tile CityJSON: %zu buildings, %zu solids (%zu valid, %zu welded, %zu left out), %zu "
      "with >= 2 LODs "
      "(%.0f %%), %zu with roof/wall/ground on every solid (%.0f %%), %ju bytes; vs roofer "
      "LoD2.2: median centre offset %.3f m, median top difference %.3f m\n",
      seq.features.size(), solids, valid, snapped, left_out, multi, 100.0 * double(multi) / n,
      semantics, 100.0 * double(semantics) / n, std::uintmax_t(fs::file_size(file)),
      dxy.empty() ? -1.0 : dxy[dxy.size() / 2], dz.empty() ? -1.0 : dz[dz.size() / 2]);

  // val3dity (the validator 3DBAG publishes with) at its default tolerances:
  // every solid and every building valid (issue 26: 71/90 solids, 19/27
  // buildings before the tolerance-aware check and the one-geometry-per-lod rule)
  if (val3dity_binary().empty()) {
    std::printf("val3dity not found beside the shared data: not run\n");
  } else {
    const Val3dityResult v3 = run_val3dity(file, d / "val3dity.json");
    ASSERT_TRUE(v3.ran) << v3.why;
    EXPECT_EQ(v3.valid_primitives, v3.primitives) << v3.first_error;
    EXPECT_EQ(v3.valid_features, v3.features) << v3.first_error;
    EXPECT_EQ(v3.primitives, solids);
    std::printf("val3dity: %zu / %zu features valid, %zu / %zu solids valid\n", v3.valid_features,
                v3.features, v3.valid_primitives, v3.primitives);
  }

  // the tiles: EXT_meshopt_compression by default (every glb requires it),
  // against the same work directory assembled with --compression none
  const CliRun none = run("assemble " + q(d / "out" / "work") + " -q --compression none --out " +
                          q(d / "tiles_none"));
  ASSERT_EQ(none.code, 0) << none.out;
  auto tile_bytes = [](const fs::path& dir, bool meshopt) {
    std::uintmax_t n = 0;
    for (const auto& e : fs::directory_iterator(dir / "tiles")) {
      n += fs::file_size(e.path());
      const std::string b = slurp(e.path());
      EXPECT_EQ(b.find("\"EXT_meshopt_compression\"") != std::string::npos, meshopt) << e.path();
    }
    return n;
  };
  const std::uintmax_t mo = tile_bytes(d / "out" / "tileset", true),
                       plain = tile_bytes(d / "tiles_none", false);
  std::printf("Delft tile glbs: meshopt %ju bytes, none %ju bytes (%.1f %%)\n", mo, plain,
              100.0 * double(mo) / double(plain));
  EXPECT_LT(double(mo), 0.5 * double(plain));

  // the subcommand on the same work directory writes the same bytes
  const CliRun c = run("cityjson " + q(d / "out" / "work") + " -q --threads 1 --out " +
                       q(d / "again.city.jsonl"));
  ASSERT_EQ(c.code, 0) << c.out;
  EXPECT_EQ(slurp(d / "again.city.jsonl"), slurp(file));
}

TEST(CityJsonCli, UsageAndBadInput) {
  const fs::path d = tmp_dir("cityjson_bad");
  CliRun r = run("cityjson " + q(d));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--out"), std::string::npos) << r.out;
  r = run("cityjson " + q(d / "nope") + " --out " + q(d / "x.city.jsonl"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("nope"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_FALSE(fs::exists(d / "x.city.jsonl"));
  r = run("cityjson " + q(d) + " --scale 0 --out " + q(d / "x.city.jsonl"));
  EXPECT_EQ(r.code, 2) << r.out;
  r = run("cityjson --help");
  EXPECT_EQ(r.code, 0) << r.out;
}

// The official CityJSON 2.0 JSON schemas (the schemas/ folder of
// github.com/cityjson/specs, not shipped with citylod) when
// CITYLOD_CITYJSON_SCHEMAS points at them and python3 has jsonschema >= 4.18:
// the example scene's file validates with no error.
TEST(CityJsonCli, OfficialSchemaWhenAvailable) {
  const char* dir = std::getenv("CITYLOD_CITYJSON_SCHEMAS");
  if (!dir || !fs::exists(fs::path(dir) / "cityjsonfeature.schema.json"))
    GTEST_SKIP() << "set CITYLOD_CITYJSON_SCHEMAS to the schemas/ folder of cityjson/specs";
  if (sh("python3 -c 'import jsonschema, referencing'").code != 0)
    GTEST_SKIP() << "python3 jsonschema >= 4.18 (with referencing) not installed";
  const fs::path ex = fs::path(CITYLOD_SOURCE_DIR) / "examples" / "delft_small";
  const fs::path d = tmp_dir("cityjson_schema");
  const CliRun t = run("tile " + q(ex / "delft_small.las") + " --crs EPSG:28992 --footprints " +
                       q(ex / "footprints.geojson") + " --threads 2 -q --out " + q(d / "out"));
  ASSERT_EQ(t.code, 0) << t.out;
  const fs::path script = fs::path(CITYLOD_SOURCE_DIR) / "tests" / "support" / "cityjson_schema.py";
  const CliRun v =
      sh("python3 " + q(script) + " " + q(dir) + " " + q(d / "out" / "buildings.city.jsonl"));
  std::printf("%s", v.out.c_str());
  EXPECT_EQ(v.code, 0) << v.out;
  EXPECT_NE(v.out.find("schema errors: 0"), std::string::npos) << v.out;
}

}  // namespace
