// Input colours through the whole chain on real LiDAR with RGB
// (autzen_trim.laz): report.json face colours -> tile glbs (COLOR_0 with the
// white "*_rgb" materials) and CityJSON (appearance, theme "rgb");
// `--set colour.enabled=false` gives neither.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "support/cli_run.hpp"

namespace fs = std::filesystem;

namespace {

using namespace citylod::test;
using nlohmann::json;

/// The JSON chunk of a glb.
json glb_json(const fs::path& p) {
  const std::string b = slurp(p);
  if (b.size() < 20) return json();
  std::uint32_t len = 0;
  std::memcpy(&len, b.data() + 12, 4);
  return json::parse(b.substr(20, len));
}

/// Primitives of an uncompressed glb whose EXT_mesh_features featureCount is
/// not the number of distinct values of their feature id attribute (the whole
/// accessor: what a validator counts).
int feature_count_mismatches(const fs::path& p) {
  const std::string b = slurp(p);
  std::uint32_t jlen = 0;
  std::memcpy(&jlen, b.data() + 12, 4);
  const json g = json::parse(b.substr(20, jlen));
  const std::size_t bin = 20 + jlen + 8;
  int bad = 0;
  for (const auto& mesh : g["meshes"])
    for (const auto& prim : mesh["primitives"]) {
      const json& acc = g["accessors"][prim["attributes"]["_FEATURE_ID_0"].get<int>()];
      const json& bv = g["bufferViews"][acc["bufferView"].get<int>()];
      const std::size_t stride = bv.value("byteStride", std::size_t(4));
      const std::size_t at =
          bin + bv.value("byteOffset", std::size_t(0)) + acc.value("byteOffset", std::size_t(0));
      std::set<float> ids;
      for (std::size_t i = 0; i < acc["count"].get<std::size_t>(); ++i) {
        float f = 0;
        std::memcpy(&f, b.data() + at + i * stride, 4);
        ids.insert(f);
      }
      const int count =
          prim["extensions"]["EXT_mesh_features"]["featureIds"][0]["featureCount"].get<int>();
      bad += count != int(ids.size());
    }
  return bad;
}

struct Seen {
  int glbs = 0, coloured_primitives = 0, rgb_materials_without_colour = 0;
  int features = 0, coloured_features = 0, bad_material_values = 0;
};

Seen scan(const fs::path& out) {
  Seen s;
  for (const auto& e : fs::directory_iterator(out / "tileset" / "tiles")) {
    if (e.path().extension() != ".glb") continue;
    ++s.glbs;
    const json g = glb_json(e.path());
    for (const auto& mesh : g["meshes"])
      for (const auto& prim : mesh["primitives"]) {
        const std::string mat = g["materials"][prim["material"].get<int>()]["name"];
        const bool rgb = mat.size() > 4 && mat.substr(mat.size() - 4) == "_rgb";
        if (prim["attributes"].contains("COLOR_0")) {
          ++s.coloured_primitives;
          const json& acc = g["accessors"][prim["attributes"]["COLOR_0"].get<int>()];
          EXPECT_EQ(acc["type"], "VEC4");
          EXPECT_EQ(acc["componentType"], 5121);  // UNSIGNED_BYTE
          EXPECT_TRUE(acc.value("normalized", false));
          EXPECT_TRUE(rgb) << mat;
        } else if (rgb) {
          ++s.rgb_materials_without_colour;
        }
      }
  }
  const std::string text = slurp(out / "buildings.city.jsonl");
  std::size_t at = text.find('\n') + 1;  // after the header line
  while (at < text.size()) {
    const std::size_t end = text.find('\n', at);
    const json f = json::parse(text.substr(at, end - at));
    at = end + 1;
    ++s.features;
    const std::size_t materials =
        f.contains("appearance") ? f["appearance"]["materials"].size() : std::size_t(0);
    s.coloured_features += materials > 0;
    for (const auto& [id, obj] : f["CityObjects"].items())
      for (const auto& geo : obj["geometry"]) {
        if (!geo.contains("material")) continue;
        const json& v = geo["material"]["rgb"]["values"];
        // one value per surface of the Solid's shell: a material index or null
        if (v.size() != 1 || v[0].size() != geo["boundaries"][0].size()) ++s.bad_material_values;
        for (const auto& x : v[0])
          if (!x.is_null() && (!x.is_number_unsigned() || x.get<std::size_t>() >= materials))
            ++s.bad_material_values;
      }
  }
  return s;
}

}  // namespace

