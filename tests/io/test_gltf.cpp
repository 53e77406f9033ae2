// io::GlbBuilder: container, axes, flat shading, materials, feature ids,
// property table, quantization, determinism.
#include <gtest/gtest.h>

#include "citylod/io/error.hpp"
#include "citylod/io/gltf.hpp"
#include "tiler/test_assemble_support.hpp"

namespace citylod::test {
namespace {

GlbFile parse(const std::string& bytes) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path p = fs::path(CITYLOD_TEST_TMP) / "gltf" / (std::string(info->name()) + ".glb");
  fs::create_directories(p.parent_path());
  io::atomic_write_file(p.string(), bytes);
  return read_glb(p.string());
}

TriangleMesh box(double x0, double y0, double z0, double x1, double y1, double z1) {
  TriangleMesh m;
  add_box(m, x0, y0, z0, x1, y1, z1);
  return m;
}

io::GlbFeature feature(const std::string& id, int index = 0) {
  io::GlbFeature f;
  f.building_id = id;
  f.kind = index % 2 ? lod::ModelKind::interpolation : lod::ModelKind::anchor;
  f.level = 1;
  f.step = 2 + index;
  f.model_index = index;
  f.model_count = 3;
  f.height_m = 7.5;
  f.footprint_area_m2 = 120.25;
  f.error_m = 1.5;
  return f;
}

TEST(Glb, BoxesBecomeFlatShadedFeaturesWithMaterials) {
  const io::Vec3d origin{85000.0, 447000.0, 40.0};
  io::GlbBuilder b(origin);
  b.add_feature(feature("a"), box(85000, 447000, 40, 85010, 447008, 46));
  b.add_feature(feature("b", 1), box(85020, 447000, 40, 85030, 447010, 52));
  EXPECT_EQ(b.feature_count(), 2u);
  EXPECT_EQ(b.triangle_count(), 24u);
  EXPECT_EQ(b.vertex_count(), 48u);  // 6 faces x 4 corners, per box
  const GlbFile g = parse(b.glb());
  EXPECT_EQ(g.json["asset"]["version"], "2.0");
  ASSERT_EQ(g.json["materials"].size(), 3u);
  EXPECT_EQ(g.json["materials"][0]["name"], "wall");
  EXPECT_EQ(g.json["materials"][1]["name"], "roof");
  // Node translation = origin in y-up axes; positions are small.
  const auto& t = g.json["nodes"][0]["translation"];
  EXPECT_EQ(t[0].get<double>(), 85000.0);
  EXPECT_EQ(t[1].get<double>(), 40.0);
  EXPECT_EQ(t[2].get<double>(), -447000.0);
  const auto& prims = g.json["meshes"][0]["primitives"];
  ASSERT_EQ(prims.size(), 3u);  // walls, roofs, bases
  const auto& pos = g.json["accessors"][prims[0]["attributes"]["POSITION"].get<size_t>()];
  for (int k = 0; k < 3; ++k) EXPECT_LE(std::fabs(pos["max"][size_t(k)].get<double>()), 40.0);
  EXPECT_EQ(prims[0]["extensions"]["EXT_mesh_features"]["featureIds"][0]["featureCount"], 2);
  EXPECT_EQ(prims[0]["extensions"]["EXT_mesh_features"]["featureIds"][0]["attribute"], 0);
  // Back in z-up ENU, vertices reproduce the boxes exactly (metre values fit float32).
  io::BBox3 box_a;
  for (const auto& v : glb_vertices(g))
    if (v.feature == 0) box_a.add(io::Vec3d{v.p.x(), v.p.y(), v.p.z()});
  EXPECT_DOUBLE_EQ(box_a.min[0], 85000.0);
  EXPECT_DOUBLE_EQ(box_a.max[1], 447008.0);
  EXPECT_DOUBLE_EQ(box_a.max[2], 46.0);
  // Normals: unit, and the roof primitive's point up (+y in glTF).
  const auto& roof = prims[1];
  EXPECT_EQ(roof["material"], 1);
  const int nacc = roof["attributes"]["NORMAL"];
  const int iacc = roof["indices"];
  for (std::size_t i = 0; i < g.json["accessors"][size_t(iacc)]["count"].get<size_t>(); ++i) {
    const auto v = std::size_t(accessor_value(g, iacc, i, 0));
    EXPECT_NEAR(accessor_value(g, nacc, v, 1), 1.0, 1e-6);
  }
  // Property table.
  const auto& md = g.json["extensions"]["EXT_structural_metadata"];
  EXPECT_EQ(md["schema"]["id"], "citylod");
  EXPECT_EQ(md["schema"]["enums"]["LodKind"]["values"][1]["name"], "interpolation");
  const auto& tab = md["propertyTables"][0];
  EXPECT_EQ(tab["count"], 2);
  const auto& bvs = g.json["bufferViews"];
  for (const auto& [name, p] : tab["properties"].items()) {
    EXPECT_EQ(bvs[p["values"].get<size_t>()].value("byteOffset", 0u) % 8, 0u) << name;
  }
  const auto& ids = bvs[tab["properties"]["building_id"]["values"].get<size_t>()];
  EXPECT_EQ(g.bin.substr(ids.value("byteOffset", 0u), 2), "ab");
  const auto& kind = bvs[tab["properties"]["lod_kind"]["values"].get<size_t>()];
  EXPECT_EQ(int(g.bin[kind.value("byteOffset", 0u) + 1]), 1);
  const auto& ext = g.json["extensionsUsed"];
  EXPECT_EQ(ext.size(), 2u);
}

TEST(Glb, SameCallsGiveSameBytes) {
  auto make = [] {
    io::GlbBuilder b({1, 2, 3});
    b.add_feature(feature("x"), box(0, 0, 0, 5, 5, 5));
    b.begin_node("model_1");
    b.add_feature(feature("x", 1), box(0, 0, 0, 5, 5, 8));
    return b.glb();
  };
  EXPECT_EQ(make(), make());
  const GlbFile g = parse(make());
  EXPECT_EQ(g.json["nodes"].size(), 2u);
  EXPECT_EQ(g.json["nodes"][1]["name"], "model_1");
}

TEST(Glb, QuantizedPositionsStayWithinOneStep) {
  io::GlbOptions o;
  o.quantize = true;
  io::GlbBuilder b({100, 200, 0}, o);
  b.add_feature(feature("q"), box(90, 190, 0, 130, 215, 21.3));
  const io::BBox3 sb = b.stored_bounds();
  const GlbFile g = parse(b.glb());
  EXPECT_EQ(g.json["extensionsRequired"][0], "KHR_mesh_quantization");
  const double step = 30.0 / 32767;
  io::BBox3 got;
  for (const auto& v : glb_vertices(g)) got.add(io::Vec3d{v.p.x(), v.p.y(), v.p.z()});
  EXPECT_NEAR(got.min[0], 90, step);
  EXPECT_NEAR(got.max[1], 215, step);
  EXPECT_NEAR(got.max[2], 21.3, step);
  EXPECT_NEAR(sb.max[2], got.max[2], 1e-5);
}

TEST(Glb, DegenerateTrianglesAreDroppedAndEmptyInputRejected) {
  TriangleMesh m = box(0, 0, 0, 1, 1, 1);
  m.triangles.push_back({0, 0, 1});
  io::GlbBuilder b({0, 0, 0});
  b.add_feature(feature("d"), m);
  EXPECT_EQ(b.triangle_count(), 12u);
  io::GlbBuilder empty({0, 0, 0});
  EXPECT_THROW(empty.glb(), io::IoError);
  TriangleMesh bad = box(0, 0, 0, 1, 1, 1);
  bad.triangles.push_back({0, 1, 99});
  EXPECT_THROW(b.add_feature(feature("e"), bad), io::IoError);
  const io::GlbMeshSize s = io::glb_mesh_size(box(0, 0, 0, 1, 1, 1));
  EXPECT_EQ(s.vertices, 24u);
  EXPECT_EQ(s.triangles, 12u);
}

TEST(Glb, SurfaceClasses) {
  EXPECT_EQ(io::classify_normal({0, 0, 1}), io::SurfaceClass::roof);
  EXPECT_EQ(io::classify_normal({0.7071, 0, 0.7071}), io::SurfaceClass::roof);  // 45 degree roof
  EXPECT_EQ(io::classify_normal({1, 0, 0}), io::SurfaceClass::wall);
  EXPECT_EQ(io::classify_normal({0, 0, -1}), io::SurfaceClass::base);
}

}  // namespace
}  // namespace citylod::test
