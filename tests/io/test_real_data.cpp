// The real files in shared/data (skipped with a message when absent).
#include <chrono>

#include "citylod/io/reader.hpp"
#include "fixtures.hpp"

using namespace citylod::io;
using namespace citylod::io::test;

TEST(RealData, CgalBuildingPly) {
  const std::string p = shared("single_building/cgal_building.ply");
  CITYLOD_REQUIRE_SHARED(p);
  FileInfo info = scan_file(p);
  EXPECT_EQ(info.point_count, 100000u);
  EXPECT_TRUE(info.has_normals);
  EXPECT_FALSE(info.has_faces);
  EXPECT_EQ(info.encoding, "ascii");
}

TEST(RealData, Ahn3CroppedLas) {
  const std::string p = shared("delft/ahn3_cropped_2.las");
  CITYLOD_REQUIRE_SHARED(p);
  auto t0 = std::chrono::steady_clock::now();
  FileInfo info = scan_file(p);
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(info.point_count, 208432u);
  EXPECT_EQ(info.las_point_format, 1);
  EXPECT_EQ(info.version, "1.2");
  ASSERT_TRUE(info.class_counts.count(6));
  EXPECT_GT(info.class_counts.at(6), 0u);
  std::uint64_t sum = 0;
  for (const auto& [c, n] : info.class_counts) sum += n;
  EXPECT_EQ(sum, 208432u);
  EXPECT_FALSE(info.has_crs());
  EXPECT_GT(info.bbox.min[0], 84000.0);  // RD New coordinates
  RecordProperty("points_per_second", std::to_string(static_cast<long long>(208432 / s)));
}

TEST(RealData, Ahn3CroppedLaz) {
  const std::string p = shared("delft/ahn3_cropped_2.laz");
  CITYLOD_REQUIRE_SHARED(p);
  FileInfo info = scan_file(p);
  EXPECT_TRUE(info.compressed);
  EXPECT_EQ(info.point_count, 208432u);
  EXPECT_EQ(info.las_point_format, 1);
  EXPECT_TRUE(info.scanned);
  EXPECT_GT(info.class_counts.at(6), 0u);
}

TEST(RealData, AutzenCrsInFeet) {
  const std::string p = shared("las/autzen_trim.las");
  CITYLOD_REQUIRE_SHARED(p);
  FileInfo info = scan_file(p);
  EXPECT_EQ(info.point_count, 110000u);
  EXPECT_EQ(info.las_point_format, 3);
  EXPECT_TRUE(info.has_crs());
  EXPECT_EQ(info.linear_unit, "foot");
  EXPECT_DOUBLE_EQ(info.linear_unit_m, 0.3048);
  EXPECT_NE(info.crs_wkt.find("PROJCS"), std::string::npos);
  EXPECT_NE(info.crs_name.find("Lambert"), std::string::npos);
  EXPECT_TRUE(info.has_colors);
}

TEST(RealData, SampleCLas) {
  const std::string p = shared("las/sample_c.las");
  CITYLOD_REQUIRE_SHARED(p);
  FileInfo info = scan_file(p);
  EXPECT_EQ(info.point_count, 14408u);
  EXPECT_EQ(info.class_counts.at(6), 12525u);
}

TEST(RealData, Easy3dOffMesh) {
  const std::string p = shared("noisy_mesh/easy3d_building.off");
  CITYLOD_REQUIRE_SHARED(p);
  FileInfo info = scan_file(p);
  EXPECT_EQ(info.point_count, 9708u);
  EXPECT_EQ(info.face_count, 19021u);
  TriangleMesh m = read_mesh(p);
  EXPECT_EQ(m.vertices.size(), 9708u);
  EXPECT_EQ(m.triangles.size(), 19021u);
}

TEST(RealData, B9MeshAndTrainingPly) {
  const std::string off = shared("urban_block_b9/b9_mesh.off");
  const std::string ply = shared("urban_block_b9/b9_training.ply");
  CITYLOD_REQUIRE_SHARED(off);
  CITYLOD_REQUIRE_SHARED(ply);
  TriangleMesh m = read_mesh(off);
  EXPECT_EQ(m.vertices.size(), 5951u);
  EXPECT_EQ(m.triangles.size(), 10174u);
  FileInfo info = scan_file(ply);
  EXPECT_EQ(info.point_count, 22300u);
  EXPECT_TRUE(info.has_colors);
  EXPECT_GT(info.bbox.min[0], 596000.0);  // doubles kept exact
}

TEST(RealData, City3dPlyAndFootprintObj) {
  const std::string ply = shared("ahn3_block/city3d_001.ply");
  const std::string obj = shared("ahn3_block/city3d_001_footprint.obj");
  CITYLOD_REQUIRE_SHARED(ply);
  CITYLOD_REQUIRE_SHARED(obj);
  FileInfo info = scan_file(ply);
  EXPECT_EQ(info.point_count, 57379u);
  EXPECT_TRUE(info.has_normals && info.has_colors);
  PolygonMesh fp = read_polygon_mesh(obj);
  EXPECT_EQ(fp.vertices.size(), 60u);
  ASSERT_EQ(fp.faces.size(), 1u);
  EXPECT_EQ(fp.faces[0].size(), 60u);
}

TEST(RealData, Ahn3BuildingLod2) {
  const std::string ply = shared("ahn3_building_lod2/AHN3_13856.ply");
  const std::string obj = shared("ahn3_building_lod2/AHN3_13856.obj");
  CITYLOD_REQUIRE_SHARED(ply);
  CITYLOD_REQUIRE_SHARED(obj);
  EXPECT_EQ(scan_file(ply).point_count, 96488u);
  PolygonMesh m = read_polygon_mesh(obj);
  EXPECT_EQ(m.faces.size(), 2332u);
  EXPECT_GT(m.vertices.size(), 0u);
}
