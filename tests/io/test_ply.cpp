#include <cmath>

#include "citylod/io/reader.hpp"
#include "citylod/io/writers.hpp"
#include "fixtures.hpp"

using namespace citylod::io;
using namespace citylod::io::test;

namespace {

const char* kAsciiMesh =
    "ply\n"
    "format ascii 1.0\n"
    "comment a unit square with two triangles and one quad\n"
    "element vertex 5\n"
    "property float x\nproperty float y\nproperty float z\n"
    "property float nx\nproperty float ny\nproperty float nz\n"
    "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    "property int segment_index\n"
    "element face 2\n"
    "property list uchar int vertex_indices\n"
    "end_header\n"
    "0 0 0 0 0 1 255 0 0 1\n"
    "1 0 0 0 0 1 0 255 0 1\n"
    "1 1 0 0 0 1 0 0 255 1\n"
    "0 1 0 0 0 1 10 20 30 2\n"
    "0.5 0.5 1 0 0 1 1 2 3 2\n"
    "4 0 1 2 3\n"
    "3 0 1 4\n";

// Binary PLY with shuffled property order and mixed types, preceded by an
// element that must be skipped.
std::string binary_ply(bool big_endian, std::size_t n, std::size_t declared,
                       bool with_faces = false) {
  Bytes b(big_endian);
  b.str("ply\nformat ");
  b.str(big_endian ? "binary_big_endian" : "binary_little_endian");
  b.str(" 1.0\nelement camera 2\nproperty float fov\nproperty list uchar int tags\n");
  b.str("element vertex " + std::to_string(declared) + "\n");
  b.str(
      "property uchar red\nproperty double x\nproperty short label\nproperty double y\nproperty "
      "float z\n");
  b.str("property uchar green\nproperty uchar blue\nproperty uint classification\n");
  if (with_faces)
    b.str("element face 1\nproperty uchar flags\nproperty list uchar uint vertex_index\n");
  b.str("end_header\n");
  // camera records: fov + list of tags
  b.put<float>(60.0f).put<std::uint8_t>(2).put<std::int32_t>(1).put<std::int32_t>(2);
  b.put<float>(45.0f).put<std::uint8_t>(0);
  for (std::size_t i = 0; i < n; ++i) {
    b.put<std::uint8_t>(static_cast<std::uint8_t>(i));
    b.put<double>(100000.25 + static_cast<double>(i));
    b.put<std::int16_t>(-3);
    b.put<double>(450000.5 - static_cast<double>(i));
    b.put<float>(static_cast<float>(i) * 0.5f);
    b.put<std::uint8_t>(200).put<std::uint8_t>(7);
    b.put<std::uint32_t>(static_cast<std::uint32_t>(i % 3 == 0 ? 6 : 2));
  }
  if (with_faces)
    b.put<std::uint8_t>(0)
        .put<std::uint8_t>(3)
        .put<std::uint32_t>(0)
        .put<std::uint32_t>(1)
        .put<std::uint32_t>(2);
  return b.data();
}

}  // namespace

