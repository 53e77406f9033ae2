// Format detection and the failure modes every reader shares.
#include <filesystem>

#include "citylod/io/reader.hpp"
#include "fixtures.hpp"

using namespace citylod::io;
using namespace citylod::io::test;

TEST(Detect, MagicBytesBeatExtension) {
  EXPECT_EQ(detect_format(write_file("ply_named.txt", "ply\nformat ascii 1.0\nend_header\n")),
            Format::ply);
  EXPECT_EQ(detect_format(write_file("off_named.dat", "OFF\n0 0 0\n")), Format::off);
  EXPECT_EQ(detect_format(write_file("coff_named.dat", "COFF\n0 0 0\n")), Format::off);
  EXPECT_EQ(detect_format(write_file("obj_named.dat", "# c\nv 1 2 3\n")), Format::obj);
  EXPECT_EQ(detect_format(write_file("xyz_named.dat", "1 2 3\n")), Format::xyz);
  EXPECT_EQ(detect_format(write_file("las_named.ply", "LASF" + std::string(300, '\0'))),
            Format::las);
  EXPECT_EQ(detect_format(write_file("notes.md", "# Title\n\nSome text.\n")), Format::unknown);
}

TEST(Errors, MissingFileDirectoryEmptyUnknown) {
  expect_io_error([] { PointReader::open("/nonexistent/dir/missing.ply"); },
                  "/nonexistent/dir/missing.ply: no such file");
  // A directory this test makes itself: the test may be the first to run.
  const std::string dir = std::filesystem::path(tmp_path("x")).parent_path().string();
  expect_io_error([&] { PointReader::open(dir); }, "is a directory");
  for (const char* name :
       {"empty.ply", "empty.las", "empty.xyz", "empty.obj", "empty.off", "empty.bin"})
    expect_io_error([&] { PointReader::open(write_file(name, "")); }, "empty file");
  std::string md =
      write_file("README.md", "# Real test data\n\nReal scans and models of buildings.\n");
  expect_io_error([&] { PointReader::open(md); },
                  md + ": not a point cloud or mesh file (unrecognised format)");
  std::string bin = write_file("random.bin", std::string("\x01\x02\x00\x7f garbage", 12));
  expect_io_error([&] { scan_file(bin); }, "unrecognised format");
  // Wrong content behind a known extension: the reader says what is wrong.
  expect_io_error([&] { PointReader::open(write_file("text.ply", "hello\n")); }, "not a PLY file");
  expect_io_error([&] { PointReader::open(write_file("text.las", "hello\n")); }, "not a LAS file");
}

TEST(Errors, GarbageNeverCrashes) {
  // Deterministic pseudo-random mutations of valid files: every outcome is
  // either success or an IoError, never a crash (run under ASan/UBSan too).
  LasSpec s;
  for (int i = 0; i < 20; ++i) s.points.push_back({1.0 * i, 2.0, 3.0, 2});
  const std::string las = make_las(s);
  const std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float "
      "y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n" +
      std::string(36, '\0') +
      std::string("\x03\x00\x00\x00\x00\x01\x00\x00\x00\x02\x00\x00\x00", 13);
  std::uint32_t seed = 12345;
  auto rnd = [&] {
    seed = seed * 1664525u + 1013904223u;
    return seed >> 8;
  };
  int ok = 0, errors = 0;
  for (const std::string* base : {&las, &ply}) {
    for (int trial = 0; trial < 300; ++trial) {
      std::string b = *base;
      int edits = 1 + static_cast<int>(rnd() % 4);
      for (int e = 0; e < edits; ++e) b[rnd() % b.size()] = static_cast<char>(rnd() & 0xFF);
      if (rnd() % 3 == 0) b.resize(rnd() % b.size());
      std::string p = write_file(base == &las ? "fuzz.las" : "fuzz.ply", b);
      try {
        scan_file(p);
        read_points(p);
        ++ok;
      } catch (const IoError&) {
        ++errors;
      }
    }
  }
  EXPECT_EQ(ok + errors, 600);
}
