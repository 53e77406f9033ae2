#include "citylod/io/reader.hpp"
#include "fixtures.hpp"

using namespace citylod::io;
using namespace citylod::io::test;

namespace {

std::vector<LasPoint> grid(std::size_t n) {
  std::vector<LasPoint> v;
  for (std::size_t i = 0; i < n; ++i) {
    LasPoint p{1000.0 + 0.25 * static_cast<double>(i), 2000.5 - 0.01 * static_cast<double>(i),
               3.0 + static_cast<double>(i % 7), static_cast<std::uint8_t>(i % 4 == 0 ? 6 : 2)};
    p.r = static_cast<std::uint16_t>(i * 256);
    p.g = 65535;
    p.b = 0;
    v.push_back(p);
  }
  return v;
}

}  // namespace

TEST(LasReader, Las12Format1) {
  LasSpec s;
  s.points = grid(100);
  std::string p = write_file("pf1.las", make_las(s));
  EXPECT_EQ(detect_format(p), Format::las);
  FileInfo h = read_header(p);
  EXPECT_EQ(h.version, "1.2");
  EXPECT_EQ(h.las_point_format, 1);
  EXPECT_EQ(h.las_record_length, 28u);
  EXPECT_EQ(h.point_count, 100u);
  EXPECT_TRUE(h.bbox_from_header);
  EXPECT_FALSE(h.has_colors);
  EXPECT_FALSE(h.has_crs());

  PointSet pts = read_points(p);
  ASSERT_EQ(pts.size(), 100u);
  ASSERT_TRUE(pts.has_classes());
  EXPECT_NEAR(pts.positions[10][0], 1002.5, 1e-9);
  EXPECT_NEAR(pts.positions[10][1], 2000.4, 1e-9);
  EXPECT_EQ(pts.classes[8], 6);  // flags in bits 5-7 are masked off
  EXPECT_EQ(pts.classes[9], 2);

  FileInfo info = scan_file(p);
  EXPECT_TRUE(info.scanned);
  EXPECT_FALSE(info.bbox_from_header);
  EXPECT_EQ(info.class_counts.at(6), 25u);
  EXPECT_EQ(info.class_counts.at(2), 75u);
  EXPECT_NEAR(info.bbox.max[0], 1024.75, 1e-9);
}

TEST(LasReader, Las12Format3Rgb16) {
  LasSpec s;
  s.point_format = 3;
  s.extra_bytes = 4;  // record length larger than the format's base size
  s.points = grid(50);
  std::string p = write_file("pf3.las", make_las(s));
  PointSet pts = read_points(p);
  ASSERT_EQ(pts.size(), 50u);
  ASSERT_TRUE(pts.has_colors());
  EXPECT_EQ(pts.colors[7][0], 7);  // 7*256 >> 8
  EXPECT_EQ(pts.colors[7][1], 255);
  FileInfo h = read_header(p);
  EXPECT_EQ(h.las_record_length, 38u);
}

TEST(LasReader, Las14Format6FullClassByteAnd64BitCount) {
  LasSpec s;
  s.minor = 4;
  s.point_format = 6;
  s.points = grid(20);
  s.points[3].cls = 40;  // > 31: only representable in formats 6-10
  s.wkt =
      "COMPD_CS[\"Amersfoort / RD New + NAP height\",PROJCS[\"Amersfoort / RD "
      "New\",GEOGCS[\"Amersfoort\"],"
      "UNIT[\"metre\",1,AUTHORITY[\"EPSG\",\"9001\"]],AUTHORITY[\"EPSG\",\"28992\"]],"
      "VERT_CS[\"NAP "
      "height\",UNIT[\"metre\",1],AUTHORITY[\"EPSG\",\"5709\"]],AUTHORITY[\"EPSG\",\"7415\"]]";
  s.wkt_in_evlr = true;
  std::string p = write_file("pf6.las", make_las(s));
  FileInfo h = read_header(p);
  EXPECT_EQ(h.version, "1.4");
  EXPECT_EQ(h.point_count, 20u);  // legacy count is 0 for pf 6
  EXPECT_EQ(h.epsg, 28992);
  EXPECT_EQ(h.vertical_epsg, 5709);
  EXPECT_EQ(h.crs_name, "Amersfoort / RD New");
  EXPECT_EQ(h.linear_unit, "metre");
  PointSet pts = read_points(p);
  ASSERT_EQ(pts.size(), 20u);
  EXPECT_EQ(pts.classes[3], 40);
  EXPECT_FALSE(pts.has_colors());

  s.point_format = 7;
  s.wkt_in_evlr = false;
  PointSet c = read_points(write_file("pf7.las", make_las(s)));
  ASSERT_TRUE(c.has_colors());
  EXPECT_EQ(c.colors[2][0], 2);
}

