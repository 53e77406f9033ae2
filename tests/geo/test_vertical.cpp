// choose_vertical: heights right by default. NAP 0 m in Delft is ~43.5 m above
// the WGS 84 ellipsoid; RD New alone implies NAP; --vertical ellipsoidal keeps z.
#include "citylod/geo/vertical.hpp"

#include "citylod/geo/georef.hpp"

#include <gtest/gtest.h>

using namespace citylod::geo;

namespace {

double ellipsoidal_height(const VerticalChoice& c, double x, double y, double z) {
  Transformer t(c.crs, c.options);
  EXPECT_EQ(t.effective_height_mode(), c.effective);
  return t.to_wgs84(Eigen::Vector3d(x, y, z)).z();
}

}  // namespace

TEST(Vertical, RdNewImpliesNapByDefault) {
  const VerticalChoice c = choose_vertical(Crs::parse("EPSG:28992"));
  EXPECT_TRUE(c.implied);
  EXPECT_EQ(c.datum, "NAP");
  EXPECT_EQ(c.vertical_epsg, 5709);
  EXPECT_TRUE(c.crs.has_vertical_datum());
  EXPECT_NE(c.effective, HeightMode::Ellipsoidal);
  const double h = ellipsoidal_height(c, 85000, 447500, 0.0);  // Delft, NAP 0 m
  EXPECT_GT(h, 43.0);
  EXPECT_LT(h, 45.0);
  EXPECT_EQ(c.assumption.rfind("heights NAP (implied by EPSG:28992) -> ellipsoidal via ", 0), 0u)
      << c.assumption;
  if (c.effective == HeightMode::Egm96) {
    // Debian's proj-data has no NSGI grids: the sentence names them
    EXPECT_NE(c.assumption.find("EGM96 (nl_nsgi_nlgeo2018.tif"), std::string::npos) << c.assumption;
    EXPECT_NE(c.assumption.find("not installed)"), std::string::npos) << c.assumption;
    EXPECT_FALSE(c.missing_grids.empty());
  }
}

TEST(Vertical, TheChoiceCarriesItsTransformerForTheGeoref) {
  VerticalChoice c = choose_vertical(Crs::parse("EPSG:28992"));
  ASSERT_TRUE(c.transformer);
  EXPECT_EQ(c.transformer->crs().definition(), c.crs.definition());
  EXPECT_EQ(c.transformer->effective_height_mode(), c.effective);
  const Eigen::AlignedBox3d box(Eigen::Vector3d(84825, 447456, -5),
                                Eigen::Vector3d(85056, 447624, 40));
  Georef built = Georef::from_crs_bbox(c.crs, box, c.options);
  Georef adopted = Georef::from_transformer_bbox(std::move(c.transformer), box);
  EXPECT_EQ(built.frame().origin(), adopted.frame().origin());
  const Eigen::Vector3d p(85000.25, 447500.5, 3.0);
  EXPECT_EQ(built.to_local(p), adopted.to_local(p));  // the same bits
  // none is set up when the choice needs none
  EXPECT_FALSE(choose_vertical(Crs::parse("EPSG:28992"), VerticalMode::Ellipsoidal).transformer);
  EXPECT_THROW(Georef::from_transformer_bbox(nullptr, box), GeoError);
}

TEST(Vertical, ExplicitEllipsoidalKeepsZ) {
  const VerticalChoice c = choose_vertical(Crs::parse("EPSG:28992"), VerticalMode::Ellipsoidal);
  EXPECT_EQ(c.effective, HeightMode::Ellipsoidal);
  EXPECT_FALSE(c.implied);
  EXPECT_TRUE(c.datum.empty());
  EXPECT_NEAR(ellipsoidal_height(c, 85000, 447500, 0.0), 0.0, 1e-9);
  EXPECT_NE(c.assumption.find("ellipsoidal (--vertical ellipsoidal)"), std::string::npos);
  // also on a compound CRS: the user's word wins, and the sentence says what is ignored
  const VerticalChoice k = choose_vertical(Crs::parse("EPSG:7415"), VerticalMode::Ellipsoidal);
  EXPECT_NEAR(ellipsoidal_height(k, 85000, 447500, 0.0), 0.0, 1e-9);
  EXPECT_NE(k.assumption.find("NAP height) is ignored"), std::string::npos) << k.assumption;
}

