// citylod assemble: model choice, Hausdorff distances, the tile tree and its
// files (tileset.json invariants, glb content, determinism, georeferencing,
// bad input, atomic replacement).
#include <gtest/gtest.h>

#include <proj.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <map>

#include "citylod/geo/georef.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/glb_reader.hpp"
#include "citylod/io/gltf.hpp"
#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/workdir.hpp"
#include "tiler/test_work_support.hpp"

namespace citylod::test {
namespace {

using tiler::AssembleParams;

/// A report's model of kind `k` (its file unused here).
tiler::ModelRecord model(tiler::ModelKind k, int level, int step) {
  tiler::ModelRecord m;
  m.kind = k;
  m.level = level;
  m.step = step;
  return m;
}

/// A report listing `models`; a model's e2 is its RMSE in metres (a 100 m diagonal).
tiler::LodReport report_of(std::vector<tiler::ModelRecord> models) {
  tiler::LodReport r;
  r.bbox_diagonal_m = 100;
  r.models = std::move(models);
  return r;
}

std::string tmp_dir(const std::string& name) {
  const fs::path p = fs::path(CITYLOD_TEST_TMP) / "assemble" / name;
  fs::remove_all(p);
  fs::remove_all(p.string() + ".out");
  fs::remove_all(p.string() + ".out.partial");
  fs::create_directories(p);
  return p.string();
}

AssembleParams quiet_params() {
  AssembleParams p;
  p.threads = 2;
  return p;
}

TriangleMesh box_mesh(double x0, double y0, double z0, double x1, double y1, double z1) {
  TriangleMesh m;
  add_box(m, x0, y0, z0, x1, y1, z1);
  return m;
}

// ------------------------------------------------------------ Hausdorff and model choice

TEST(AssembleMetrics, HausdorffOfKnownShapes) {
  const TriangleMesh a = box_mesh(0, 0, 0, 10, 8, 6);
  EXPECT_NEAR(tiler::hausdorff_distance(a, a, 0.5), 0.0, 1e-9);
  // Shifted by 1 m along x: every point of one is within 1 m of the other.
  EXPECT_NEAR(tiler::hausdorff_distance(a, box_mesh(1, 0, 0, 11, 8, 6), 0.25), 1.0, 1e-9);
  // A taller box: its roof is 3 m above the other's.
  EXPECT_NEAR(tiler::hausdorff_distance(a, box_mesh(0, 0, 0, 10, 8, 9), 0.25), 3.0, 1e-9);
  // A 4.5 m chimney on top: the distance is the chimney height.
  TriangleMesh c = a;
  add_box(c, 3, 1, 6, 4, 2, 10.5);
  EXPECT_NEAR(tiler::hausdorff_distance(a, c, 0.25), 4.5, 1e-6);
  EXPECT_TRUE(std::isinf(tiler::hausdorff_distance(a, TriangleMesh{}, 0.25)));
}

// The distance skips the vertices and triangles both models share (their distance is
// 0; issue 28), and a vertex no triangle uses is not on the surface: a corner of one
// model where the other has only an unused vertex is measured, and a model's own unused
// vertex is not (it counted before: 18 of 1,265 City3D buildings' errors were too large).
TEST(AssembleMetrics, HausdorffOfModelsSharingPartsAndUnusedVertices) {
  const TriangleMesh a = box_mesh(0, 0, 0, 10, 8, 6);
  TriangleMesh b = a;
  add_box(b, 3, 1, 6, 4, 2, 10.5);  // a's triangles and vertices, and a chimney
  EXPECT_NEAR(tiler::hausdorff_distance(a, b, 0.25), 4.5, 1e-9);
  EXPECT_NEAR(tiler::hausdorff_distance(b, a, 0.25), 4.5, 1e-9);
  // t: the box and a sheet from the roof's front edge up to (3, 1, 10.5), 4.5 m above
  // the roof; u: the box and an unused vertex at that apex
  TriangleMesh t = a;
  const auto n = std::uint32_t(t.vertices.size());
  t.vertices.push_back({0, 0, 6});
  t.vertices.push_back({10, 0, 6});
  t.vertices.push_back({3, 1, 10.5});
  t.triangles.push_back({n, n + 1, n + 2});
  TriangleMesh u = a;
  u.vertices.push_back({3, 1, 10.5});
  EXPECT_NEAR(tiler::hausdorff_distance(t, u, 0.05), 4.5, 1e-9);  // the apex, exactly
  EXPECT_NEAR(tiler::hausdorff_distance(u, t, 0.05), 4.5, 1e-9);
  // and u's own unused vertex is not part of its surface: u and the box are the same
  EXPECT_NEAR(tiler::hausdorff_distance(u, a, 0.05), 0.0, 1e-9);
  EXPECT_NEAR(tiler::hausdorff_distance(a, u, 0.05), 0.0, 1e-9);
}

// A triangle is dropped from the search once the distances of its corners to one
// planar face of the other model bound it, and only when that face is convex (issue 28).
// B: an L-shaped block (10 x 10 m, a 6 x 6 m notch, 6 m high) whose roof is one
// non-convex face of four triangles; A: B and a sheet over the roof's lower-left half,
// its corners on the roof, its hypotenuse crossing the notch 1 m from B's walls at most.
TEST(AssembleMetrics, HausdorffBoundsByConvexFacesOnly) {
  const std::vector<std::array<double, 2>> ring{{0, 0}, {10, 0}, {10, 4}, {4, 4}, {4, 10}, {0, 10}};
  TriangleMesh b;
  for (const double z : {0.0, 6.0})
    for (const auto& p : ring) b.vertices.push_back({p[0], p[1], z});
  for (std::uint32_t k = 1; k + 1 < 6; ++k) {  // floor and roof: fans from (0, 0)
    b.triangles.push_back({0, k + 1, k});
    b.triangles.push_back({6, 6 + k, 6 + k + 1});
  }
  for (std::uint32_t k = 0; k < 6; ++k) {  // walls
    const std::uint32_t j = (k + 1) % 6;
    b.triangles.push_back({k, j, 6 + j});
    b.triangles.push_back({k, 6 + j, 6 + k});
  }
  TriangleMesh a = b;
  const auto n = std::uint32_t(a.vertices.size());
  a.vertices.push_back({0, 10, 6});
  a.vertices.push_back({10, 0, 6});
  a.vertices.push_back({0, 0, 6});
  a.triangles.push_back({n, n + 1, n + 2});
  const double d = tiler::hausdorff_distance(a, b, 0.05);
  EXPECT_LE(d, 1.0 + 1e-9);  // (5, 5, 6): 1 m from the walls x = 4 and y = 4
  EXPECT_GE(d, 1.0 - 0.05);
  // a convex roof in four triangles around its centre against the same roof in two:
  // nothing to find, both ways
  TriangleMesh four = box_mesh(0, 0, 0, 10, 8, 6), two = four;
  const auto c = std::uint32_t(four.vertices.size());
  four.vertices.push_back({5, 4, 6});
  for (auto& t : four.triangles) {
    bool roof = true;
    for (const auto v : t) roof = roof && four.vertices[v][2] == 6;
    if (roof) t = {0, 0, 0};  // dropped below
  }
  four.triangles.erase(std::remove(four.triangles.begin(), four.triangles.end(),
                                   std::array<std::uint32_t, 3>{0, 0, 0}),
                       four.triangles.end());
  std::vector<std::uint32_t> corner;  // the roof's corners, counter-clockwise
  for (const Vec3d p : {Vec3d{0, 0, 6}, Vec3d{10, 0, 6}, Vec3d{10, 8, 6}, Vec3d{0, 8, 6}})
    corner.push_back(std::uint32_t(std::find(four.vertices.begin(), four.vertices.end(), p) -
                                   four.vertices.begin()));
  for (std::size_t k = 0; k < 4; ++k) four.triangles.push_back({corner[k], corner[(k + 1) % 4], c});
  EXPECT_NEAR(tiler::hausdorff_distance(four, two, 0.05), 0.0, 1e-9);
  EXPECT_NEAR(tiler::hausdorff_distance(two, four, 0.05), 0.0, 1e-9);
}

TEST(AssembleMetrics, KeepsAnchorsAndInterpolationsThatChangeTheLook) {
  // box (A) -> house (I) -> [I identical to the next anchor] -> house + annex (A) -> + chimney (A)
  const auto chain = lod_chain(12, 9, 8, 4);
  std::vector<tiler::ModelRecord> entries;
  std::vector<TriangleMesh> meshes;
  for (const auto& m : chain) {
    entries.push_back(
        model(m.kind == "anchor" ? tiler::ModelKind::anchor : tiler::ModelKind::interpolation,
              m.level, m.step * 2));
    meshes.push_back(m.mesh);
  }
  entries.insert(entries.begin() + 2, model(tiler::ModelKind::interpolation, 1, 3));
  meshes.insert(meshes.begin() + 2, chain[2].mesh);
  const tiler::ModelChoice c = tiler::choose_models(report_of(entries), meshes, 0.1, 0.05);
  EXPECT_EQ(c.kept, (std::vector<std::size_t>{0, 1, 3, 4}));
  ASSERT_EQ(c.error_m.size(), 4u);
  // box: the chimney top is 4.5 m above its roof; house: the 4 m annex is
  // missing; house + annex: the chimney's top edge is 1.5 m above the ridge
  // and 0.5 m beside it.
  EXPECT_NEAR(c.hausdorff_m[0], 4.5, 1e-6);
  EXPECT_NEAR(c.hausdorff_m[1], 4.0, 1e-6);
  EXPECT_NEAR(c.hausdorff_m[2], std::sqrt(2.5), 0.05);
  EXPECT_EQ(c.error_m.back(), 0.0);
  for (std::size_t i = 1; i < c.error_m.size(); ++i) EXPECT_LT(c.error_m[i], c.error_m[i - 1]);
}

TEST(AssembleMetrics, DropsInterpolationsThatDoNotGetCloser) {
  // box -> box + annex -> house + annex + ridge chimney: the annex does not
  // lower the worst distance (the chimney), so the interpolation is dropped.
  const auto c4 = lod_chain(12, 9, 8, 4);
  TriangleMesh box_annex;
  add_box(box_annex, 0, 0, 0, 12, 9, 8);
  add_box(box_annex, 12, 0, 0, 16, 4.5, 4);
  const auto c = tiler::choose_models(report_of({model(tiler::ModelKind::anchor, 0, 0),
                                                 model(tiler::ModelKind::interpolation, 1, 1),
                                                 model(tiler::ModelKind::anchor, 2, 2)}),
                                      {c4[0].mesh, box_annex, c4[3].mesh}, 0.1, 0.05);
  EXPECT_EQ(c.kept, (std::vector<std::size_t>{0, 2}));
}

TEST(AssembleMetrics, ErrorsStrictlyDecreaseEvenWhenDistancesDoNot) {
  // Anchors 2 m and 3 m away from the finest, in that order: the coarser one
  // is charged the finer one's error + 1 cm. Identical anchors count once.
  const TriangleMesh fin = box_mesh(0, 0, 0, 10, 10, 10);
  const auto A = tiler::ModelKind::anchor;
  std::vector<tiler::ModelRecord> e{model(A, 0, 0), model(A, 1, 1), model(A, 2, 2), model(A, 3, 3)};
  const auto c = tiler::choose_models(
      report_of(e), {box_mesh(2, 0, 0, 12, 10, 10), box_mesh(3, 0, 0, 13, 10, 10), fin, fin}, 0.1,
      0.05);
  EXPECT_EQ(c.kept, (std::vector<std::size_t>{0, 1, 3}));
  ASSERT_EQ(c.error_m.size(), 3u);
  EXPECT_NEAR(c.error_m[0], 3.01, 1e-9);
  EXPECT_NEAR(c.error_m[1], 3.0, 1e-9);
  EXPECT_EQ(c.error_m[2], 0.0);
}

// Issue 26 item 4: zooming in never makes a building worse. Four boxes, each
// an anchor 2 m from the next (all kept by distance); their RMSEs decide.
TEST(AssembleMetrics, KeptChainIsMonotoneInRmse) {
  const auto A = tiler::ModelKind::anchor;
  const std::vector<TriangleMesh> meshes{
      box_mesh(6, 0, 0, 16, 10, 10), box_mesh(4, 0, 0, 14, 10, 10), box_mesh(2, 0, 0, 12, 10, 10),
      box_mesh(0, 0, 0, 10, 10, 10)};
  auto choose = [&](std::vector<double> rmse) {
    std::vector<tiler::ModelRecord> e;
    for (int i = 0; i < 4; ++i) {
      e.push_back(model(A, i, i));
      e.back().e2 = rmse[std::size_t(i)];  // % of a 100 m diagonal: metres
    }
    return tiler::choose_models(report_of(e), meshes, 0.1, 0.05).kept;
  };
  using K = std::vector<std::size_t>;
  EXPECT_EQ(choose({0.5, 0.4, 0.3, 0.2}), (K{0, 1, 2, 3}));   // better and better
  EXPECT_EQ(choose({0.5, 2.8, 0.3, 0.2}), (K{0, 2, 3}));      // worse than the block: dropped
  EXPECT_EQ(choose({0.5, 0.54, 0.3, 0.2}), (K{0, 1, 2, 3}));  // within 5 cm
  EXPECT_EQ(choose({0.5, 0.4, 0.9, 0.44}), (K{0, 1, 3}));     // 0.9 > 0.4 + 0.05
  // the finest stays; a coarser model better than it by more than 5 cm goes
  EXPECT_EQ(choose({0.3, 0.5, 0.6, 0.5}), (K{1, 3}));
  EXPECT_EQ(choose({0.5, 2.8, -1, 0.2}), (K{0, 2, 3}));    // not measured: not judged
  EXPECT_EQ(choose({-1, 2.8, -1, 0.2}), (K{0, 1, 2, 3}));  // nothing measured to compare with
  // the distances still decide first (an anchor identical to the next goes)
  EXPECT_EQ(choose({0.5, 0.4, 0.3, 0.2}).back(), 3u);
}

// ------------------------------------------------------------ whole stage

// Footprint attributes become typed glb properties: one schema over all buildings.
TEST(AssembleAttributes, SchemaTypesAreExactAndDeterministic) {
  const nlohmann::json a = {{"n", 5},          {"big", 9007199254740993LL},
                            {"r", 1.5},        {"b", true},
                            {"s", "x"},        {"mixed", 1},
                            {"gap", 7},        {"bgap", false},
                            {"nul", nullptr},  {"bad name!", "v"},
                            {"bad_name_", "w"}};
  const nlohmann::json b = {{"n", -2},  {"big", 1},       {"r", 2},         {"b", false},
                            {"s", "y"}, {"mixed", "one"}, {"nul", nullptr}, {"bad name!", "u"}};
  const auto schema = io::glb_attribute_schema({&a, &b});
  std::map<std::string, io::GlbAttribute> by;
  for (const auto& s : schema) by[s.name] = s;
  using T = io::GlbAttribute::Type;
  EXPECT_EQ(by.at("n").type, T::int64);
  EXPECT_FALSE(by.at("n").no_data);
  EXPECT_EQ(by.at("big").type, T::int64);  // no gap: exact as INT64
  EXPECT_EQ(by.at("r").type, T::float64);  // 1.5 and 2
  EXPECT_EQ(by.at("b").type, T::boolean);
  EXPECT_EQ(by.at("s").type, T::string);
  EXPECT_EQ(by.at("mixed").type, T::string);
  EXPECT_EQ(by.at("gap").type, T::float64);  // missing in b: FLOAT64 with noData
  EXPECT_TRUE(by.at("gap").no_data);
  EXPECT_EQ(by.at("bgap").type, T::string);  // BOOLEAN has no noData
  EXPECT_EQ(by.at("nul").type, T::string);
  EXPECT_EQ(by.at("n").property, "fp_n");
  // property ids are [A-Za-z0-9_] and unique: "bad name!" and "bad_name_" collide
  EXPECT_EQ(by.at("bad name!").property, "fp_bad_name_");
  EXPECT_EQ(by.at("bad_name_").property, "fp_bad_name__2");
  // sorted by name, the same for the same objects in any order
  for (std::size_t i = 1; i < schema.size(); ++i) EXPECT_LT(schema[i - 1].name, schema[i].name);
  const auto again = io::glb_attribute_schema({&b, &a});
  ASSERT_EQ(again.size(), schema.size());
  for (std::size_t i = 0; i < schema.size(); ++i) {
    EXPECT_EQ(again[i].property, schema[i].property);
    EXPECT_EQ(again[i].type, schema[i].type);
  }
  // with a gap, an integer beyond 2^53 is not exact as FLOAT64: STRING
  const nlohmann::json c = {{"id", 9007199254740993LL}};
  const nlohmann::json d = nlohmann::json::object();
  EXPECT_EQ(io::glb_attribute_schema({&c, &d}).at(0).type, T::string);
  // few distinct strings, none missing: an ENUM of them (sorted)
  EXPECT_TRUE(by.at("s").enum_values.empty());  // 2 values for 2 objects
  const nlohmann::json e1 = {{"k", "same"}, {"t", "b"}, {"u", "x"}},
                       e2 = {{"k", "same"}, {"t", "a"}, {"u", "y"}},
                       e3 = {{"k", "same"}, {"t", "b"}, {"u", "z"}},
                       e4 = {{"k", "same"}, {"t", "a"}};
  const auto k = io::glb_attribute_schema({&e1, &e2, &e3, &e4});
  ASSERT_EQ(k.size(), 3u);  // k, t, u
  EXPECT_EQ(k[0].enum_values, (std::vector<std::string>{"same"}));
  EXPECT_EQ(k[1].enum_values, (std::vector<std::string>{"a", "b"}));
  EXPECT_TRUE(k[2].enum_values.empty());  // missing in e4
}

TEST(Assemble, SyntheticCityMakesAValidHierarchy) {
  const std::string work = tmp_dir("city50");
  const auto city = synthetic_city(50, 3);
  write_work(work, synthetic_manifest(), city);
  const std::string out = work + ".out";
  const auto t0 = std::chrono::steady_clock::now();
  const tiler::AssembleStats st = tiler::assemble(work, out, quiet_params());
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf(
      "[ measure  ] 50 buildings x 3 models: %.3f s, %zu tiles (%zu glb, depth %d), %zu B of tiles "
      "(largest %zu B), %zu B of building glbs\n",
      secs, st.tiles, st.content_tiles, st.depth, st.glb_bytes, st.max_glb_bytes,
      st.building_glb_bytes);
  EXPECT_EQ(st.buildings, 50u);
  EXPECT_EQ(st.models_read, 150u);
  EXPECT_EQ(st.models_kept, 150u);
  EXPECT_TRUE(st.warnings.empty());

  const TilesetCheck chk = check_tileset(out);
  for (const auto& p : chk.problems) ADD_FAILURE() << p;
  EXPECT_EQ(chk.tiles, int(st.tiles));
  EXPECT_GE(chk.depth, 2);  // three models -> at least three levels of content
  EXPECT_GT(chk.leaves, 4);
  EXPECT_EQ(std::size_t(chk.content_tiles), st.content_tiles);

  // Root: the coarse anchor (model 0) of all 50 buildings; leaves: the finest.
  const auto ts = nlohmann::json::parse(read_bytes(out + "/tileset.json"));
  ASSERT_TRUE(ts["root"].contains("transform"));
  ASSERT_TRUE(ts["root"].contains("content"));
  const GlbFile root = read_glb(out + "/" + ts["root"]["content"]["uri"].get<std::string>());
  const auto& table = root.json["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
  EXPECT_EQ(table["count"], 50);
  // one schema for the tileset (schemaUri), 11 properties without footprint attributes
  EXPECT_EQ(root.json["extensions"]["EXT_structural_metadata"]["schemaUri"], "../schema.json");
  const auto schema = nlohmann::json::parse(read_bytes(out + "/schema.json"));
  EXPECT_EQ(schema["classes"]["building"]["properties"].size(), 11u);
  std::set<int> features;
  for (const auto& v : glb_vertices(root)) features.insert(v.feature);
  EXPECT_EQ(features.size(), 50u);
  // (building_id, model_index) of every feature of a glb's property table.
  auto features_of = [](const GlbFile& g) {
    const auto& pt = g.json["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
    const auto& bv = g.json["bufferViews"];
    const std::size_t n = pt["count"];
    const auto& ids = bv[pt["properties"]["building_id"]["values"].get<size_t>()];
    const auto& offs = bv[pt["properties"]["building_id"]["stringOffsets"].get<size_t>()];
    const auto& idx = bv[pt["properties"]["model_index"]["values"].get<size_t>()];
    // UINT16 string offsets (UINT32 only for more than 64 KiB of characters)
    EXPECT_EQ(pt["properties"]["building_id"]["stringOffsetType"], "UINT16");
    auto off = [&](std::size_t i) {
      const std::size_t at = offs.value("byteOffset", 0u) + 2 * i;
      return std::uint32_t(std::uint8_t(g.bin[at])) | std::uint32_t(std::uint8_t(g.bin[at + 1]))
                                                          << 8;
    };
    std::vector<std::pair<std::string, std::uint32_t>> out;
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint32_t a = off(i), b = off(i + 1);
      out.emplace_back(g.bin.substr(ids.value("byteOffset", 0u) + a, b - a),
                       u32(g.bin, idx.value("byteOffset", 0u) + 4 * i));
    }
    return out;
  };
  // Every building appears in the leaves exactly once, with its finest model.
  std::map<std::string, int> leaf_count;
  std::function<void(const nlohmann::json&)> leaves = [&](const nlohmann::json& t) {
    if (!t.contains("children")) {
      for (const auto& [id, m] :
           features_of(read_glb(out + "/" + t["content"]["uri"].get<std::string>()))) {
        ++leaf_count[id];
        EXPECT_EQ(m, 2u);
      }
      return;
    }
    for (const auto& c : t["children"]) leaves(c);
  };
  leaves(ts["root"]);
  EXPECT_EQ(leaf_count.size(), 50u);
  for (const auto& [id, n] : leaf_count) EXPECT_EQ(n, 1) << id;

  // The viewer's index: each kept model names the tile glb that holds it
  // (the LOD slider shows that feature alone); no per-building glbs by default.
  const auto index = nlohmann::json::parse(read_bytes(out + "/buildings.json"));
  ASSERT_EQ(index["buildings"].size(), 50u);
  EXPECT_FALSE(fs::exists(out + "/buildings"));
  EXPECT_EQ(st.building_glb_bytes, 0u);
  for (const auto& [id, e] : index["buildings"].items()) {
    EXPECT_FALSE(e.contains("glb")) << id;
    ASSERT_EQ(e["models"].size(), 3u) << id;
    for (std::uint32_t m = 0; m < 3; ++m) {
      const auto& tile = e["models"][m]["tile"];
      ASSERT_TRUE(tile.is_string()) << id << " model " << m;
      const auto f = features_of(read_glb(out + "/" + tile.get<std::string>()));
      EXPECT_EQ(std::count(f.begin(), f.end(), std::make_pair(id, m)), 1) << id << " " << tile;
    }
  }
  const auto& b0 = index["buildings"]["b-0000"];
  EXPECT_EQ(b0["models"][0]["kind"], "anchor");
  EXPECT_EQ(b0["models"][1]["kind"], "interpolation");
  EXPECT_EQ(b0["models"][2]["error_m"], 0.0);
  EXPECT_EQ(b0["models"][0]["tile"], ts["root"]["content"]["uri"]);
}

TEST(Assemble, BuildingModelsOnRequest) {
  const std::string work = tmp_dir("city_bglb");
  write_work(work, synthetic_manifest(), synthetic_city(5, 3));
  const std::string out = work + ".out";
  AssembleParams p = quiet_params();
  p.building_models = true;
  const tiler::AssembleStats st = tiler::assemble(work, out, p);
  EXPECT_GT(st.building_glb_bytes, 0u);
  const auto index = nlohmann::json::parse(read_bytes(out + "/buildings.json"));
  const auto& b0 = index["buildings"]["b-0000"];
  EXPECT_TRUE(b0["models"][1]["tile"].is_string());
  EXPECT_EQ(b0["models"][1]["node"], "model_1");
  const GlbFile bg = read_glb(out + "/" + b0["glb"].get<std::string>());
  EXPECT_EQ(bg.json["nodes"].size(), 3u);
  EXPECT_EQ(bg.json["nodes"][1]["name"], "model_1");
}

TEST(Assemble, OutputIsDeterministicWhateverTheThreads) {
  const std::string work = tmp_dir("determinism");
  write_work(work, synthetic_manifest(), synthetic_city(30, 4));
  AssembleParams p = quiet_params();
  p.threads = 1;
  tiler::assemble(work, work + ".a", p);
  p.threads = 2;
  tiler::assemble(work, work + ".b", p);
  const auto a = dir_contents(work + ".a"), b = dir_contents(work + ".b");
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [name, bytes] : a) {
    ASSERT_TRUE(b.count(name)) << name;
    EXPECT_TRUE(bytes == b.at(name)) << name << " differs";
  }
  fs::remove_all(work + ".a");
  fs::remove_all(work + ".b");
}

TEST(Assemble, SingleModelBuildingsGiveALeafRoot) {
  // Before the LOD engine: one watertight model per building (extruded outlines).
  const std::string work = tmp_dir("single");
  write_work(work, synthetic_manifest(), synthetic_city(9, 1));
  const auto st = tiler::assemble(work, work + ".out/", quiet_params());  // trailing slash
  EXPECT_FALSE(fs::exists(work + ".out/.partial"));
  EXPECT_EQ(st.tiles, 1u);
  const TilesetCheck chk = check_tileset(work + ".out");
  for (const auto& pr : chk.problems) ADD_FAILURE() << pr;
  const auto ts = nlohmann::json::parse(read_bytes(work + ".out/tileset.json"));
  EXPECT_EQ(ts["root"]["geometricError"], 0.0);
  EXPECT_GT(ts["geometricError"].get<double>(), 10.0);  // a building's size
}

TEST(Assemble, FallbackModelsAreShown) {
  // The LOD engine writes one "fallback" model (extruded outline) when a
  // building's reconstruction fails.
  const std::string work = tmp_dir("fallback");
  auto city = synthetic_city(3, 3);
  city[1].models.resize(1);
  city[1].models[0].kind = "fallback";
  write_work(work, synthetic_manifest(), city);
  tiler::assemble(work, work + ".out", quiet_params());
  const TilesetCheck chk = check_tileset(work + ".out");
  for (const auto& pr : chk.problems) ADD_FAILURE() << pr;
  const auto index = nlohmann::json::parse(read_bytes(work + ".out/buildings.json"));
  EXPECT_EQ(index["buildings"]["b-0001"]["models"][0]["kind"], "fallback");
}

TEST(Assemble, ChainsOfDifferentLengthsShareTheTree) {
  const std::string work = tmp_dir("mixed");
  auto city = synthetic_city(16, 4);
  for (std::size_t i = 0; i < city.size(); i += 3) city[i].models.resize(1 + i % 3);
  write_work(work, synthetic_manifest(), city);
  const auto st = tiler::assemble(work, work + ".out", quiet_params());
  EXPECT_EQ(st.buildings, 16u);
  const TilesetCheck chk = check_tileset(work + ".out");
  for (const auto& pr : chk.problems) ADD_FAILURE() << pr;
  EXPECT_EQ(chk.depth, 3);  // the single-model buildings are too few for leaves of their own
  // with leaves for any finished buildings: an empty root over a leaf of the
  // single-model buildings and the refining tiles, one level deeper
  AssembleParams p = quiet_params();
  p.min_leaf_bytes = 0;
  tiler::assemble(work, work + ".out", p);
  const TilesetCheck sep = check_tileset(work + ".out");
  for (const auto& pr : sep.problems) ADD_FAILURE() << pr;
  const auto ts = nlohmann::json::parse(read_bytes(work + ".out/tileset.json"));
  EXPECT_FALSE(ts["root"].contains("content"));
  EXPECT_EQ(sep.depth, 4);
}

// Every kept model is stored in exactly one tile (buildings that reach their
// finest model go to leaves, the others refine on), and with a minimum tile
// extent the leaves gather whole blocks.
TEST(Assemble, EachModelIsStoredOnceAndLeavesGatherBuildings) {
  const std::string work = tmp_dir("once");
  auto city = synthetic_city(64, 4);
  for (std::size_t i = 0; i < city.size(); i += 5) city[i].models.resize(1 + i % 4);
  write_work(work, synthetic_manifest(), city);
  auto count_tiles = [&](const AssembleParams& p, std::size_t& leaves) {
    const auto st = tiler::assemble(work, work + ".out", p);
    const TilesetCheck chk = check_tileset(work + ".out");
    for (const auto& pr : chk.problems) ADD_FAILURE() << pr;
    std::map<std::pair<std::string, int>, int> stored;
    leaves = 0;
    for (const auto& e : fs::directory_iterator(work + ".out/tiles")) {
      const io::GlbDocument d = io::read_glb(e.path().string());
      const io::GlbPropertyTable& t = d.property_tables.at(0);
      bool all_finest = true;
      for (std::size_t i = 0; i < t.count; ++i) {
        ++stored[{t.strings.at("building_id")[i], int(t.numbers.at("model_index")[i])}];
        all_finest = all_finest && t.numbers.at("geometric_error")[i] == 0;
      }
      leaves += all_finest;
    }
    EXPECT_EQ(stored.size(), st.models_kept);
    for (const auto& [k, n] : stored) EXPECT_EQ(n, 1) << k.first << " model " << k.second;
    return st.content_tiles;
  };
  AssembleParams p = quiet_params();
  p.building_models = false;  // (the default)
  p.min_leaf_bytes = 0;       // leaves of their own for any finished buildings
  std::size_t leaves_factor = 0, leaves_blocks = 0;
  const std::size_t tiles_factor = count_tiles(p, leaves_factor);
  p.min_tile_extent_m = 1000;  // the whole synthetic city (8 x 8 buildings, 30 m apart)
  const std::size_t tiles_blocks = count_tiles(p, leaves_blocks);
  std::printf(
      "[ measure  ] 64 buildings: %zu glbs (%zu leaves) -> %zu (%zu) with 1 km min extent\n",
      tiles_factor, leaves_factor, tiles_blocks, leaves_blocks);
  EXPECT_LT(tiles_blocks, tiles_factor);
  EXPECT_LT(leaves_blocks, leaves_factor);
  // at most one tile per level of refining models (chains of up to 4 models:
  // 3) and one leaf per chain length (4)
  EXPECT_LE(tiles_blocks, 3u + 4u);
  EXPECT_LE(leaves_blocks, 4u);
}

// A large tree is written as external tilesets (tiles/<name>.json) of a bounded
// number of tiles each; the tiles themselves do not change.
TEST(Assemble, LargeTreesGoToExternalTilesets) {
  const std::string work = tmp_dir("external");
  write_work(work, synthetic_manifest(), synthetic_city(64, 3));
  AssembleParams p = quiet_params();
  p.building_models = false;  // (the default)
  p.max_tile_triangles = 60;  // a few buildings per tile: a deep, wide tree
  const auto one = tiler::assemble(work, work + ".one", p);
  EXPECT_EQ(one.tileset_files, 1u);
  p.max_tiles_per_file = 6;
  const auto st = tiler::assemble(work, work + ".ext", p);
  EXPECT_GT(st.tileset_files, 3u);
  EXPECT_EQ(st.tiles, one.tiles);
  const TilesetCheck chk = check_tileset(work + ".ext");
  for (const auto& pr : chk.problems) ADD_FAILURE() << pr;
  EXPECT_EQ(chk.tiles, int(st.tiles));
  EXPECT_EQ(std::size_t(chk.external_files) + 1, st.tileset_files);
  EXPECT_EQ(std::size_t(chk.content_tiles), one.content_tiles);
  // each file: at most 6 tiles of its own plus the references to its externals
  std::function<std::size_t(const nlohmann::json&)> count = [&](const nlohmann::json& t) {
    std::size_t n = 1;
    if (t.contains("children"))
      for (const auto& c : t["children"]) n += count(c);
    return n;
  };
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(work + ".ext/tiles"))
    if (e.path().extension() == ".json") {
      ++files;
      const auto j = nlohmann::json::parse(read_bytes(e.path().string()));
      EXPECT_LE(count(j["root"]), 6u + 4u) << e.path();
    }
  EXPECT_EQ(files + 1, st.tileset_files);
  auto glbs = [](const std::string& dir) {
    auto all = dir_contents(dir);
    for (auto it = all.begin(); it != all.end();)
      it = it->first.size() > 4 && it->first.substr(it->first.size() - 4) == ".glb" ? std::next(it)
                                                                                    : all.erase(it);
    return all;
  };
  EXPECT_EQ(glbs(work + ".ext"), glbs(work + ".one"));
}

TEST(Assemble, TileBudgetSplitsTiles) {
  const std::string work = tmp_dir("budget");
  write_work(work, synthetic_manifest(), synthetic_city(64, 3));
  AssembleParams p = quiet_params();
  p.max_tile_triangles = 120;  // a few buildings per tile
  p.building_models = false;   // (the default)
  const auto st = tiler::assemble(work, work + ".out", p);
  EXPECT_LE(st.max_tile_triangles, 120u);
  const TilesetCheck chk = check_tileset(work + ".out");
  for (const auto& pr : chk.problems) ADD_FAILURE() << pr;
  // The coarse models of 64 buildings (768 triangles) do not fit: empty root.
  const auto ts = nlohmann::json::parse(read_bytes(work + ".out/tileset.json"));
  EXPECT_FALSE(ts["root"].contains("content"));
  EXPECT_GT(ts["root"]["children"].size(), 4u);
  EXPECT_FALSE(fs::exists(work + ".out/buildings"));
}

TEST(Assemble, QuantizedOutputIsValidAndSmaller) {
  const std::string work = tmp_dir("quantized");
  write_work(work, synthetic_manifest(), synthetic_city(20, 3));
  AssembleParams p = quiet_params();
  p.building_models = true;  // their glbs are checked too
  p.compression = io::Compression::none;
  const auto plain = tiler::assemble(work, work + ".plain", p);
  p.quantize = true;
  const auto q = tiler::assemble(work, work + ".out", p);
  EXPECT_LT(q.glb_bytes, plain.glb_bytes);
  const TilesetCheck chk = check_tileset(work + ".out");
  for (const auto& pr : chk.problems) ADD_FAILURE() << pr;
  const auto ts = nlohmann::json::parse(read_bytes(work + ".out/tileset.json"));
  const GlbFile g = read_glb(work + ".out/" + ts["root"]["content"]["uri"].get<std::string>());
  EXPECT_EQ(g.json["extensionsRequired"][0], "KHR_mesh_quantization");
  // The default, EXT_meshopt_compression: the same tiles, decoded by
  // meshoptimizer (test support), pass the same checks and are smaller still.
  p.quantize = false;
  p.compression = io::Compression::meshopt;
  const auto m = tiler::assemble(work, work + ".meshopt", p);
  EXPECT_EQ(m.tiles, plain.tiles);
  EXPECT_LT(double(m.glb_bytes), 0.6 * double(plain.glb_bytes));
  std::printf("synthetic city, tile glb bytes: none %zu, quantized %zu, meshopt %zu (%.0f %%)\n",
              plain.glb_bytes, q.glb_bytes, m.glb_bytes,
              100.0 * double(m.glb_bytes) / double(plain.glb_bytes));
  const TilesetCheck mchk = check_tileset(work + ".meshopt");
  for (const auto& pr : mchk.problems) ADD_FAILURE() << "meshopt: " << pr;
  const GlbFile gm = read_glb(work + ".meshopt/" + ts["root"]["content"]["uri"].get<std::string>());
  EXPECT_EQ(gm.json["extensionsRequired"],
            nlohmann::json({"EXT_meshopt_compression", "KHR_mesh_quantization"}));
  EXPECT_EQ(gm.json["buffers"][1]["extensions"]["EXT_meshopt_compression"]["fallback"], true);
  // Every glb (tiles and buildings, one or many meshes): one compressed
  // position-and-feature-id bufferView per mesh, one normal and one triangle
  // bufferView for all of them.
  std::size_t glbs = 0;
  for (const char* dir : {"/tiles", "/buildings"})
    for (const auto& e : fs::directory_iterator(work + ".meshopt" + dir)) {
      if (e.path().extension() != ".glb") continue;
      ++glbs;
      const GlbFile g = read_glb(e.path().string());
      std::map<std::string, std::size_t> modes;
      for (const auto& bv : g.json["bufferViews"])
        if (bv.contains("extensions")) {
          const auto& x = bv["extensions"]["EXT_meshopt_compression"];
          ++modes[x["mode"].get<std::string>() + "/" + x.value("filter", "NONE")];
        }
      const std::size_t meshes = g.json["meshes"].size();
      EXPECT_EQ(modes["ATTRIBUTES/OCTAHEDRAL"], 1u) << e.path();
      EXPECT_EQ(modes["TRIANGLES/NONE"], 1u) << e.path();
      EXPECT_EQ(modes["ATTRIBUTES/NONE"] + modes["ATTRIBUTES/EXPONENTIAL"], meshes) << e.path();
      for (const auto& mesh : g.json["meshes"])
        for (const auto& pr : mesh["primitives"])
          EXPECT_EQ(
              g.json["accessors"][pr["attributes"]["_FEATURE_ID_0"].get<std::size_t>()]
                    ["bufferView"],
              g.json["accessors"][pr["attributes"]["POSITION"].get<std::size_t>()]["bufferView"])
              << e.path();
    }
  EXPECT_GT(glbs, m.tiles);  // the building glbs too
  fs::remove_all(work + ".plain");
  fs::remove_all(work + ".meshopt");
}

// ------------------------------------------------------------ georeferencing

TEST(Assemble, DelftBuildingLandsWhereItIs) {
  // Scene in RD New (EPSG:28992), heights given as ellipsoidal. One building
  // whose corner is at RD (84950, 447450) (Delft centre), base 43.5 m.
  geo::TransformOptions to;
  to.height = geo::HeightMode::Ellipsoidal;
  geo::Georef g = geo::Georef::from_crs(geo::Crs::parse("EPSG:28992"),
                                        Eigen::Vector3d(84000, 447000, 43.0), to);
  tiler::Manifest man =
      synthetic_manifest(g.frame().origin().x(), g.frame().origin().y(), g.frame().origin().z());
  man.scene.crs = "EPSG:28992";
  man.scene.origin_crs = {84000, 447000, 43.0};
  const Eigen::Vector3d corner_rd(84950.0, 447450.0, 43.5);
  const Eigen::Vector3d corner_enu = g.to_local(corner_rd);
  SynthBuilding b;
  b.id = "delft";
  b.origin = {corner_enu.x(), corner_enu.y(), corner_enu.z()};
  b.models = lod_chain(12, 9, 15, 3);
  const std::string work = tmp_dir("delft");
  write_work(work, man, {b});
  tiler::assemble(work, work + ".out", quiet_params());

  // The leaf (finest model): its lowest south-west vertex is the RD corner.
  const auto ts = nlohmann::json::parse(read_bytes(work + ".out/tileset.json"));
  const Eigen::Matrix4d T = matrix_of(ts["root"]["transform"]);
  nlohmann::json leaf = ts["root"];
  while (leaf.contains("children")) leaf = leaf["children"][0];
  const GlbFile glb = read_glb(work + ".out/" + leaf["content"]["uri"].get<std::string>());
  Eigen::Vector3d best(0, 0, 0);
  double key = std::numeric_limits<double>::infinity();
  for (const auto& v : glb_vertices(glb))
    if (v.p.sum() < key) {
      key = v.p.sum();
      best = v.p;
    }
  const Eigen::Vector3d ecef = (T * Eigen::Vector4d(best.x(), best.y(), best.z(), 1)).head<3>();

  // Reference straight from PROJ: RD -> WGS84 lon/lat, then (lon, lat, h) -> ECEF.
  PJ_CONTEXT* ctx = proj_context_create();
  PJ* rd = proj_create_crs_to_crs(ctx, "EPSG:28992", "EPSG:4326", nullptr);
  ASSERT_NE(rd, nullptr);
  PJ* rdn = proj_normalize_for_visualization(ctx, rd);
  PJ_COORD ll = proj_trans(rdn, PJ_FWD, proj_coord(corner_rd.x(), corner_rd.y(), 0, 0));
  PJ* geoc = proj_create_crs_to_crs(ctx, "EPSG:4979", "EPSG:4978", nullptr);
  PJ* geocn = proj_normalize_for_visualization(ctx, geoc);
  PJ_COORD xyz = proj_trans(geocn, PJ_FWD, proj_coord(ll.lp.lam, ll.lp.phi, corner_rd.z(), 0));
  const Eigen::Vector3d ref(xyz.xyz.x, xyz.xyz.y, xyz.xyz.z);
  const double lon = ll.lp.lam * M_PI / 180, lat = ll.lp.phi * M_PI / 180;
  proj_destroy(geocn);
  proj_destroy(geoc);
  proj_destroy(rdn);
  proj_destroy(rd);
  proj_context_destroy(ctx);

  const Eigen::Vector3d d = ecef - ref;
  const Eigen::Vector3d up(std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon),
                           std::sin(lat));
  const double vertical = d.dot(up), horizontal = (d - vertical * up).norm();
  std::printf(
      "[ measure  ] Delft corner: ECEF off PROJ by %.4f m horizontally, %.4f m vertically\n",
      horizontal, vertical);
  EXPECT_LT(horizontal, 0.05);
  EXPECT_LT(std::fabs(vertical), 0.05);  // ellipsoidal height kept
}

