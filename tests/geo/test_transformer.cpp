// Transformer: PROJ and UTM paths, round trips, geoid, area checks, threads, throughput.
#include "citylod/geo/georef.hpp"
#include "citylod/geo/transformer.hpp"
#include "support/las_read.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <random>
#include <thread>

using namespace citylod::geo;

namespace {

const std::string kAutzen = std::string(CITYLOD_SHARED_DATA) + "/las/autzen_trim.las";
constexpr double kDegToM = 111'320.0;  // metres per degree of latitude, roughly

/// n points spread over +-half (CRS units) around c, deterministic.
Eigen::Matrix3Xd cloud(const Eigen::Vector3d& c, double half, Eigen::Index n, unsigned seed = 7) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3Xd p(3, n);
  for (Eigen::Index i = 0; i < n; ++i)
    p.col(i) = c + Eigen::Vector3d(u(rng) * half, u(rng) * half, u(rng) * 0.05 * half);
  return p;
}

struct Case {
  std::string name, spec;
  Eigen::Vector3d point;  // CRS units
};

std::vector<Case> round_trip_cases() {
  std::vector<Case> cases = {
      {"RD New", "EPSG:28992", {155000, 463000, 10}},
      {"UTM 31N", "EPSG:32631", {593500, 5762500, 20}},
      {"UTM 33N", "EPSG:32633", {400000, 6500000, 120}},
      {"UTM 33S", "EPSG:32733", {300000, 7000000, 900}},
      {"CH1903+ LV95", "EPSG:2056", {2600000, 1200000, 540}},
  };
  if (const auto las = citylod::test::read_las(kAutzen)) {
    const auto f = las->point(0).xyz;
    cases.push_back({"autzen WKT (ft)", las->wkt(), {f[0], f[1], f[2]}});
  }
  return cases;
}

}  // namespace

TEST(Transformer, RdNewCentreOfAmersfoort) {
  Transformer t(Crs::parse("EPSG:28992"));
  const LonLatH g = t.to_wgs84(Eigen::Vector3d(155000, 463000, 0));
  EXPECT_NEAR(g.y(), 52.1552, 1e-4);
  EXPECT_NEAR(g.x(), 5.3872, 1e-4);
  EXPECT_FALSE(t.uses_geographiclib_utm());
  EXPECT_EQ(t.effective_height_mode(), HeightMode::Ellipsoidal);
  EXPECT_NEAR(g.z(), 0.0, 1e-9);  // 2D CRS without geoid: z passes through (metres)
}

// CRS -> WGS84 -> ECEF -> ENU -> ECEF -> WGS84 -> CRS, and Georef's batch to_local / to_crs.
TEST(Transformer, RoundTripsWithinOneMillimetre) {
  for (const Case& c : round_trip_cases()) {
    SCOPED_TRACE(c.name);
    const Crs crs = Crs::parse(c.spec);
    const double to_m = crs.horizontal_unit().to_si;
    Transformer t(crs);
    const LocalFrame frame(t.to_wgs84(c.point));
    const Eigen::Matrix3Xd pts = cloud(c.point, 800.0 / to_m, 1000);

    double worst = 0;
    for (Eigen::Index i = 0; i < pts.cols(); ++i) {
      const Eigen::Vector3d p = pts.col(i);
      const LonLatH g = t.to_wgs84(p);
      const Eigen::Vector3d enu = frame.ecef_to_enu(frame.enu_to_ecef(frame.geodetic_to_enu(g)));
      const Eigen::Vector3d back = t.from_wgs84(frame.enu_to_geodetic(enu));
      worst = std::max(worst, (back - p).norm() * to_m);
    }
    EXPECT_LT(worst, 1e-6);  // exact inverse: ~1e-8 m in practice

    Georef geo = Georef::from_crs_bbox(
        crs, Eigen::AlignedBox3d(pts.rowwise().minCoeff(), pts.rowwise().maxCoeff()));
    Eigen::Matrix3Xd local = pts;
    geo.to_local_inplace(local);
    EXPECT_LT(local.cwiseAbs().maxCoeff(), 1200.0);  // ENU metres near the origin
    Eigen::Matrix3Xd back = local;
    geo.to_crs_inplace(back);
    const double batch_worst = (back - pts).cwiseAbs().maxCoeff() * to_m;
    EXPECT_LT(batch_worst, 1e-6);
    RecordProperty(c.name + " round trip max error m",
                   std::to_string(std::max(worst, batch_worst)));
    std::printf("  round trip %-16s max error %.3g m\n", c.name.c_str(),
                std::max(worst, batch_worst));
  }
}

TEST(Transformer, AutzenLandsInOregon) {
  const auto las = citylod::test::read_las(kAutzen);
  if (!las) GTEST_SKIP() << "shared data missing: " << kAutzen;
  Transformer t(Crs::parse(las->wkt()));
  const auto f = las->point(0).xyz;
  const LonLatH g = t.to_wgs84(Eigen::Vector3d(f[0], f[1], f[2]));
  EXPECT_NEAR(g.y(), 44.05, 0.02);
  EXPECT_NEAR(g.x(), -123.07, 0.02);
  EXPECT_NEAR(g.z(), f[2] * 0.3048, 1e-9);  // feet heights become metres
  const auto &lo = las->min, &hi = las->max;
  EXPECT_NO_THROW(t.check_in_area(Eigen::AlignedBox3d(Eigen::Vector3d(lo[0], lo[1], lo[2]),
                                                      Eigen::Vector3d(hi[0], hi[1], hi[2]))));
}

