#include "citylod/geo/crs.hpp"

#include <gtest/gtest.h>

using namespace citylod::geo;

TEST(Crs, ParsesRdNew) {
  const Crs crs = Crs::parse("EPSG:28992");
  EXPECT_EQ(crs.epsg(), 28992);
}
