// LocalFrame (ENU <-> geodetic <-> ECEF, 3D Tiles root transform, regions) and Georef.
#include "citylod/geo/georef.hpp"
#include "citylod/geo/local_frame.hpp"

#include <gtest/gtest.h>
#include <GeographicLib/LocalCartesian.hpp>

#include <cmath>
#include <random>
#include <thread>

using namespace citylod::geo;

namespace {

/// ECEF of a geodetic point by the closed-form WGS84 formula (independent of the library).
Eigen::Vector3d ecef_reference(double lon_deg, double lat_deg, double h) {
  const double a = 6378137.0, f = 1.0 / 298.257223563, e2 = f * (2 - f);
  const double lat = lat_deg * M_PI / 180, lon = lon_deg * M_PI / 180;
  const double n = a / std::sqrt(1 - e2 * std::sin(lat) * std::sin(lat));
  return {(n + h) * std::cos(lat) * std::cos(lon), (n + h) * std::cos(lat) * std::sin(lon),
          (n * (1 - e2) + h) * std::sin(lat)};
}

const LonLatH kDelft(4.36, 52.0, 45.0);

}  // namespace

TEST(LocalFrame, RootTransformMapsOriginToItsEcef) {
  for (const LonLatH& o : {kDelft, LonLatH(-123.07, 44.05, 120), LonLatH(151.2, -33.9, 10),
                           LonLatH(0, 0, 0), LonLatH(-70, 89.5, 3000)}) {
    const LocalFrame frame(o);
    const std::array<double, 16> m = frame.enu_to_ecef_matrix();
    const Eigen::Matrix4d M = Eigen::Map<const Eigen::Matrix4d>(m.data());  // column-major
    const Eigen::Vector4d origin = M * Eigen::Vector4d(0, 0, 0, 1);
    const Eigen::Vector3d ref = ecef_reference(o.x(), o.y(), o.z());
    EXPECT_LT((origin.head<3>() - ref).norm(), 1e-6);
    EXPECT_EQ(origin.w(), 1.0);
    EXPECT_EQ(m[3], 0.0);
    EXPECT_EQ(m[7], 0.0);
    EXPECT_EQ(m[11], 0.0);
    const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
    EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-14);
    EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
    // A point 100 m up the local vertical is 100 m further along the ellipsoid normal.
    const Eigen::Vector4d up = M * Eigen::Vector4d(0, 0, 100, 1);
    EXPECT_LT((up.head<3>() - ecef_reference(o.x(), o.y(), o.z() + 100)).norm(), 1e-6);
  }
}

TEST(LocalFrame, AgreesWithGeographicLibLocalCartesian) {
  const LocalFrame frame(kDelft);
  const GeographicLib::LocalCartesian lc(kDelft.y(), kDelft.x(), kDelft.z());
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.05, 0.05);
  for (int i = 0; i < 1000; ++i) {
    const LonLatH g(kDelft.x() + u(rng), kDelft.y() + u(rng), 100 * u(rng));
    Eigen::Vector3d ref;
    lc.Forward(g.y(), g.x(), g.z(), ref.x(), ref.y(), ref.z());
    const Eigen::Vector3d enu = frame.geodetic_to_enu(g);
    EXPECT_LT((enu - ref).norm(), 1e-8);
    const LonLatH back = frame.enu_to_geodetic(enu);
    EXPECT_LT((back.head<2>() - g.head<2>()).norm() * 111e3, 1e-8);
    EXPECT_NEAR(back.z(), g.z(), 1e-8);
    EXPECT_LT((frame.ecef_to_enu(frame.enu_to_ecef(enu)) - enu).norm(), 1e-8);
  }
}

TEST(LocalFrame, BoundingRegionEnclosesTheBox) {
  const LocalFrame frame(kDelft);
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-600, -400, -5), Eigen::Vector3d(900, 700, 80));
  const BoundingRegion r = frame.bounding_region(box);
  EXPECT_LT(r.west, r.east);
  EXPECT_LT(r.south, r.north);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d p =
        box.min() + (box.max() - box.min()).cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng)));
    const LonLatH g = frame.enu_to_geodetic(p);
    ASSERT_GE(g.x() * M_PI / 180, r.west);
    ASSERT_LE(g.x() * M_PI / 180, r.east);
    ASSERT_GE(g.y() * M_PI / 180, r.south);
    ASSERT_LE(g.y() * M_PI / 180, r.north);
    ASSERT_GE(g.z(), r.min_height);
    ASSERT_LE(g.z(), r.max_height);
  }
  // Tight: heights within a few cm (earth curvature over ~1 km is ~0.1 m) of the box.
  EXPECT_NEAR(r.min_height, kDelft.z() - 5, 0.05);
  EXPECT_NEAR(r.max_height, kDelft.z() + 80, 0.15);
  const auto a = r.to_array();
  EXPECT_EQ(a[0], r.west);
  EXPECT_EQ(a[5], r.max_height);
}

