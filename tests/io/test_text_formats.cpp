// OBJ, OFF and XYZ/PTS readers.
#include "citylod/io/reader.hpp"
#include "fixtures.hpp"

using namespace citylod::io;
using namespace citylod::io::test;

TEST(ObjReader, VertexFormsNegativeIndicesAndPolygons) {
  std::string s =
      "# cube corner\n"
      "mtllib x.mtl\no thing\n"
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
      "vt 0 0\nvn 0 0 1\n"
      "f 1 2 3\n"
      "f 1/1 3/1 4/1\n"
      "f 1/1/1 2/1/1 3/1/1\n"
      "f 1//1 3//1 4//1\n"
      "v 0.5 0.5 2\n"
      "f -5 -4 -1\n"
      "f 1 2 3 4 5\n";
  std::string p = write_file("forms.obj", s);
  EXPECT_EQ(detect_format(p), Format::obj);
  PolygonMesh m = read_polygon_mesh(p);
  ASSERT_EQ(m.vertices.size(), 5u);
  ASSERT_EQ(m.faces.size(), 6u);
  EXPECT_EQ(m.faces[4], (std::vector<std::uint32_t>{0, 1, 4}));
  EXPECT_EQ(m.faces[5].size(), 5u);
  TriangleMesh t = read_mesh(p);
  EXPECT_EQ(t.triangles.size(), 4u + 1u + 3u);
  FileInfo info = scan_file(p);
  EXPECT_EQ(info.point_count, 5u);
  EXPECT_EQ(info.face_count, 6u);
  PointSet pts = read_points(p);
  EXPECT_EQ(pts.size(), 5u);
}

TEST(ObjReader, BadIndices) {
  std::string p = write_file("oob.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n");
  expect_io_error([&] { read_mesh(p); },
                  "face #0 references vertex 4 but the file has only 3 vertices");
  expect_io_error([&] { scan_file(p); }, "face #0 references vertex 4");
  std::string pn = write_file("oobneg.obj", "v 0 0 0\nv 1 0 0\nf -1 -2 -3\n");
  expect_io_error([&] { read_mesh(pn); }, "references vertex -3 but the file has only 2 vertices");
  std::string pz = write_file("zero.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 0 1 2\n");
  expect_io_error([&] { read_mesh(pz); }, "OBJ indices start at 1");
  std::string pnan = write_file("nan.obj", "v 0 0 0\nv 1 nan 0\n");
  expect_io_error([&] { read_points(pnan); }, "NaN coordinate at point #1");
  std::string pts_only = write_file("pts.obj", "v 0 0 0\nv 1 0 0\n");
  expect_io_error([&] { read_mesh(pts_only); }, "no faces");
}