TEST(LasReader, OtherPointFormatsAndVersions) {
  for (int pf : {0, 2, 4, 5, 8, 9, 10}) {
    LasSpec s;
    s.minor = pf >= 6 ? 4 : (pf >= 4 ? 3 : 0);
    s.point_format = pf;
    s.points = grid(5);
    std::string p = write_file("pf" + std::to_string(pf) + ".las", make_las(s));
    PointSet pts = read_points(p);
    ASSERT_EQ(pts.size(), 5u) << "pf " << pf;
    EXPECT_NEAR(pts.positions[4][0], 1001.0, 1e-9) << "pf " << pf;
    EXPECT_EQ(pts.classes[4], 6) << "pf " << pf;
    EXPECT_EQ(pts.has_colors(), pf == 2 || pf == 5 || pf == 8 || pf == 10) << "pf " << pf;
  }
}

TEST(LasReader, GeoTiffKeysFeet) {
  LasSpec s;
  s.points = grid(3);
  // version 1.1.0, 4 keys: GTModelType, ProjectedCSType 2992, ProjLinearUnits 9002, VerticalUnits
  // 9003
  s.geokeys = {1, 1, 0, 4, 1024, 0, 1, 1, 3072, 0, 1, 2992, 3076, 0, 1, 9002, 4099, 0, 1, 9003};
  FileInfo h = read_header(write_file("feet.las", make_las(s)));
  EXPECT_TRUE(h.has_crs());
  EXPECT_EQ(h.epsg, 2992);
  EXPECT_EQ(h.linear_unit, "foot");
  EXPECT_DOUBLE_EQ(h.linear_unit_m, 0.3048);
  EXPECT_EQ(h.vertical_unit, "US survey foot");
}

TEST(LasReader, TruncatedAndLyingCounts) {
  LasSpec s;
  s.points = grid(10);
  s.declared = 25;
  std::string p = write_file("lie_more.las", make_las(s));
  std::string w =
      expect_io_error([&] { PointReader::open(p); },
                      "truncated: header declares 25 points but the file holds only 10");
  EXPECT_EQ(w.rfind(p + ": ", 0), 0u);

  s.declared = 4;
  expect_io_error([&] { PointReader::open(write_file("lie_less.las", make_las(s))); },
                  "header declares 4 points but the file holds 10");

  s.declared = 4000000000;
  expect_io_error([&] { PointReader::open(write_file("lie_huge.las", make_las(s))); },
                  "truncated: header declares 4000000000 points but the file holds only 10");

  s.declared = -1;
  std::string bytes = make_las(s);
  bytes.resize(bytes.size() - 30);
  expect_io_error([&] { PointReader::open(write_file("cut.las", bytes)); },
                  "truncated: header declares 10 points but the file holds only 8");

  LasSpec s14;
  s14.minor = 4;
  s14.point_format = 1;
  s14.points = grid(10);
  s14.legacy = 9;
  expect_io_error([&] { PointReader::open(write_file("legacy.las", make_las(s14))); },
                  "legacy point count 9 and 64-bit point count 10 disagree");

  std::string hdr = make_las(s).substr(0, 100);
  expect_io_error([&] { PointReader::open(write_file("short_header.las", hdr)); },
                  "truncated: LAS header");
}

TEST(LasReader, BadHeaderFields) {
  LasSpec s;
  s.points = grid(3);
  s.scale = {0.0, 0.0, 0.0};
  expect_io_error([&] { PointReader::open(write_file("scale0.las", make_las(s))); },
                  "scale factor");
  LasSpec r;
  r.points = grid(3);
  std::string bytes = make_las(r);
  bytes[105] = 10;  // record length 10 < 28
  bytes[106] = 0;
  expect_io_error([&] { PointReader::open(write_file("rl.las", bytes)); },
                  "point record length 10 is smaller");
  bytes = make_las(r);
  bytes[104] = 11;
  expect_io_error([&] { PointReader::open(write_file("pf11.las", bytes)); },
                  "unsupported LAS point format 11");
  bytes = make_las(r);
  bytes[100] = 3;  // 3 VLRs that are not there
  expect_io_error([&] { PointReader::open(write_file("vlr.las", bytes)); }, "VLR #0");
}

TEST(LasReader, LazWithoutLaszipVlrIsRefused) {
  LasSpec s;
  s.points = grid(10);
  s.compressed_bit = true;
  std::string bytes = make_las(s);
  bytes.resize(bytes.size() - 100);  // compressed data is shorter than raw records
  std::string p = write_file("c.laz", bytes);
  EXPECT_EQ(detect_format(p), Format::laz);
  expect_io_error([&] { read_header(p); }, "no laszip VLR");

  // A file merely named .laz (no compression bits, no laszip VLR) is read as LAS.
  s.compressed_bit = false;
  std::string p2 = write_file("plain_named.laz", make_las(s));
  EXPECT_FALSE(read_header(p2).compressed);
  EXPECT_EQ(read_points(p2).size(), 10u);
}
