// io::read_glb / parse_glb: what GlbBuilder writes comes back (positions through
// the node matrix, triangles, feature ids, the property table), plain and
// quantized; corrupt bytes are an IoError naming the file.
#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>

#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "citylod/io/error.hpp"
#include "citylod/io/glb_reader.hpp"
#include "citylod/io/gltf.hpp"
#include "tiler/test_assemble_support.hpp"

namespace citylod::test {
namespace {

io::GlbFeature feature(const std::string& id, lod::ModelKind kind, int step, int index) {
  io::GlbFeature f;
  f.building_id = id;
  f.kind = kind;
  f.level = 1;
  f.step = step;
  f.model_index = index;
  f.model_count = 3;
  f.height_m = 6;
  f.error_m = 0.25;
  return f;
}

/// Every stored triangle back in the input frame (y-up -> z-up), per feature.
std::map<std::int64_t, std::vector<std::array<Vec3d, 3>>> triangles(const io::GlbDocument& d) {
  std::map<std::int64_t, std::vector<std::array<Vec3d, 3>>> out;
  for (const auto& p : d.primitives)
    for (const auto& t : p.triangles) {
      std::array<Vec3d, 3> tri;
      for (int k = 0; k < 3; ++k) {
        const Vec3d y = io::transform_point(p.matrix, p.positions[t[size_t(k)]]);
        tri[size_t(k)] = {y[0], -y[2], y[1]};
      }
      out[p.feature_ids.at(t[0])].push_back(tri);
    }
  return out;
}

void expect_round_trip(bool quantize, double tolerance,
                       io::Compression compression = io::Compression::none) {
  const Vec3d origin{1000.0, 2000.0, 10.0};
  io::GlbOptions opt;
  opt.quantize = quantize;
  opt.compression = compression;
  io::GlbBuilder b(origin, opt);
  TriangleMesh a, c;
  add_box(a, 990, 1995, 10, 1000, 2003, 16);
  add_house(c, 10, 8, 6, 3);
  for (auto& v : c.vertices) v = {v[0] + 1005, v[1] + 2001, v[2] + 10};
  b.add_feature(feature("bldg-a", lod::ModelKind::anchor, 4, 2), a);
  io::GlbFeature fc = feature("bldg-c", lod::ModelKind::interpolation, 7, 1);
  fc.rmse_m = 0.375;
  fc.valid = false;
  b.add_feature(fc, c);
  const io::GlbDocument d = io::parse_glb(b.glb(), "mem.glb");

  ASSERT_EQ(d.property_tables.size(), 1u);
  const auto& t = d.property_tables[0];
  EXPECT_EQ(t.class_name, "building");
  ASSERT_EQ(t.count, 2u);
  EXPECT_EQ(t.strings.at("building_id"), (std::vector<std::string>{"bldg-a", "bldg-c"}));
  EXPECT_EQ(t.strings.at("lod_kind"), (std::vector<std::string>{"anchor", "interpolation"}));
  EXPECT_EQ(t.numbers.at("step"), (std::vector<double>{4, 7}));
  EXPECT_EQ(t.numbers.at("model_index"), (std::vector<double>{2, 1}));
  EXPECT_NEAR(t.numbers.at("geometric_error")[1], 0.25, 1e-7);
  // quality: RMSE (noData -1 when not measured) and validity (BOOLEAN bitstream)
  EXPECT_EQ(t.numbers.at("rmse"), (std::vector<double>{-1, 0.375}));
  EXPECT_EQ(t.numbers.at("valid"), (std::vector<double>{1, 0}));

  const auto tris = triangles(d);
  ASSERT_EQ(tris.size(), 2u);
  EXPECT_EQ(tris.at(0).size(), a.triangles.size());
  EXPECT_EQ(tris.at(1).size(), c.triangles.size());
  for (const auto* src : {&a, &c}) {
    const auto& got = tris.at(src == &a ? 0 : 1);
    // Every stored corner is a source vertex, every source vertex is stored.
    std::set<std::size_t> hit;
    for (const auto& tri : got)
      for (const auto& p : tri) {
        double best = 1e9;
        std::size_t which = 0;
        for (std::size_t i = 0; i < src->vertices.size(); ++i) {
          const auto& v = src->vertices[i];
          const double dd = std::hypot(p[0] - v[0], p[1] - v[1], p[2] - v[2]);
          if (dd < best) best = dd, which = i;
        }
        EXPECT_LT(best, tolerance);
        hit.insert(which);
      }
    EXPECT_EQ(hit.size(), src->vertices.size());
  }
  for (const auto& p : d.primitives) EXPECT_EQ(p.property_table, 0);
}

TEST(GlbReader, RoundTripOfTheWriter) {
  expect_round_trip(false, 1e-4);
}

TEST(GlbReader, RoundTripQuantized) {
  expect_round_trip(true, 20.0 / 32767 * 2);
}

TEST(GlbReader, RoundTripMeshopt) {
  // EXT_meshopt_compression: int16 positions (20 m node), decoded by the reader
  expect_round_trip(false, 20.0 / 32767 * 2, io::Compression::meshopt);
}

TEST(GlbReader, CorruptBytesNameTheFile) {
  TriangleMesh a;
  add_box(a, 0, 0, 0, 1, 1, 1);
  io::GlbBuilder b({0, 0, 0});
  b.add_feature(feature("x", lod::ModelKind::anchor, 0, 0), a);
  const std::string good = b.glb();
  auto fails = [](const std::string& bytes, const std::string& what) {
    try {
      io::parse_glb(bytes, "tile.glb");
      ADD_FAILURE() << "no error for " << what;
    } catch (const io::IoError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("tile.glb: ", 0), 0u) << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  };
  fails("", "empty");
  fails(good.substr(0, good.size() - 7), "truncated");
  fails("glTF" + good.substr(4, 8) + std::string(good.size() - 12, '\0'), "zeroed chunks");
  std::string v1 = good;
  v1[4] = 1;
  fails(v1, "version 1");
  // An index past the vertices: the first index of the first primitive := 65535.
  std::uint32_t jlen;
  std::memcpy(&jlen, good.data() + 12, 4);
  const nlohmann::json j = nlohmann::json::parse(good.substr(20, jlen));
  const auto& acc = j["accessors"][j["meshes"][0]["primitives"][0]["indices"].get<std::size_t>()];
  ASSERT_EQ(acc["componentType"], 5123);  // uint16
  const std::size_t at =
      20 + jlen + 8 +
      j["bufferViews"][acc["bufferView"].get<std::size_t>()]["byteOffset"].get<std::size_t>() +
      acc.value("byteOffset", std::size_t(0));
  std::string bad_index = good;
  bad_index[at] = char(0xff);
  bad_index[at + 1] = char(0xff);
  fails(bad_index, "index out of range");
  EXPECT_NO_THROW(io::parse_glb(good, "tile.glb"));
  EXPECT_THROW(io::read_glb((fs::path(CITYLOD_TEST_TMP) / "no_such_dir" / "x.glb").string()),
               io::IoError);
}

// int16 positions must not merge distinct corners of a model (a thin part
// closer than one quantization step would become non-manifold): such a node is
// written with float positions; an ordinary node stays quantized.
TEST(GlbReader, QuantizationNeverMergesCornersOfAModel) {
  const Vec3d origin{0.0, 0.0, 0.0};
  io::GlbOptions opt;
  opt.quantize = true;
  TriangleMesh far, thin;
  add_box(far, 900, 900, 0, 1000, 1000, 10);  // node extent 1000 m: step ~3 cm
  add_box(thin, 0, 0, 0, 10, 10, 0.004);      // 4 mm thick slab
  io::GlbBuilder merged(origin, opt);
  merged.add_feature(feature("far", lod::ModelKind::anchor, 1, 0), far);
  merged.add_feature(feature("thin", lod::ModelKind::anchor, 1, 0), thin);
  const std::string bytes = merged.glb();
  EXPECT_EQ(bytes.find("KHR_mesh_quantization"), std::string::npos);
  const auto tris = triangles(io::parse_glb(bytes, "mem.glb"));
  double zmax = 0;
  for (const auto& tri : tris.at(1))
    for (const auto& p : tri) zmax = std::max(zmax, p[2]);
  EXPECT_NEAR(zmax, 0.004, 1e-6);  // the slab keeps its thickness

  io::GlbBuilder plain(origin, opt);
  plain.add_feature(feature("far", lod::ModelKind::anchor, 1, 0), far);
  EXPECT_NE(plain.glb().find("KHR_mesh_quantization"), std::string::npos);
}

TEST(GlbReader, MeshoptKeepsOnlyTheDamagedFeaturesFloat) {
  io::GlbOptions opt;
  opt.compression = io::Compression::meshopt;
  TriangleMesh far, thin;
  add_box(far, 900, 900, 0, 1000, 1000, 10);  // node extent 1000 m: int16 step ~3 cm
  add_box(thin, 0, 0, 0, 10, 10, 0.004);      // 4 mm thick slab: int16 would flatten it
  io::GlbBuilder b({0, 0, 0}, opt);
  b.add_feature(feature("far", lod::ModelKind::anchor, 1, 0), far);
  b.add_feature(feature("thin", lod::ModelKind::anchor, 1, 0), thin);
  const io::BBox3 stored = b.stored_bounds();
  const io::GlbDocument d = io::parse_glb(b.glb(), "mem.glb");
  EXPECT_NE(
      std::find(d.extensions_used.begin(), d.extensions_used.end(), "EXT_meshopt_compression"),
      d.extensions_used.end());
  const std::string bytes = b.glb();
  // the float part through meshopt's EXPONENTIAL filter, within 1/256 of the
  // node's int16 step (1000 m / 32767 / 256 = 0.12 mm)
  EXPECT_NE(bytes.find("\"EXPONENTIAL\""), std::string::npos);
  const auto tris = triangles(d);
  double zmax = 0, zmin = 1;
  for (const auto& tri : tris.at(1))
    for (const auto& p : tri) {
      zmax = std::max(zmax, p[2]);
      zmin = std::min(zmin, p[2]);
    }
  const double tol = 1000.0 / 32767 / 256;
  EXPECT_NEAR(zmax, 0.004, tol);  // the slab is not int16: it keeps its thickness
  EXPECT_NEAR(zmin, 0.0, tol);
  io::BBox3 got;
  for (const auto& [f, ts] : tris)
    for (const auto& tri : ts)
      for (const auto& p : tri) got.add(p);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(got.min[size_t(k)], stored.min[size_t(k)], 1e-4);
    EXPECT_NEAR(got.max[size_t(k)], stored.max[size_t(k)], 1e-4);
  }
  EXPECT_NEAR(got.max[0], 1000, 1000.0 / 32767);  // the far box: int16
  EXPECT_EQ(tris.at(0).size(), far.triangles.size());
  EXPECT_EQ(tris.at(1).size(), thin.triangles.size());
}

/// A 10 m cube whose bottom front edge has an extra vertex 1 mm from a corner
/// (both faces at that edge use it): int16 at a 3 cm step merges the two.
TriangleMesh cube_with_close_corners() {
  TriangleMesh m;
  m.vertices = {{0, 0, 0},   {10, 0, 0},   {10, 10, 0}, {0, 10, 0},   {0, 0, 10},
                {10, 0, 10}, {10, 10, 10}, {0, 10, 10}, {0.001, 0, 0}};
  m.triangles = {{3, 2, 1}, {3, 1, 8}, {3, 8, 0}, {4, 0, 8}, {4, 8, 1}, {4, 1, 5}, {3, 7, 6},
                 {3, 6, 2}, {4, 5, 6}, {4, 6, 7}, {0, 4, 7}, {0, 7, 3}, {1, 2, 6}, {1, 6, 5}};
  return m;
}

/// Closed and oriented by exact incidence: every directed edge once, with its
/// reverse once; not empty.
bool closed_and_oriented(const io::TriangleMesh& m) {
  std::map<std::pair<std::uint32_t, std::uint32_t>, int> edges;
  for (const auto& t : m.triangles)
    for (int k = 0; k < 3; ++k) ++edges[{t[size_t(k)], t[size_t((k + 1) % 3)]}];
  for (const auto& [e, n] : edges)
    if (n != 1 || edges.count({e.second, e.first}) == 0) return false;
  return !m.triangles.empty();
}

// With a check of the stored solid (GlbOptions::snapped_is_valid), a model
// whose corners int16 merges is snapped and stored int16 when the check
// accepts it (the collapsed triangles dropped), and stays float when it does
// not (the 4 mm slab flattens: nothing closed is left).
TEST(GlbReader, MeshoptSnapsAModelWhenTheCheckAcceptsIt) {
  TriangleMesh far, cube = cube_with_close_corners(), thin;
  add_box(far, 900, 900, 0, 1000, 1000, 10);  // node extent 1000 m: int16 step ~3 cm
  add_box(thin, 0, 0, 0, 10, 10, 0.004);
  std::vector<std::size_t> checked;  // triangles of each mesh the check saw
  io::GlbOptions opt;
  opt.compression = io::Compression::meshopt;
  opt.snapped_is_valid = [&](const io::TriangleMesh& m) {
    checked.push_back(m.triangles.size());
    return closed_and_oriented(m);
  };
  {
    io::GlbBuilder b({0, 0, 0}, opt);
    b.add_feature(feature("far", lod::ModelKind::anchor, 1, 0), far);
    b.add_feature(feature("cube", lod::ModelKind::anchor, 1, 0), cube);
    const std::string bytes = b.glb();
    EXPECT_EQ(bytes.find("\"EXPONENTIAL\""), std::string::npos);  // no float part
    const auto tris = triangles(io::parse_glb(bytes, "mem.glb"));
    ASSERT_EQ(tris.at(1).size(), 12u);  // the two slivers at the merged corner dropped
    io::TriangleMesh back;
    std::map<std::array<double, 3>, std::uint32_t> ids;
    for (const auto& tri : tris.at(1)) {
      std::array<std::uint32_t, 3> t{};
      for (int k = 0; k < 3; ++k) {
        const Vec3d& p = tri[size_t(k)];
        EXPECT_TRUE(std::fabs(p[0]) < 0.04 || std::fabs(p[0] - 10) < 0.04) << p[0];
        const auto [it, fresh] =
            ids.emplace(std::array<double, 3>{p[0], p[1], p[2]}, std::uint32_t(ids.size()));
        if (fresh) back.vertices.push_back(p);
        t[size_t(k)] = it->second;
      }
      back.triangles.push_back(t);
    }
    EXPECT_EQ(back.vertices.size(), 8u);
    EXPECT_TRUE(closed_and_oriented(back));
    const io::BBox3 stored = b.stored_bounds();
    EXPECT_NEAR(stored.min[0], 0, 1000.0 / 32767);
  }
  // only the cube could be damaged (two corners within 2 steps): checked once
  EXPECT_EQ(checked, (std::vector<std::size_t>{12}));
  checked.clear();
  {
    io::GlbBuilder b({0, 0, 0}, opt);
    b.add_feature(feature("far", lod::ModelKind::anchor, 1, 0), far);
    b.add_feature(feature("thin", lod::ModelKind::anchor, 1, 0), thin);
    const std::string bytes = b.glb();
    EXPECT_NE(bytes.find("\"EXPONENTIAL\""), std::string::npos);  // the slab stays float
    const auto tris = triangles(io::parse_glb(bytes, "mem.glb"));
    double zmax = 0;
    for (const auto& tri : tris.at(1))
      for (const auto& p : tri) zmax = std::max(zmax, p[2]);
    EXPECT_NEAR(zmax, 0.004, 1000.0 / 32767);
    EXPECT_EQ(tris.at(1).size(), thin.triangles.size());
  }
  // the slab flattened (nothing left), then as EXPONENTIAL floats: valid
  EXPECT_EQ(checked, (std::vector<std::size_t>{0, 12}));
}

// meshopt: the feature id lives in its mesh's position bufferView, the normals
// and the triangles of every mesh of the glb in one compressed bufferView each;
// the reader gets the same models and feature ids as from the plain glb.
TEST(GlbReader, MeshoptSharesViewsAndKeepsTheModels) {
  TriangleMesh far, thin, house;
  add_box(far, 900, 900, 0, 1000, 1000, 10);  // node extent 1000 m: int16
  add_box(thin, 0, 0, 0, 10, 10, 0.004);      // 4 mm slab: stays float
  add_house(house, 10, 8, 6, 3);
  auto write = [&](io::Compression c) {
    io::GlbOptions opt;
    opt.compression = c;
    io::GlbBuilder b({0, 0, 0}, opt);
    b.begin_node("model_0");  // one int16 and one float mesh
    b.add_feature(feature("far", lod::ModelKind::anchor, 1, 0), far);
    b.add_feature(feature("thin", lod::ModelKind::anchor, 1, 0), thin);
    b.begin_node("model_1");  // one int16 mesh
    b.add_feature(feature("house", lod::ModelKind::anchor, 1, 0), house);
    return b.glb();
  };
  const std::string mo = write(io::Compression::meshopt), none = write(io::Compression::none);
  std::uint32_t jlen;
  std::memcpy(&jlen, mo.data() + 12, 4);
  const nlohmann::json j = nlohmann::json::parse(mo.substr(20, jlen));
  ASSERT_EQ(j["meshes"].size(), 3u);
  std::map<std::string, int> modes;  // compressed bufferViews: mode/filter -> count
  for (const auto& bv : j["bufferViews"])
    if (bv.contains("extensions")) {
      const auto& e = bv["extensions"]["EXT_meshopt_compression"];
      ++modes[e["mode"].get<std::string>() + "/" + e.value("filter", "NONE") + "/" +
              std::to_string(e["byteStride"].get<int>())];
    }
  // two int16 meshes (position, padding, float id: 12 bytes), one float
  // mesh (EXPONENTIAL position and id: 16 bytes), the normals and the
  // triangles of all three: 5 compressed bufferViews instead of 12
  EXPECT_EQ(modes, (std::map<std::string, int>{{"ATTRIBUTES/NONE/12", 2},
                                               {"ATTRIBUTES/EXPONENTIAL/16", 1},
                                               {"ATTRIBUTES/OCTAHEDRAL/4", 1},
                                               {"TRIANGLES/NONE/2", 1}}));
  std::set<int> normal_views, index_views;
  for (const auto& mesh : j["meshes"]) {
    EXPECT_FALSE(mesh.contains("name"));  // the node carries it
    for (const auto& p : mesh["primitives"]) {
      EXPECT_FALSE(p.contains("mode"));  // TRIANGLES, the default
      const auto& pos = j["accessors"][p["attributes"]["POSITION"].get<std::size_t>()];
      const auto& fid = j["accessors"][p["attributes"]["_FEATURE_ID_0"].get<std::size_t>()];
      EXPECT_EQ(fid["bufferView"], pos["bufferView"]);
      EXPECT_EQ(fid["byteOffset"], pos["componentType"] == 5122 ? 8 : 12);
      normal_views.insert(
          j["accessors"][p["attributes"]["NORMAL"].get<std::size_t>()]["bufferView"].get<int>());
      index_views.insert(j["accessors"][p["indices"].get<std::size_t>()]["bufferView"].get<int>());
    }
  }
  EXPECT_EQ(normal_views.size(), 1u);
  EXPECT_EQ(index_views.size(), 1u);

  const io::GlbDocument dm = io::parse_glb(mo, "mo.glb"), dn = io::parse_glb(none, "none.glb");
  const auto tm = triangles(dm), tn = triangles(dn);
  ASSERT_EQ(tm.size(), 3u);
  ASSERT_EQ(tn.size(), 3u);
  EXPECT_EQ(tm.at(0).size(), far.triangles.size());
  EXPECT_EQ(tm.at(1).size(), thin.triangles.size());
  EXPECT_EQ(tm.at(2).size(), house.triangles.size());
  // the same corners per feature: within the int16 step of the 1000 m node
  // (far, house) and within 1/256 of it (the float slab)
  const double step = 1000.0 / 32767;
  for (std::int64_t f = 0; f < 3; ++f) {
    std::set<std::array<double, 3>> a, b;
    for (const auto& tri : tm.at(f))
      for (const auto& p : tri) a.insert({p[0], p[1], p[2]});
    for (const auto& tri : tn.at(f))
      for (const auto& p : tri) b.insert({p[0], p[1], p[2]});
    ASSERT_EQ(a.size(), b.size()) << "feature " << f;
    const double tol = f == 1 ? step / 256 : step;
    for (const auto& p : b) {
      double best = 1e9;
      for (const auto& q : a)
        best = std::min(best, std::hypot(p[0] - q[0], p[1] - q[1], p[2] - q[2]));
      EXPECT_LT(best, tol) << "feature " << f;
    }
  }
}

// A shared schema (GlbOptions::schema_uri): the glb refers to it, read_glb
// reads it next to the file; a constant string attribute is an ENUM.
TEST(GlbReader, SchemaByUriAndFewStringsAsEnums) {
  const nlohmann::json a = {{"same", "NL"}, {"own", 1}}, b = {{"same", "NL"}, {"own", 2}};
  io::GlbOptions opt;
  opt.compression = io::Compression::meshopt;
  opt.attributes = io::glb_attribute_schema({&a, &b});
  opt.schema_uri = "../schema.json";
  TriangleMesh box1, box2;
  add_box(box1, 0, 0, 0, 10, 10, 5);
  add_box(box2, 20, 0, 0, 30, 10, 8);
  io::GlbBuilder g({0, 0, 0}, opt);
  io::GlbFeature f1 = feature("b1", lod::ModelKind::anchor, 1, 0), f2 = f1;
  f1.attributes = a;
  f2.building_id = "b2";
  f2.attributes = b;
  g.add_feature(f1, box1);
  g.add_feature(f2, box2);
  const std::string bytes = g.glb();
  EXPECT_NE(bytes.find("\"schemaUri\":\"../schema.json\""), std::string::npos);
  EXPECT_EQ(bytes.find("\"classes\""), std::string::npos);  // not embedded
  const fs::path dir = fs::path(CITYLOD_TEST_TMP) / "glb_schema_uri";
  fs::remove_all(dir);
  fs::create_directories(dir / "tiles");
  {
    std::ofstream(dir / "schema.json") << io::glb_schema(opt);
    std::ofstream(dir / "tiles" / "t.glb", std::ios::binary) << bytes;
  }
  const nlohmann::json schema = nlohmann::json::parse(io::glb_schema(opt));
  const nlohmann::json& props = schema["classes"]["building"]["properties"];
  EXPECT_EQ(props["fp_same"]["type"], "ENUM");
  EXPECT_EQ(schema["enums"]["fp_same"]["values"][0]["name"], "NL");
  EXPECT_EQ(props["fp_own"]["componentType"], "INT64");
  const io::GlbDocument d = io::read_glb((dir / "tiles" / "t.glb").string());
  ASSERT_EQ(d.property_tables.size(), 1u);
  const io::GlbPropertyTable& t = d.property_tables[0];
  EXPECT_EQ(t.strings.at("building_id"), (std::vector<std::string>{"b1", "b2"}));
  EXPECT_EQ(t.numbers.count("fp_own"), 0u);  // INT64: not read, but present in the glb
  EXPECT_EQ(t.strings.at("fp_same"), (std::vector<std::string>{"NL", "NL"}));
  EXPECT_NE(bytes.find("\"fp_own\""), std::string::npos);
  EXPECT_EQ(t.numbers.at("valid"), (std::vector<double>{1, 1}));
  // from memory (no directory): the table has no schema, no error
  EXPECT_NO_THROW(io::parse_glb(bytes, "mem.glb"));
  // the embedded form is the same schema
  opt.schema_uri.clear();
  io::GlbBuilder e({0, 0, 0}, opt);
  e.add_feature(f1, box1);
  const std::string eb = e.glb();
  std::uint32_t jl = 0;
  std::memcpy(&jl, eb.data() + 12, 4);
  EXPECT_EQ(
      nlohmann::json::parse(eb.substr(20, jl))["extensions"]["EXT_structural_metadata"]["schema"],
      schema);
}

// A STRING attribute missing in every feature of a glb: the missing values are
// the noData string NUL, so the column still has characters (a bufferView of 0
// bytes is not valid glTF; the 3D Tiles validator wants byteLength = last offset).
TEST(GlbReader, MissingStringsAreTheNoDataCharacter) {
  const nlohmann::json a = {{"g", "x"}, {"h", "1"}}, b = {{"h", "2"}};
  io::GlbOptions opt;
  opt.attributes = io::glb_attribute_schema({&a, &b});
  ASSERT_EQ(opt.attributes.at(0).name, "g");
  ASSERT_TRUE(opt.attributes.at(0).no_data);
  TriangleMesh box1;
  add_box(box1, 0, 0, 0, 10, 10, 5);
  io::GlbBuilder g({0, 0, 0}, opt);
  io::GlbFeature f = feature("b1", lod::ModelKind::anchor, 1, 0);
  f.attributes = b;
  g.add_feature(f, box1);
  const std::string bytes = g.glb();
  std::uint32_t jl = 0;
  std::memcpy(&jl, bytes.data() + 12, 4);
  const nlohmann::json j = nlohmann::json::parse(bytes.substr(20, jl));
  const auto& meta = j["extensions"]["EXT_structural_metadata"];
  EXPECT_EQ(meta["schema"]["classes"]["building"]["properties"]["fp_g"]["noData"],
            std::string(1, '\0'));
  const auto& col = meta["propertyTables"][0]["properties"]["fp_g"];
  EXPECT_EQ(j["bufferViews"][col["values"].get<std::size_t>()]["byteLength"], 1);
  const io::GlbDocument d = io::parse_glb(bytes, "mem.glb");
  EXPECT_EQ(d.property_tables.at(0).strings.at("fp_g"),
            (std::vector<std::string>{std::string(1, '\0')}));
}

}  // namespace
}  // namespace citylod::test

