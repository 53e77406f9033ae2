// Georef in the projected scene frame (geo::SceneFrame::projected): scene
// coordinates are the CRS's axes in metres minus the origin, and the earth's
// curvature and the vertical datum enter only on the way to the tiles' ENU frame.
#include "citylod/geo/georef.hpp"

#include <gtest/gtest.h>

#include <cmath>

using namespace citylod::geo;

namespace {

TEST(SceneFrame, ProjectedIsATranslationAndTheCrsUnits) {
  const Eigen::Vector3d o(85000, 447500, 0);
  Georef enu = Georef::from_crs(Crs::parse("EPSG:28992"), o);
  Georef g = enu.clone();
  g.use_projected_frame(o);
  EXPECT_EQ(g.scene_frame(), SceneFrame::projected);
  // the same point 100 m and 10 km away: the same coordinates minus the shift, exactly
  const Eigen::Vector3d p(85012.34, 447488.01, 3.5);
  const Eigen::Vector3d a = g.to_local(p), b = g.to_local(p + Eigen::Vector3d(10000, 100, 0));
  EXPECT_EQ(a, Eigen::Vector3d(85012.34 - 85000, 447488.01 - 447500, 3.5));
  EXPECT_NEAR(b.x() - a.x(), 10000, 1e-9);
  EXPECT_NEAR(b.y() - a.y(), 100, 1e-9);
  EXPECT_EQ(b.z(), a.z());  // heights as given, no geoid
  // and back to the CRS
  EXPECT_NEAR((g.to_crs(a) - p).norm(), 0, 1e-9);
  // to the tiles' ENU frame: what the ENU scene makes of the CRS point (the same origin)
  Eigen::Matrix3Xd m(3, 2);
  m.col(0) = a;
  m.col(1) = b;
  g.to_enu_inplace(m);
  EXPECT_NEAR((m.col(0) - enu.to_local(p)).norm(), 0, 1e-6);
  EXPECT_NEAR((m.col(1) - enu.to_local(p + Eigen::Vector3d(10000, 100, 0))).norm(), 0, 1e-6);
  // 10 km away the ENU frame and the projected axes differ by far more than a millimetre
  // (the curvature drops the ENU height, the grid convergence turns the axes)
  EXPECT_GT((m.col(1) - b).norm(), 1.0);
  // and back
  g.enu_to_scene_inplace(m);
  EXPECT_NEAR((m.col(0) - a).norm(), 0, 1e-6);
  EXPECT_NEAR((m.col(1) - b).norm(), 0, 1e-6);
  // geodetic of a scene point = geodetic of its CRS point
  const LonLatH ga = g.to_geodetic(a), ge = enu.frame().enu_to_geodetic(enu.to_local(p));
  EXPECT_NEAR(ga[0], ge[0], 1e-9);
  EXPECT_NEAR(ga[1], ge[1], 1e-9);
  EXPECT_NEAR((g.from_geodetic(ga) - a).norm(), 0, 1e-6);
  // a clone keeps the frame
  Georef c = g.clone();
  EXPECT_EQ(c.scene_frame(), SceneFrame::projected);
  EXPECT_EQ(c.to_local(p), a);
}

TEST(SceneFrame, FeetAreConvertedToMetres) {
  // NAD83(HARN) / Oregon GIC Lambert (ft), the autzen tile's CRS
  const Eigen::Vector3d o(637000, 851000, 400);
  Georef g = Georef::from_crs(Crs::parse("EPSG:2994"), o);
  g.use_projected_frame(o);
  const Eigen::Vector3d a = g.to_local(o + Eigen::Vector3d(100, 0, 10));
  EXPECT_NEAR(a.x(), 30.48, 1e-9);
  EXPECT_NEAR(a.z(), 3.048, 1e-9);
  EXPECT_NEAR((g.to_crs(a) - (o + Eigen::Vector3d(100, 0, 10))).norm(), 0, 1e-9);
}

TEST(SceneFrame, LocalScenesHaveNoProjectedFrame) {
  Georef g = Georef::local(LonLatH(4.37, 52.0, 0));
  EXPECT_THROW(g.use_projected_frame(Eigen::Vector3d::Zero()), GeoError);
  EXPECT_EQ(g.scene_frame(), SceneFrame::enu);
}

}  // namespace