TEST(OffReader, VariantsCommentsAndCountsOnFirstLine) {
  std::string p = write_file("tet.off",
                             "OFF\n# a tetrahedron\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                             "3 0 2 1\n3 0 1 3\n3 1 2 3\n3 2 0 3\n");
  EXPECT_EQ(detect_format(p), Format::off);
  TriangleMesh m = read_mesh(p);
  EXPECT_EQ(m.vertices.size(), 4u);
  EXPECT_EQ(m.triangles.size(), 4u);
  FileInfo info = scan_file(p);
  EXPECT_EQ(info.point_count, 4u);
  EXPECT_EQ(info.face_count, 4u);

  std::string pn =
      write_file("n.off", "NOFF 3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n");
  PointSet a = read_points(pn);
  ASSERT_TRUE(a.has_normals());
  EXPECT_FLOAT_EQ(a.normals[1][2], 1.0f);

  std::string pc =
      write_file("c.off",
                 "COFF\n3 1 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n0 1 0 0 0 255 255\n"
                 "4 0 1 2 0\n");
  // A quad whose last corner repeats vertex 0: still valid.
  PointSet c = read_points(pc);
  ASSERT_TRUE(c.has_colors());
  EXPECT_EQ(c.colors[1][1], 255);
  PolygonMesh pm = read_polygon_mesh(pc);
  EXPECT_EQ(pm.faces[0].size(), 4u);
}

TEST(OffReader, Errors) {
  expect_io_error([&] { read_points(write_file("t.off", "OFF\n5 0 0\n0 0 0\n1 1 1\n")); },
                  "truncated: header declares 5 points but the file holds only 2");
  expect_io_error(
      [&] { read_mesh(write_file("i.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n")); },
      "face #0 references vertex 3 but the file has only 3 vertices");
  expect_io_error(
      [&] { read_mesh(write_file("f.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")); },
      "truncated: header declares 2 faces but the file holds only 1");
  expect_io_error([&] { read_points(write_file("c.off", "OFF\nthree 1 0\n")); }, "bad OFF counts");
  expect_io_error([&] { read_points(write_file("h.off", "OFF\n99999999999 1 0\n0 0 0\n")); },
                  "truncated: header declares 99999999999 points but the file holds only 1");
  expect_io_error([&] { read_points(write_file("inf.off", "OFF\n2 0 0\n0 0 0\n1 inf 0\n")); },
                  "infinite coordinate at point #1");
}

TEST(XyzReader, Layouts) {
  std::string p = write_file("a.xyz", "# comment\n1 2 3\n4 5 6\n\n7 8 9\n");
  EXPECT_EQ(detect_format(p), Format::xyz);
  PointSet a = read_points(p);
  ASSERT_EQ(a.size(), 3u);
  EXPECT_FALSE(a.has_normals());
  EXPECT_DOUBLE_EQ(a.positions[2][2], 9.0);

  PointSet n = read_points(write_file("n.xyz", "1 2 3 0 0 1\n4 5 6 0.6 0.8 0\n"));
  ASSERT_TRUE(n.has_normals());
  EXPECT_FALSE(n.has_colors());
  EXPECT_FLOAT_EQ(n.normals[1][1], 0.8f);

  PointSet c = read_points(write_file("c.xyz", "1,2,3,255,128,0\n4,5,6,10,20,30\n"));
  ASSERT_TRUE(c.has_colors());
  EXPECT_FALSE(c.has_normals());
  EXPECT_EQ(c.colors[0][1], 128);

  PointSet pts =
      read_points(write_file("l.pts", "2\n1 2 3 -1200 10 20 30\n4 5 6 -1100 40 50 60\n"));
  ASSERT_EQ(pts.size(), 2u);
  ASSERT_TRUE(pts.has_colors());
  EXPECT_EQ(pts.colors[1][2], 60);

  PointSet nine = read_points(write_file("nine.xyz", "1 2 3 0 0 1 200 100 50\n"));
  ASSERT_TRUE(nine.has_normals() && nine.has_colors());
  EXPECT_EQ(nine.colors[0][0], 200);

  PointSet hdr = read_points(write_file("h.csv", "X,Y,Z\n1,2,3\n"));
  EXPECT_EQ(hdr.size(), 1u);

  FileInfo info = scan_file(p);
  EXPECT_EQ(info.point_count, 3u);
  EXPECT_DOUBLE_EQ(info.bbox.min[0], 1.0);
}

TEST(XyzReader, Errors) {
  expect_io_error([&] { read_points(write_file("t.pts", "5\n1 2 3\n4 5 6\n")); },
                  "truncated: header declares 5 points but the file holds only 2");
  expect_io_error([&] { read_points(write_file("nan.xyz", "1 2 3\nnan 1 1\n")); },
                  "NaN coordinate at point #1");
  expect_io_error([&] { read_points(write_file("short.xyz", "1 2 3\n4 5\n")); },
                  "line 2: expected 3 values, found 2");
  expect_io_error([&] { read_points(write_file("word.xyz", "1 2 3\n4 five 6\n")); },
                  "invalid number 'five' at line 2");
}