TEST(LocalFrame, ParseOrigin) {
  const LonLatH o = parse_origin("52.0,4.36,45.5");
  EXPECT_EQ(o, LonLatH(4.36, 52.0, 45.5));
  EXPECT_EQ(parse_origin(" -33.9 , 151.2 , 0 "), LonLatH(151.2, -33.9, 0));
  EXPECT_THROW(parse_origin("4.36;52.0;0"), GeoError);
  EXPECT_THROW(parse_origin("52.0,4.36"), GeoError);
  EXPECT_THROW(parse_origin("95,4,0"), GeoError);
  EXPECT_THROW(parse_origin("52,4,0,1"), GeoError);
}

TEST(Georef, LocalSceneIsIdentity) {
  Georef geo = Georef::local(parse_origin("52.0,4.36,45"));
  EXPECT_FALSE(geo.has_crs());
  EXPECT_THROW(geo.crs(), GeoError);
  const Eigen::Vector3d p(12.5, -3.25, 7);
  EXPECT_EQ(geo.to_local(p), p);
  EXPECT_THROW(geo.to_crs(p), GeoError);
  const Eigen::Vector4d o =
      Eigen::Map<const Eigen::Matrix4d>(geo.root_transform().data()) * Eigen::Vector4d(0, 0, 0, 1);
  EXPECT_LT((o.head<3>() - ecef_reference(4.36, 52.0, 45)).norm(), 1e-6);
}

TEST(Georef, RdSceneOriginAtBoxCentre) {
  const Crs rd = Crs::parse("EPSG:28992");
  const Eigen::AlignedBox3d box(Eigen::Vector3d(84000, 446000, -2),
                                Eigen::Vector3d(86000, 448000, 40));
  Georef geo = Georef::from_crs_bbox(rd, box, {HeightMode::Egm96});
  EXPECT_EQ(geo.origin_crs(), box.center());
  EXPECT_LT(geo.to_local(box.center()).norm(), 1e-6);
  // 10 m higher in NAP/EGM96 is 10 m up in ENU (same lon/lat: same geoid undulation).
  const Eigen::Vector3d up = geo.to_local(box.center() + Eigen::Vector3d(0, 0, 10));
  EXPECT_NEAR(up.z(), 10.0, 1e-6);
  EXPECT_LT(up.head<2>().norm(), 1e-6);
  // 1 km east in RD is ~1 km east in ENU (RD grid convergence near Delft is ~-0.8 deg).
  const Eigen::Vector3d east = geo.to_local(box.center() + Eigen::Vector3d(1000, 0, 0));
  EXPECT_NEAR(east.norm(), 1000.0, 1.0);
  EXPECT_GT(east.x(), 999.0);
  // Origin height: ellipsoidal = 19 m NAP-as-EGM96 + N (~43.5 m).
  EXPECT_NEAR(geo.frame().origin().z(), 19 + 43.5, 0.5);
  const BoundingRegion r = geo.bounding_region(
      Eigen::AlignedBox3d(Eigen::Vector3d(-1000, -1000, -21), Eigen::Vector3d(1000, 1000, 21)));
  EXPECT_NEAR(r.west * 180 / M_PI, 4.35, 0.05);
  EXPECT_NEAR(r.south * 180 / M_PI, 51.99, 0.05);
}

TEST(Georef, CloneInThreadsGivesIdenticalResults) {
  Georef geo = Georef::from_crs(Crs::parse("EPSG:2056"), {2600000, 1200000, 540});
  Eigen::Matrix3Xd pts(3, 20000);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-2000, 2000);
  for (Eigen::Index i = 0; i < pts.cols(); ++i)
    pts.col(i) = Eigen::Vector3d(2600000 + u(rng), 1200000 + u(rng), 540 + u(rng) / 100);
  Eigen::Matrix3Xd ref = pts;
  geo.to_local_inplace(ref);
  Georef g1 = geo.clone(), g2 = geo.clone();
  Eigen::Matrix3Xd r1 = pts, r2 = pts;
  std::thread a([&] { g1.to_local_inplace(r1); }), b([&] { g2.to_local_inplace(r2); });
  a.join();
  b.join();
  EXPECT_TRUE((r1.array() == ref.array()).all());
  EXPECT_TRUE((r2.array() == ref.array()).all());
}