namespace citylod::test {
namespace {

/// The glb with its JSON chunk changed by `edit` (BIN chunk kept as it is).
std::string edit_glb_json(const std::string& glb,
                          const std::function<void(nlohmann::json&)>& edit) {
  std::uint32_t json_len = 0;
  std::memcpy(&json_len, glb.data() + 12, 4);
  nlohmann::json j = nlohmann::json::parse(glb.substr(20, json_len));
  edit(j);
  std::string js = j.dump();
  while (js.size() % 4) js.push_back(' ');
  const std::string rest = glb.substr(20 + json_len);
  std::string out(12, '\0');
  auto put = [](std::string& s, std::size_t at, std::uint32_t v) { std::memcpy(&s[at], &v, 4); };
  out += std::string(8, '\0') + js + rest;
  put(out, 0, 0x46546C67u);  // "glTF"
  put(out, 4, 2);
  put(out, 8, std::uint32_t(out.size()));
  put(out, 12, std::uint32_t(js.size()));
  put(out, 16, 0x4E4F534Au);  // "JSON"
  return out;
}

}  // namespace

// Found by fuzz_glb: meshoptimizer asserts its preconditions (an abort); the
// reader checks them first and names the file.
TEST(GlbReader, MeshoptParametersAreCheckedBeforeDecoding) {
  io::GlbOptions opt;
  opt.compression = io::Compression::meshopt;
  TriangleMesh box;
  add_box(box, 0, 0, 0, 10, 10, 5);
  io::GlbBuilder b({0, 0, 0}, opt);
  b.add_feature(feature("b", lod::ModelKind::anchor, 1, 0), box);
  const std::string glb = b.glb();
  ASSERT_NO_THROW(io::parse_glb(glb, "ok.glb"));
  auto with = [&](const char* mode, const std::function<void(nlohmann::json&)>& change) {
    return edit_glb_json(glb, [&](nlohmann::json& j) {
      for (auto& bv : j["bufferViews"])
        if (bv.contains("extensions") && bv["extensions"].contains("EXT_meshopt_compression") &&
            bv["extensions"]["EXT_meshopt_compression"]["mode"] == mode)
          change(bv["extensions"]["EXT_meshopt_compression"]);
    });
  };
  const std::vector<std::string> bad = {
      with("TRIANGLES", [](nlohmann::json& e) { e["count"] = e["count"].get<int>() + 1; }),
      with("TRIANGLES", [](nlohmann::json& e) { e["byteStride"] = 3; }),
      with("ATTRIBUTES", [](nlohmann::json& e) { e["byteStride"] = 6; }),
      with("ATTRIBUTES", [](nlohmann::json& e) { e["count"] = 1000000000; }),
  };
  for (std::size_t k = 0; k < bad.size(); ++k) {
    SCOPED_TRACE("edit " + std::to_string(k));
    try {
      io::parse_glb(bad[k], "bad.glb");
      ADD_FAILURE() << "no error";
    } catch (const io::IoError& e) {
      EXPECT_NE(std::string(e.what()).find("bad.glb"), std::string::npos) << e.what();
    }
  }
}

}  // namespace citylod::test