TEST(Transformer, GeographicLibUtmAgreesWithProj) {
  for (const char* spec : {"EPSG:32631", "EPSG:32633", "EPSG:32733"}) {
    SCOPED_TRACE(spec);
    const Crs crs = Crs::parse(spec);
    Transformer fast(crs, {HeightMode::FromCrs, true});
    Transformer proj(crs);
    ASSERT_TRUE(fast.uses_geographiclib_utm());
    ASSERT_FALSE(proj.uses_geographiclib_utm());
    // Across the zone and beyond its edges (x 166..834 km), 2000 km of northing.
    Eigen::Matrix3Xd a(3, 0);
    std::vector<Eigen::Vector3d> v;
    const double y0 = crs.utm()->north ? 1'000'000 : 8'000'000;
    for (double x = 166'000; x <= 834'000; x += 66'800)
      for (double y = y0; y <= y0 + 2'000'000; y += 200'000) v.push_back({x, y, 50});
    a = Eigen::Map<Eigen::Matrix3Xd>(v[0].data(), 3, static_cast<Eigen::Index>(v.size()));
    Eigen::Matrix3Xd b = a;
    fast.to_wgs84_inplace(a);
    proj.to_wgs84_inplace(b);
    const double dlat = (a.row(1) - b.row(1)).cwiseAbs().maxCoeff() * kDegToM;
    const double dlon = (a.row(0) - b.row(0)).cwiseAbs().maxCoeff() * kDegToM;
    EXPECT_LT(dlat, 1e-3);
    EXPECT_LT(dlon, 1e-3);
    // And the inverse.
    fast.from_wgs84_inplace(b);
    const Eigen::Matrix3Xd orig = Eigen::Map<Eigen::Matrix3Xd>(v[0].data(), 3, a.cols());
    EXPECT_LT((b - orig).cwiseAbs().maxCoeff(), 1e-3);
  }
}

TEST(Transformer, OutsideAreaOfUse) {
  Transformer rd(Crs::parse("EPSG:28992"));
  // UTM-like coordinates fed to RD New: far away from the Netherlands.
  const Eigen::AlignedBox3d bad(Eigen::Vector3d(593000, 5762000, 0),
                                Eigen::Vector3d(594000, 5763000, 10));
  try {
    rd.check_in_area(bad);
    FAIL() << "expected GeoError";
  } catch (const GeoError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind("coordinates (", 0), 0u) << msg;
    EXPECT_NE(msg.find("lie outside the area of use of EPSG:28992"), std::string::npos) << msg;
  }
  EXPECT_THROW(Georef::from_crs_bbox(Crs::parse("EPSG:28992"), bad), GeoError);
  const Eigen::AlignedBox3d delft(Eigen::Vector3d(84000, 446000, -5),
                                  Eigen::Vector3d(86000, 448000, 60));
  EXPECT_NO_THROW(rd.check_in_area(delft));
  // Swiss coordinates in RD: outside too.
  EXPECT_THROW(rd.check_in_area(Eigen::AlignedBox3d(Eigen::Vector3d(2600000, 1200000, 0),
                                                    Eigen::Vector3d(2600100, 1200100, 0))),
               GeoError);
}

// EGM96: h = H + N. N at Delft (52.0 N, 4.36 E) is 43.48 m in PROJ's 15' egm96_15.gtx grid
// (cs2cs EPSG:4326+5773 -> EPSG:4979 gives 43.4768). The tolerance 0.3 m covers the grid's
// interpolation error against the full EGM96 model (a few cm in flat terrain) with margin, while
// still catching a missing correction (0) or a wrong sign (-43).
TEST(Geoid, Egm96AtDelft) {
  EXPECT_NE(egm96_grid_path().find("egm96_15.gtx"), std::string::npos);
  Transformer ell(Crs::parse("EPSG:4326"), {HeightMode::Egm96});
  const LonLatH g = ell.to_wgs84(Eigen::Vector3d(4.36, 52.0, 0.0));
  EXPECT_NEAR(g.z(), 43.48, 0.3);
  // An independent PROJ path: compound WGS 84 + EGM96 height (EPSG:5773), resolved by PROJ.
  Transformer compound(Crs::parse("EPSG:4326+5773"));
  EXPECT_EQ(compound.effective_height_mode(), HeightMode::FromCrs);
  const LonLatH h = compound.to_wgs84(Eigen::Vector3d(4.36, 52.0, 0.0));
  EXPECT_NEAR(h.z(), g.z(), 1e-3);
  // Orthometric 10 m -> ellipsoidal 10 + N, and back.
  const LonLatH up = ell.to_wgs84(Eigen::Vector3d(4.36, 52.0, 10.0));
  EXPECT_NEAR(up.z() - g.z(), 10.0, 1e-9);
  EXPECT_NEAR(ell.from_wgs84(up).z(), 10.0, 1e-9);
}

TEST(Geoid, RdNewWithEgm96) {
  Transformer t(Crs::parse("EPSG:28992"), {HeightMode::Egm96});
  const LonLatH g = t.to_wgs84(Eigen::Vector3d(85000, 447000, 2.0));  // Delft, 2 m NAP
  EXPECT_NEAR(g.z(), 2.0 + 43.5, 0.5);
  EXPECT_NE(t.description().find("EGM96"), std::string::npos);
}

// RD New + NAP: PROJ needs nl_nsgi_nlgeo2018.tif (+ rdtrans2018), which Debian's proj-data does
// not ship. PROJ would then silently pick a "ballpark" vertical step (h = H, 43 m wrong); citylod
// must fall back to EGM96 and say so.
TEST(Geoid, RdNapFallsBackToEgm96WithWarning) {
  Transformer t(Crs::parse("EPSG:7415"));
  const LonLatH g = t.to_wgs84(Eigen::Vector3d(85000, 447000, 2.0));
  EXPECT_GT(g.z(), 40.0);  // never the ballpark h = H
  EXPECT_LT(g.z(), 50.0);
  if (t.effective_height_mode() == HeightMode::Egm96) {
    ASSERT_EQ(t.warnings().size(), 1u);
    EXPECT_NE(t.warnings()[0].find("nl_nsgi_nlgeo2018"), std::string::npos) << t.warnings()[0];
    EXPECT_NE(t.warnings()[0].find("EGM96"), std::string::npos);
  } else {
    EXPECT_TRUE(t.warnings().empty());  // the NSGI grids are installed
  }
}

TEST(Transformer, ErrorsAreGeoErrors) {
  Transformer t(Crs::parse("EPSG:28992"));
  EXPECT_THROW(t.to_wgs84(Eigen::Vector3d(NAN, 0, 0)), GeoError);
  Transformer g(Crs::parse("EPSG:4326"));
  EXPECT_THROW(g.from_wgs84(LonLatH(0, 95, 0)), GeoError);
}

TEST(Transformer, DeterministicAndThreadSafe) {
  const Crs crs = Crs::parse("EPSG:28992");
  const Eigen::Matrix3Xd pts = cloud({155000, 463000, 10}, 20000, 50000);
  Transformer base(crs, {HeightMode::Egm96});
  Eigen::Matrix3Xd ref = pts;
  base.to_wgs84_inplace(ref);
  Eigen::Matrix3Xd again = pts;
  base.to_wgs84_inplace(again);
  EXPECT_EQ(std::memcmp(ref.data(), again.data(), sizeof(double) * ref.size()), 0);

  Transformer t1 = base.clone(), t2 = base.clone();
  Eigen::Matrix3Xd r1, r2;
  auto work = [&pts](Transformer& t, Eigen::Matrix3Xd& out) {
    for (int rep = 0; rep < 5; ++rep) {
      out = pts;
      t.to_wgs84_inplace(out);
    }
  };
  std::thread a(work, std::ref(t1), std::ref(r1)), b(work, std::ref(t2), std::ref(r2));
  a.join();
  b.join();
  EXPECT_EQ(std::memcmp(ref.data(), r1.data(), sizeof(double) * ref.size()), 0);
  EXPECT_EQ(std::memcmp(ref.data(), r2.data(), sizeof(double) * ref.size()), 0);
}

TEST(Transformer, BatchThroughput) {
  const Eigen::Index n = 1'000'000;
  struct Run {
    const char* name;
    std::string spec;
    Eigen::Vector3d c;
    TransformOptions opt;
  };
  for (const Run& r :
       {Run{"RD New (PROJ)", "EPSG:28992", {155000, 463000, 0}, {}},
        Run{"RD New + EGM96", "EPSG:28992", {155000, 463000, 0}, {HeightMode::Egm96}},
        Run{"UTM 31N PROJ", "EPSG:32631", {593500, 5762500, 0}, {}},
        Run{"UTM 31N GeogLib", "EPSG:32631", {593500, 5762500, 0}, {HeightMode::FromCrs, true}}}) {
    Transformer t(Crs::parse(r.spec), r.opt);
    Eigen::Matrix3Xd p = cloud(r.c, 5000, n);
    const auto t0 = std::chrono::steady_clock::now();
    t.to_wgs84_inplace(p);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("  to_wgs84 %-16s %6.2f Mpts/s\n", r.name, n / s / 1e6);
    RecordProperty(std::string(r.name) + " Mpts/s", std::to_string(n / s / 1e6));
  }
  Georef geo = Georef::from_crs(Crs::parse("EPSG:28992"), {155000, 463000, 0});
  Eigen::Matrix3Xd p = cloud({155000, 463000, 0}, 5000, n);
  const auto t0 = std::chrono::steady_clock::now();
  geo.to_local_inplace(p);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("  Georef::to_local RD New  %6.2f Mpts/s\n", n / s / 1e6);
}