// ------------------------------------------------------------ bad input

template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(Assemble, MissingManifestIsAClearError) {
  const std::string work = tmp_dir("nomanifest");
  const std::string e = error_of([&] { tiler::assemble(work, work + ".out", quiet_params()); });
  EXPECT_NE(e.find("manifest.json"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(work + ".out"));
  const std::string e2 =
      error_of([&] { tiler::assemble(work + "/nope", work + ".out", quiet_params()); });
  EXPECT_NE(e2.find("does not exist"), std::string::npos) << e2;
}

TEST(Assemble, EmptyWorkDirIsAClearError) {
  const std::string work = tmp_dir("empty");
  write_work(work, synthetic_manifest(), {});
  const std::string e = error_of([&] { tiler::assemble(work, work + ".out", quiet_params()); });
  EXPECT_NE(e.find("no buildings"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(work + ".out"));
}

TEST(Assemble, BuildingWithoutModelsIsAClearError) {
  const std::string work = tmp_dir("nomodels");
  auto city = synthetic_city(4, 3);
  city[2].write_report = false;  // 'lod' never ran for it
  city[1].models.clear();        // report.json with an empty model list
  write_work(work, synthetic_manifest(), city);
  std::string e = error_of([&] { tiler::assemble(work, work + ".out", quiet_params()); });
  EXPECT_NE(e.find("'b-0001' has no models"), std::string::npos) << e;
  EXPECT_FALSE(fs::exists(work + ".out"));
  // With --skip-missing both are skipped with warnings.
  AssembleParams p = quiet_params();
  p.skip_missing = true;
  const auto st = tiler::assemble(work, work + ".out", p);
  EXPECT_EQ(st.buildings, 2u);
  EXPECT_EQ(st.skipped, 2u);
  ASSERT_EQ(st.warnings.size(), 2u);
  EXPECT_NE(st.warnings[1].find("'b-0002' has no LOD models"), std::string::npos) << st.warnings[1];
  // A model file listed but missing.
  fs::remove(fs::path(tiler::lod_dir(work, "b-0000")) / "model_01_interpolation_L1.ply");
  e = error_of([&] { tiler::assemble(work, work + ".out2", quiet_params()); });
  EXPECT_NE(e.find("model_01_interpolation_L1.ply: model listed in"), std::string::npos) << e;
}

TEST(Assemble, ReplacesAPreviousTilesetAtomicallyAndKeepsItOnFailure) {
  const std::string work = tmp_dir("replace");
  write_work(work, synthetic_manifest(), synthetic_city(6, 3));
  const std::string out = work + ".out";
  tiler::assemble(work, out, quiet_params());
  const auto before = dir_contents(out);
  // A failing run (a building lost its report) leaves the old tileset intact.
  fs::remove(fs::path(tiler::lod_dir(work, "b-0003")) / "report.json");
  EXPECT_FALSE(error_of([&] { tiler::assemble(work, out, quiet_params()); }).empty());
  EXPECT_EQ(dir_contents(out), before);
  EXPECT_FALSE(fs::exists(out + ".partial"));
  // A user directory that is not a tileset is never replaced without force.
  const std::string other = work + ".other";
  fs::create_directories(other);
  io::atomic_write_file(other + "/notes.txt", "mine");
  AssembleParams p = quiet_params();
  p.skip_missing = true;
  const std::string e = error_of([&] { tiler::assemble(work, other, p); });
  EXPECT_NE(e.find("not a tileset"), std::string::npos) << e;
  EXPECT_TRUE(fs::exists(other + "/notes.txt"));
  fs::remove_all(other);
}

}  // namespace
}  // namespace citylod::test