TEST(Vertical, CompoundCrsUsesItsVerticalDatum) {
  for (VerticalMode m : {VerticalMode::Auto, VerticalMode::Orthometric}) {
    const VerticalChoice c = choose_vertical(Crs::parse("EPSG:7415"), m);
    EXPECT_FALSE(c.implied);
    EXPECT_EQ(c.datum, "NAP height");
    const double h = ellipsoidal_height(c, 85000, 447500, 0.0);
    EXPECT_GT(h, 43.0);
    EXPECT_LT(h, 45.0);
    EXPECT_EQ(c.assumption.rfind("heights NAP height (from EPSG:7415) -> ellipsoidal via ", 0), 0u)
        << c.assumption;
  }
  // implied and stated give the same heights
  const double a = ellipsoidal_height(choose_vertical(Crs::parse("EPSG:28992")), 85000, 447500, 3);
  const double b = ellipsoidal_height(choose_vertical(Crs::parse("EPSG:7415")), 85000, 447500, 3);
  EXPECT_NEAR(a, b, 1e-6);
}

TEST(Vertical, NoImpliedDatumStaysEllipsoidalUnlessOrthometric) {
  const Crs utm = Crs::parse("EPSG:32631");
  const VerticalChoice a = choose_vertical(utm);
  EXPECT_EQ(a.effective, HeightMode::Ellipsoidal);
  EXPECT_NE(a.assumption.find("EPSG:32631 has no vertical datum and none is implied"),
            std::string::npos)
      << a.assumption;
  EXPECT_NEAR(ellipsoidal_height(a, 500000, 5760000, 10.0), 10.0, 1e-9);
  const VerticalChoice o = choose_vertical(utm, VerticalMode::Orthometric);
  EXPECT_EQ(o.effective, HeightMode::Egm96);
  EXPECT_EQ(o.datum, "EGM96");
  const double h = ellipsoidal_height(o, 500000, 5760000, 10.0);  // 3 E, 52 N: N ~ 45-47 m
  EXPECT_GT(h, 50.0);
  EXPECT_LT(h, 60.0);
}

TEST(Vertical, ConditionalTableEntriesNeedProjsGrids) {
  // CH1903+ / LV95 -> LN02 only when PROJ has the Swiss geoid (not in Debian's proj-data)
  const VerticalChoice c = choose_vertical(Crs::parse("EPSG:2056"));
  if (c.implied) {
    EXPECT_EQ(c.effective, HeightMode::FromCrs);
    EXPECT_EQ(c.datum, "LN02");
  } else {
    EXPECT_EQ(c.effective, HeightMode::Ellipsoidal);
    EXPECT_NE(c.assumption.find("often LN02"), std::string::npos) << c.assumption;
    EXPECT_NE(c.assumption.find("not installed"), std::string::npos) << c.assumption;
    // asked for, orthometric heights go through EGM96
    const VerticalChoice o = choose_vertical(Crs::parse("EPSG:2056"), VerticalMode::Orthometric);
    EXPECT_EQ(o.effective, HeightMode::Egm96);
  }
  for (const ImpliedVertical& v : implied_vertical_table())
    EXPECT_EQ(v.needs_proj_path, v.horizontal_epsg != 28992) << v.horizontal_epsg;
}

TEST(Vertical, ParseMode) {
  EXPECT_EQ(parse_vertical_mode("auto"), VerticalMode::Auto);
  EXPECT_EQ(parse_vertical_mode("Ellipsoidal"), VerticalMode::Ellipsoidal);
  EXPECT_EQ(parse_vertical_mode("orthometric"), VerticalMode::Orthometric);
  EXPECT_THROW(parse_vertical_mode("geoid"), GeoError);
}
