// Georef::to_local_inplace through the node lattice (geo/src/lattice.hpp) against PROJ
// point by point.
#include "citylod/geo/georef.hpp"
#include "citylod/geo/vertical.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>

using namespace citylod::geo;

namespace {

/// n points in a square of side `side` (CRS units) around c, heights lo..hi.
Eigen::Matrix3Xd scatter(const Eigen::Vector3d& c, double side, double lo, double hi,
                         Eigen::Index n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.5, 0.5), h(lo, hi);
  Eigen::Matrix3Xd p(3, n);
  for (Eigen::Index i = 0; i < n; ++i)
    p.col(i) = Eigen::Vector3d(c.x() + u(rng) * side, c.y() + u(rng) * side, h(rng));
  return p;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct LatticeCase {
  const char* name;
  const char* spec;
  Eigen::Vector3d centre;  // CRS units
  double side;             // CRS units
  double lo, hi;           // heights, CRS units
};

}  // namespace

TEST(Lattice, AgreesWithProjTo20Nanometres) {
  for (const LatticeCase& c : {
           LatticeCase{"RD New, NAP via EGM96", "EPSG:28992", {85000, 446000, 0}, 800, -10, 300},
           // 6 km wide, across a line of the EGM96 grid (15'): the geoid's bilinear
           // interpolation has a kink there, which the cells' checks find
           LatticeCase{"RD New, 6 km", "EPSG:28992", {85000, 446000, 0}, 6000, -10, 300},
           LatticeCase{"LV95 + LN02", "EPSG:2056+5728", {2600000, 1200000, 500}, 800, 200, 4500},
           LatticeCase{"UTM 31N (PROJ)", "EPSG:32631", {593500, 5762500, 0}, 800, -50, 500},
           LatticeCase{"Oregon Lambert ft", "EPSG:2994", {7600000, 700000, 0}, 2600, 0, 1500},
       }) {
    SCOPED_TRACE(c.name);
    const VerticalChoice vc = choose_vertical(Crs::parse(c.spec));
    Georef fast = Georef::from_crs(vc.crs, c.centre, vc.options);
    Georef exact = Georef::from_crs(vc.crs, c.centre, vc.options);
    exact.set_exact(true);
    const Eigen::Index n = 200000;
    const Eigen::Matrix3Xd pts = scatter(c.centre, c.side, c.lo, c.hi, n, 11);
    Eigen::Matrix3Xd a = pts, b = pts;
    auto t0 = std::chrono::steady_clock::now();
    exact.to_local_inplace(a);
    const double t_exact = seconds_since(t0);
    t0 = std::chrono::steady_clock::now();
    fast.to_local_inplace(b);
    const double t_fast = seconds_since(t0);
    const double worst = (a - b).colwise().norm().maxCoeff();
    EXPECT_LT(worst, 2e-8);
    // The same point gives the same bytes whatever batch it comes in (here: alone,
    // after the cache is warm, and in a fresh Georef in reverse order).
    Eigen::Matrix3Xd one = pts.col(12345);
    fast.to_local_inplace(one);
    EXPECT_TRUE((one.array() == b.col(12345).array()).all());
    Georef again = Georef::from_crs(vc.crs, c.centre, vc.options);
    Eigen::Matrix3Xd r = pts.rowwise().reverse();
    again.to_local_inplace(r);
    EXPECT_TRUE((r.rowwise().reverse().array() == b.array()).all());
    std::printf("  %-22s max |lattice - PROJ| %.2g m; PROJ %.2f Mpts/s, lattice %.2f Mpts/s\n",
                c.name, worst, double(n) / t_exact / 1e6, double(n) / t_fast / 1e6);
  }
}

TEST(Lattice, PointsPROJCannotMapFailAsBefore) {
  Georef fast = Georef::from_crs(Crs::parse("EPSG:28992"), {155000, 463000, 0});
  Georef exact = Georef::from_crs(Crs::parse("EPSG:28992"), {155000, 463000, 0});
  exact.set_exact(true);
  Eigen::Matrix3Xd p = scatter({155000, 463000, 0}, 1000, 0, 50, 1000, 3);
  p(0, 700) = std::nan("");
  std::string want, got;
  Eigen::Matrix3Xd a = p, b = p;
  try {
    exact.to_local_inplace(a);
  } catch (const GeoError& e) {
    want = e.what();
  }
  try {
    fast.to_local_inplace(b);
  } catch (const GeoError& e) {
    got = e.what();
  }
  EXPECT_FALSE(want.empty());
  EXPECT_EQ(got, want);
  EXPECT_NE(got.find("#700"), std::string::npos) << got;
}
