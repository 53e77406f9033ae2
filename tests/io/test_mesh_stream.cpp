// MeshReader: a mesh streamed in batches (vertices, then faces) gives exactly what the
// whole-file readers give, in every encoding, and fails on the same defects.
#include <array>
#include <cstdint>
#include <vector>

#include "citylod/io/reader.hpp"
#include "citylod/io/writers.hpp"
#include "fixtures.hpp"

using namespace citylod::io;
using namespace citylod::io::test;

namespace {

// A 4 x 3 grid of vertices with a triangle, a quad, an L-shaped (non-convex) hexagon and
// a pentagon, plus normals and colours on every vertex.
const char* kAsciiPolygons =
    "ply\n"
    "format ascii 1.0\n"
    "element vertex 12\n"
    "property double x\nproperty double y\nproperty double z\n"
    "property float nx\nproperty float ny\nproperty float nz\n"
    "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    "element face 4\n"
    "property list uchar int vertex_indices\n"
    "end_header\n"
    "100000.5 450000.25 1 0 0 1 1 2 3\n"
    "100001.5 450000.25 1 0 0 1 4 5 6\n"
    "100002.5 450000.25 1 0 0 1 7 8 9\n"
    "100003.5 450000.25 1 0 0 1 10 11 12\n"
    "100000.5 450001.25 2 0 0 1 13 14 15\n"
    "100001.5 450001.25 2 0 0 1 16 17 18\n"
    "100002.5 450001.25 2 0 0 1 19 20 21\n"
    "100003.5 450001.25 2 0 0 1 22 23 24\n"
    "100000.5 450002.25 3 0 0 1 25 26 27\n"
    "100001.5 450002.25 3 0 0 1 28 29 30\n"
    "100002.5 450002.25 3 0 0 1 31 32 33\n"
    "100003.5 450002.25 3 0 0 1 34 35 36\n"
    "3 0 1 5\n"
    "4 1 2 6 5\n"
    "6 2 3 7 6 10 9\n"
    "5 4 5 9 8 0\n";

/// The same file in binary (double xyz, float normals, uchar colours, list uchar int).
std::string binary_polygons(bool big_endian) {
  Bytes b(big_endian);
  b.str("ply\nformat ");
  b.str(big_endian ? "binary_big_endian" : "binary_little_endian");
  b.str(
      " 1.0\nelement vertex 12\nproperty double x\nproperty double y\nproperty double z\n"
      "property float nx\nproperty float ny\nproperty float nz\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      "element face 4\nproperty list uchar int vertex_indices\nend_header\n");
  for (int i = 0; i < 12; ++i) {
    b.put<double>(100000.5 + i % 4).put<double>(450000.25 + i / 4).put<double>(1 + i / 4);
    b.put<float>(0).put<float>(0).put<float>(1);
    for (int c = 0; c < 3; ++c) b.put<std::uint8_t>(static_cast<std::uint8_t>(3 * i + c + 1));
  }
  const std::vector<std::vector<std::int32_t>> faces{
      {0, 1, 5}, {1, 2, 6, 5}, {2, 3, 7, 6, 10, 9}, {4, 5, 9, 8, 0}};
  for (const auto& f : faces) {
    b.put<std::uint8_t>(static_cast<std::uint8_t>(f.size()));
    for (std::int32_t v : f) b.put<std::int32_t>(v);
  }
  return b.data();
}

struct Streamed {
  PointSet vertices;
  std::vector<std::vector<std::uint32_t>> faces;
  std::vector<std::size_t> batch_sizes;
};

Streamed stream(const std::string& path, std::size_t vertex_batch, std::size_t face_batch) {
  Streamed s;
  auto r = MeshReader::open(path);
  PointSet b;
  while (r->read_vertices(b, vertex_batch) > 0) {
    EXPECT_LE(b.size(), vertex_batch);
    s.vertices.append(b);
  }
  FaceBatch fb;
  while (std::size_t n = r->read_faces(fb, face_batch)) {
    EXPECT_EQ(fb.size(), n);
    s.batch_sizes.push_back(n);
    for (std::size_t i = 0; i < fb.size(); ++i)
      s.faces.emplace_back(fb.face(i), fb.face(i) + fb.face_size(i));
  }
  EXPECT_EQ(r->read_faces(fb, face_batch), 0u);  // stays at the end
  return s;
}

std::vector<std::array<std::uint32_t, 3>> triangulate(const Streamed& s) {
  std::vector<std::array<std::uint32_t, 3>> out;
  std::vector<Vec3d> corners;
  for (const auto& f : s.faces) {
    corners.clear();
    for (std::uint32_t v : f) corners.push_back(s.vertices.positions[v]);
    triangulate_face(corners.data(), f.data(), f.size(), out);
  }
  return out;
}

}  // namespace

TEST(MeshReader, PlyInBatchesEqualsTheWholeReadInEveryEncoding) {
  const std::vector<std::string> paths{write_file("poly_ascii.ply", kAsciiPolygons),
                                       write_file("poly_le.ply", binary_polygons(false)),
                                       write_file("poly_be.ply", binary_polygons(true))};
  const std::vector<std::vector<std::uint32_t>> faces{
      {0, 1, 5}, {1, 2, 6, 5}, {2, 3, 7, 6, 10, 9}, {4, 5, 9, 8, 0}};
  // the L (2 3 7 6 10 9) is not convex: ear clipping, not a fan
  const std::vector<std::array<std::uint32_t, 3>> tris{{0, 1, 5}, {1, 2, 6}, {1, 6, 5},  {2, 3, 7},
                                                       {2, 7, 6}, {9, 2, 6}, {6, 10, 9}, {4, 5, 9},
                                                       {4, 9, 8}, {4, 8, 0}};
  for (const auto& p : paths) {
    const TriangleMesh whole = read_mesh(p);
    EXPECT_EQ(whole.triangles, tris) << p;
    for (std::size_t fbatch : {1u, 3u, 1000u}) {
      const Streamed s = stream(p, 5, fbatch);
      EXPECT_EQ(s.faces, faces) << p;
      EXPECT_EQ(s.faces, read_polygon_mesh(p).faces) << p;
      EXPECT_EQ(s.vertices.positions, whole.vertices) << p;
      EXPECT_EQ(s.vertices.normals, whole.normals) << p;
      EXPECT_EQ(s.vertices.colors, whole.colors) << p;
      EXPECT_EQ(triangulate(s), whole.triangles) << p;
      const std::vector<std::size_t> sizes =
          fbatch == 1
              ? std::vector<std::size_t>{1, 1, 1, 1}
              : (fbatch == 3 ? std::vector<std::size_t>{3, 1} : std::vector<std::size_t>{4});
      EXPECT_EQ(s.batch_sizes, sizes) << p;
    }
    EXPECT_EQ(scan_file(p).max_face_corners, 6u) << p;
  }
}

TEST(MeshReader, FacesWithoutReadingTheVerticesFirst) {
  const std::string p = write_file("poly_skip.ply", binary_polygons(false));
  auto r = MeshReader::open(p);
  FaceBatch fb;
  ASSERT_EQ(r->read_faces(fb, 2), 2u);
  EXPECT_EQ(fb.corners, (std::vector<std::uint32_t>{0, 1, 5, 1, 2, 6, 5}));
  EXPECT_EQ(fb.offsets, (std::vector<std::size_t>{0, 3, 7}));
  PointSet b;
  EXPECT_EQ(r->read_vertices(b, 100), 0u);
}

TEST(MeshReader, ObjAndOffInBatchesEqualTheWholeRead) {
  // relative indices, a forward reference, vn on corners, v/vt/vn forms
  const std::string obj = write_file("stream.obj",
                                     "v 0 0 0\nv 1 0 0\nv 1 1 0\n"
                                     "vn 0 0 1\n"
                                     "f -3//1 -2//1 -1//1\n"
                                     "f 1 3 4\n"
                                     "v 0 1 0\n"
                                     "v 2 0 0\n"
                                     "f 2/1/1 5/1/1 3/1/1 -5\n");
  const std::string off = write_file("stream.off",
                                     "OFF\n5 3 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n"
                                     "3 0 1 2\n3 0 2 3\n4 1 4 2 0\n");
  const std::vector<std::vector<std::uint32_t>> faces{{0, 1, 2}, {0, 2, 3}, {1, 4, 2, 0}};
  for (const auto& p : {obj, off}) {
    const TriangleMesh whole = read_mesh(p);
    for (std::size_t fbatch : {1u, 2u}) {
      const Streamed s = stream(p, 2, fbatch);
      EXPECT_EQ(s.faces, faces) << p;
      EXPECT_EQ(s.faces, read_polygon_mesh(p).faces) << p;
      EXPECT_EQ(s.vertices.positions, whole.vertices) << p;
      EXPECT_TRUE(s.vertices.normals.empty()) << p;  // OBJ: vn belong to corners
      EXPECT_EQ(triangulate(s), whole.triangles) << p;
    }
  }
  auto r = MeshReader::open(obj);
  FaceBatch fb;
  r->read_faces(fb, 1);
  EXPECT_EQ(r->info().point_count, 5u);  // OBJ counts known once the faces started
  EXPECT_EQ(r->info().face_count, 3u);
  EXPECT_EQ(r->info().max_face_corners, 4u);
}

// The streamed read fails where the whole read fails, with the same one-line messages.
TEST(MeshReader, DefectsGiveOneLineNamingTheFile) {
  auto drain = [](const std::string& p) {
    auto r = MeshReader::open(p);
    PointSet b;
    while (r->read_vertices(b, 4) > 0) {
    }
    FaceBatch fb;
    while (r->read_faces(fb, 1) > 0) {
    }
  };
  std::string bad = kAsciiPolygons;
  bad.replace(bad.find("5 4 5 9 8 0"), 11, "5 4 5 9 8 12");
  const std::string pb = write_file("stream_bad_index.ply", bad);
  std::string w =
      expect_io_error([&] { drain(pb); }, "face #3 references vertex 12 but the file has only 12");
  EXPECT_EQ(w.rfind(pb, 0), 0u);

  std::string nan = kAsciiPolygons;
  nan.replace(nan.find("100002.5 450001.25 2"), 20, "100002.5 nan 2");
  expect_io_error([&] { drain(write_file("stream_nan.ply", nan)); }, "NaN coordinate at point #6");

  std::string cut = binary_polygons(false);
  cut.resize(cut.size() - 10);  // inside the last face
  expect_io_error([&] { drain(write_file("stream_cut.ply", cut)); },
                  "truncated: header declares 4 faces but the file holds only 3");
  std::string cut_ascii = kAsciiPolygons;
  cut_ascii.resize(cut_ascii.find("5 4 5 9 8 0"));
  expect_io_error([&] { drain(write_file("stream_cut_ascii.ply", cut_ascii)); },
                  "truncated: header declares 4 faces but the file holds only 3");
  expect_io_error(
      [&] { drain(write_file("stream_trailing.ply", std::string(kAsciiPolygons) + "3 0 1 2\n")); },
      "trailing data after the elements the header declares");

  expect_io_error([&] { drain(write_file("stream_bad.obj", "v 0 0 0\nv 1 0 0\nf 1 2 3\n")); },
                  "references vertex 3 but the file has only 2 vertices");
  expect_io_error([&] { drain(write_file("stream_zero.obj", "v 0 0 0\nf 0 1 1\n")); },
                  "(OBJ indices start at 1)");
  expect_io_error([&] { drain(write_file("stream_points.obj", "v 0 0 0\nv 1 0 0\n")); },
                  "OBJ file has no faces");
  expect_io_error([&] { MeshReader::open(write_file("stream_points.xyz", "1 2 3\n4 5 6\n")); },
                  "hold no faces");
}