TEST(ColourCli, LasRgbReachesTilesAndCityJson) {
  const fs::path las = fs::path(CITYLOD_SHARED_DATA) / "laz" / "autzen_trim.laz";
  if (!fs::exists(las)) GTEST_SKIP() << "shared data not found: " << las;
  const fs::path d = tmp_dir("colour_cli");
  const CliRun t = run("tile " + q(las) + " --threads 2 --out " + q(d / "on"));
  ASSERT_EQ(t.code, 0) << t.out;
  EXPECT_NE(t.out.find("with the input's colours)"), std::string::npos) << t.out;
  // report.json: the finest model of some building has a coloured run [n, r, g, b]
  int coloured_reports = 0;
  for (const auto& e : fs::directory_iterator(d / "on" / "work" / "lod")) {
    const json r = json::parse(slurp(e.path() / "report.json"));
    const json& fin = r["models"].back();
    if (!fin.contains("colours")) continue;
    bool coloured = false;
    for (const auto& run : fin["colours"]["triangles"]) coloured = coloured || run.size() == 4;
    coloured_reports += coloured;
    EXPECT_GE(r["timings_s"]["colour"].get<double>(), 0.0);
  }
  EXPECT_GE(coloured_reports, 1);
  const Seen on = scan(d / "on");
  EXPECT_GE(on.coloured_primitives, 1);
  EXPECT_EQ(on.rgb_materials_without_colour, 0);
  EXPECT_EQ(on.coloured_features, on.features);
  EXPECT_EQ(on.bad_material_values, 0);

  const CliRun off =
      run("tile " + q(las) + " --threads 2 -q --set colour.enabled=false --out " + q(d / "off"));
  ASSERT_EQ(off.code, 0) << off.out;
  const Seen none = scan(d / "off");
  EXPECT_EQ(none.glbs, on.glbs);
  EXPECT_EQ(none.coloured_primitives, 0);
  EXPECT_EQ(none.coloured_features, 0);
}

// Uncompressed tiles of three coloured buildings (city3d_001.ply: some
// models have coloured faces, others none): every primitive's featureCount is
// the number of distinct ids of its attribute, the whole accessor the
// primitives share (a model without coloured faces is still in the coloured
// primitive's accessor; counting only the triangles' ids was 3D Tiles
// validator error FEATURE_COUNT_MISMATCH).
TEST(ColourCli, FeatureCountIsTheAttributesDistinctIds) {
  const fs::path ply = fs::path(CITYLOD_SHARED_DATA) / "ahn3_block" / "city3d_001.ply";
  if (!fs::exists(ply)) GTEST_SKIP() << "shared data not found: " << ply;
  const fs::path d = tmp_dir("colour_feature_count");
  const CliRun t =
      run("tile " + q(ply) + " --origin 52.0,4.37,45 --threads 2 -q --compression none --out " +
          q(d / "out"));
  ASSERT_EQ(t.code, 0) << t.out;
  int glbs = 0, coloured = 0;
  for (const auto& e : fs::directory_iterator(d / "out" / "tileset" / "tiles")) {
    if (e.path().extension() != ".glb") continue;
    ++glbs;
    coloured += slurp(e.path()).find("COLOR_0") != std::string::npos;
    EXPECT_EQ(feature_count_mismatches(e.path()), 0) << e.path();
  }
  EXPECT_GE(glbs, 2);
  EXPECT_GE(coloured, 1);
}