TEST(PlyReader, AsciiPointsAttributesAndMesh) {
  std::string p = write_file("ascii_mesh.ply", kAsciiMesh);
  EXPECT_EQ(detect_format(p), Format::ply);
  PointSet pts = read_points(p);
  ASSERT_EQ(pts.size(), 5u);
  ASSERT_TRUE(pts.has_normals());
  ASSERT_TRUE(pts.has_colors());
  EXPECT_FALSE(pts.has_classes());
  EXPECT_DOUBLE_EQ(pts.positions[4][0], 0.5);
  EXPECT_FLOAT_EQ(pts.normals[2][2], 1.0f);
  EXPECT_EQ(pts.colors[3][1], 20);

  FileInfo info = scan_file(p);
  EXPECT_EQ(info.format_name, "PLY");
  EXPECT_EQ(info.encoding, "ascii");
  EXPECT_EQ(info.point_count, 5u);
  EXPECT_EQ(info.face_count, 2u);
  EXPECT_TRUE(info.has_faces);
  ASSERT_EQ(info.extra_attributes.size(), 1u);
  EXPECT_EQ(info.extra_attributes[0], "segment_index");
  EXPECT_DOUBLE_EQ(info.bbox.max[2], 1.0);

  PolygonMesh pm = read_polygon_mesh(p);
  ASSERT_EQ(pm.faces.size(), 2u);
  EXPECT_EQ(pm.faces[0].size(), 4u);
  TriangleMesh tm = read_mesh(p);
  ASSERT_EQ(tm.triangles.size(), 3u);  // quad -> 2, triangle -> 1
  EXPECT_EQ(tm.triangles[1], (std::array<std::uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(tm.normals.size(), 5u);
}

TEST(PlyReader, BinaryBothEndiannessesAnyPropertyOrder) {
  for (bool be : {false, true}) {
    std::string p = write_file(be ? "be.ply" : "le.ply", binary_ply(be, 10, 10, true));
    PointSet pts = read_points(p);
    ASSERT_EQ(pts.size(), 10u) << (be ? "big" : "little");
    EXPECT_DOUBLE_EQ(pts.positions[3][0], 100003.25);
    EXPECT_DOUBLE_EQ(pts.positions[3][1], 449997.5);
    EXPECT_DOUBLE_EQ(pts.positions[3][2], 1.5);
    ASSERT_TRUE(pts.has_colors());
    EXPECT_EQ(pts.colors[5][0], 5);
    EXPECT_EQ(pts.colors[5][1], 200);
    EXPECT_EQ(pts.colors[5][2], 7);
    ASSERT_TRUE(pts.has_classes());
    EXPECT_EQ(pts.classes[3], 6);
    EXPECT_EQ(pts.classes[4], 2);
    FileInfo info = scan_file(p);
    EXPECT_EQ(info.point_count, 10u);
    EXPECT_EQ(info.face_count, 1u);
    TriangleMesh m = read_mesh(p);
    ASSERT_EQ(m.triangles.size(), 1u);
    EXPECT_EQ(m.triangles[0], (std::array<std::uint32_t, 3>{0, 1, 2}));
  }
}

TEST(PlyReader, StreamsInBoundedBatches) {
  std::string p = write_file("batches.ply", binary_ply(false, 1000, 1000));
  auto r = PointReader::open(p);
  EXPECT_EQ(r->info().point_count, 1000u);
  PointSet batch;
  std::size_t total = 0, calls = 0;
  while (std::size_t n = r->read(batch, 7)) {
    EXPECT_LE(n, 7u);
    EXPECT_EQ(batch.size(), n);
    EXPECT_TRUE(batch.consistent());
    EXPECT_DOUBLE_EQ(batch.positions[0][0], 100000.25 + static_cast<double>(total));
    total += n;
    ++calls;
  }
  EXPECT_EQ(total, 1000u);
  EXPECT_EQ(calls, 143u);
  EXPECT_EQ(r->points_read(), 1000u);
  EXPECT_DOUBLE_EQ(r->progress(), 1.0);
}

TEST(PlyReader, TruncatedBinary) {
  std::string p = write_file("trunc.ply", binary_ply(false, 50, 100));
  std::string w =
      expect_io_error([&] { PointReader::open(p); },
                      "truncated: header declares 100 points but the file holds only 50");
  EXPECT_EQ(w.rfind(p, 0), 0u) << "message starts with the file name";
}

TEST(PlyReader, TruncatedBinaryCutMidRecord) {
  std::string bytes = binary_ply(false, 20, 20);
  bytes.resize(bytes.size() - 10);
  std::string p = write_file("trunc_mid.ply", bytes);
  expect_io_error([&] { PointReader::open(p); },
                  "truncated: header declares 20 points but the file holds only 19");
}

TEST(PlyReader, TruncatedAscii) {
  std::string s = kAsciiMesh;
  s = s.substr(0, s.find("0 1 0 0 0 1 10"));  // keeps 3 vertices
  std::string p = write_file("trunc_ascii.ply", s);
  expect_io_error([&] { read_points(p); },
                  "truncated: header declares 5 points but the file holds only 3");
}

TEST(PlyReader, HeaderCountTooSmallIsDetectedByScan) {
  std::string p = write_file("lying_small.ply", binary_ply(false, 30, 20));
  expect_io_error([&] { scan_file(p); }, "header counts lie");
  std::string a =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "end_header\n1 2 3\n4 5 6\n7 8 9\n";
  std::string pa = write_file("lying_small_ascii.ply", a);
  expect_io_error([&] { scan_file(pa); }, "header counts lie");
}

TEST(PlyReader, HugeDeclaredCountDoesNotAllocate) {
  std::string bytes = binary_ply(false, 3, 3);
  auto pos = bytes.find("element vertex 3");
  bytes.replace(pos, 16, "element vertex 18446744073709551615");
  std::string p = write_file("huge.ply", bytes);
  expect_io_error([&] { PointReader::open(p); },
                  "truncated: header declares 18446744073709551615 points");
}

TEST(PlyReader, NanCoordinate) {
  std::string s =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "end_header\n1 2 3\n4 5 6\n7 nan 9\n";
  std::string p = write_file("nan.ply", s);
  expect_io_error([&] { read_points(p); }, "NaN coordinate at point #2");
  Bytes b;
  b.str(
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty double x\nproperty double "
      "y\n"
      "property double z\nend_header\n");
  b.put<double>(1).put<double>(2).put<double>(3).put<double>(INFINITY).put<double>(0).put<double>(
      0);
  std::string pb = write_file("inf.ply", b.data());
  expect_io_error([&] { read_points(pb); }, "infinite coordinate at point #1");
}

TEST(PlyReader, FaceIndexOutOfRange) {
  std::string s = kAsciiMesh;
  s.replace(s.find("3 0 1 4"), 7, "3 0 1 9");
  std::string p = write_file("bad_index.ply", s);
  expect_io_error([&] { read_mesh(p); },
                  "face #1 references vertex 9 but the file has only 5 vertices");
  expect_io_error([&] { scan_file(p); }, "face #1 references vertex 9");
  std::string neg = kAsciiMesh;
  neg.replace(neg.find("3 0 1 4"), 7, "3 0 -1 4");
  std::string pn = write_file("neg_index.ply", neg);
  expect_io_error([&] { read_mesh(pn); }, "references vertex -1");
}

TEST(PlyReader, MalformedHeaders) {
  expect_io_error(
      [&] {
        PointReader::open(write_file("noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"));
      },
      "no end_header");
  expect_io_error(
      [&] {
        PointReader::open(write_file("nox.ply",
                                     "ply\nformat ascii 1.0\nelement vertex 1\nproperty float y\n"
                                     "property float z\nend_header\n1 2\n"));
      },
      "lacks x, y or z");
  expect_io_error(
      [&] {
        PointReader::open(
            write_file("badtype.ply",
                       "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\n"
                       "end_header\n"));
      },
      "unknown PLY property type");
  expect_io_error(
      [&] {
        PointReader::open(
            write_file("badfmt.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"));
      },
      "unknown PLY format");
  expect_io_error(
      [&] {
        read_mesh(write_file("pc.ply",
                             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                             "property float y\nproperty float z\nend_header\n1 2 3\n"));
      },
      "no face element");
}

// ply_bytes is what write_ply writes: binary with every attribute, and ASCII.
TEST(PlyWriter, BytesInMemoryAreTheFileBytes) {
  PointSet ps;
  for (int i = 0; i < 3000; ++i) {  // more than one write buffer in ASCII
    ps.positions.push_back({100000.25 + i, 450000.5 - i, 0.125 * i});
    ps.normals.push_back({0.0f, 0.6f, 0.8f});
    ps.colors.push_back({std::uint8_t(i), 20, 30});
    ps.classes.push_back(std::uint8_t(i % 7));
  }
  for (bool binary : {true, false}) {
    PlyWriteOptions o;
    o.binary = binary;
    o.comment = "a comment";
    const std::string path = tmp_path(binary ? "b.ply" : "a.ply");
    write_ply(path, ps, o);
    const std::string file = read_file(path);
    EXPECT_EQ(ply_bytes(path, ps, o), file) << (binary ? "binary" : "ascii");
    EXPECT_GT(file.size(), 3000u * 25);
  }
}
