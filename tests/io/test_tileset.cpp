// io::Tileset writer: required fields, boxes, rounding, errors.
#include <gtest/gtest.h>

#include "citylod/io/error.hpp"
#include "citylod/io/tileset.hpp"
#include "tiler/test_assemble_support.hpp"

namespace citylod::test {
namespace {

io::BBox3 bbox(double x0, double y0, double z0, double x1, double y1, double z1) {
  io::BBox3 b;
  b.add(io::Vec3d{x0, y0, z0});
  b.add(io::Vec3d{x1, y1, z1});
  return b;
}

TEST(TilesetJson, BoxFromBBoxContainsItAndIsRoundedOutward) {
  const io::BBox3 b = bbox(-12.3456789, 0.1, 3.0000004, 100.0000001, 7.77777777, 9.5);
  const io::TileBox t = io::TileBox::from_bbox(b);
  const io::BBox3 back = t.to_bbox();
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE(back.min[size_t(k)], b.min[size_t(k)]);
    EXPECT_GE(back.max[size_t(k)], b.max[size_t(k)]);
    EXPECT_LT(back.max[size_t(k)] - b.max[size_t(k)], 1e-5);
  }
  EXPECT_EQ(t.v[4], 0.0);  // axis aligned
  EXPECT_THROW(io::TileBox::from_bbox(io::BBox3{}), io::IoError);
}

TEST(TilesetJson, WritesTheRequiredFields) {
  io::Tileset ts;
  ts.geometric_error = 50;
  ts.root.box = io::TileBox::from_bbox(bbox(0, 0, 0, 100, 100, 20));
  ts.root.geometric_error = 10;
  ts.root.refine = "REPLACE";
  ts.root.transform =
      std::array<double, 16>{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 3900000, 300000, 5000000, 1};
  ts.root.content_uri = "tiles/r.glb";
  ts.root.content_box = io::TileBox::from_bbox(bbox(1, 1, 0, 99, 99, 18));
  io::Tile child;
  child.box = io::TileBox::from_bbox(bbox(0, 0, 0, 50, 50, 20));
  child.content_uri = "tiles/r_0.glb";
  ts.root.children.push_back(child);
  const auto j = nlohmann::json::parse(io::tileset_json(ts));
  EXPECT_EQ(j["asset"]["version"], "1.1");
  EXPECT_EQ(j["geometricError"], 50);
  EXPECT_EQ(j["root"]["refine"], "REPLACE");
  EXPECT_EQ(j["root"]["transform"].size(), 16u);
  EXPECT_EQ(j["root"]["boundingVolume"]["box"].size(), 12u);
  EXPECT_EQ(j["root"]["content"]["uri"], "tiles/r.glb");
  EXPECT_TRUE(j["root"]["content"].contains("boundingVolume"));
  EXPECT_FALSE(j["root"]["children"][0].contains("refine"));  // inherited
  EXPECT_EQ(j["root"]["children"][0]["geometricError"], 0);
  EXPECT_EQ(io::tile_count(ts.root), 2u);
  EXPECT_EQ(io::tile_depth(ts.root), 1);
  EXPECT_EQ(io::tileset_json(ts), io::tileset_json(ts));

  ts.root.refine.clear();
  EXPECT_THROW(io::tileset_json(ts), io::IoError);
  ts.root.refine = "REPLACE";
  ts.root.geometric_error = std::nan("");
  EXPECT_THROW(io::tileset_json(ts), io::IoError);
}

}  // namespace
}  // namespace citylod::test
