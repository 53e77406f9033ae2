// io::read_footprints: the Delft BGT footprints from GeoPackage, SQLite, and
// GeoJSON / Shapefile / FlatGeobuf copies written by GDAL's ogr2ogr at test
// time give the same ids and rings; invalid polygons are repaired or reported;
// bad sources are clear errors.
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>

#include "citylod/io/footprints.hpp"
#include "fixtures.hpp"

using namespace citylod::io;
using namespace citylod::io::test;

namespace {

using Rings = std::vector<std::vector<std::array<double, 2>>>;

bool have_ogr2ogr() {
  static const bool ok = std::system("ogr2ogr --version >/dev/null 2>&1") == 0;
  return ok;
}

// ogr2ogr SRC into a fresh file of `driver` in the test temp dir.
std::string convert(const std::string& src, const std::string& driver, const std::string& name,
                    const std::string& extra = "") {
  const std::string out = tmp_path(name);
  std::filesystem::remove_all(out);
  const std::string cmd =
      "ogr2ogr -f \"" + driver + "\" " + extra + " '" + out + "' '" + src + "' >/dev/null 2>&1";
  if (std::system(cmd.c_str()) != 0) return "";
  return out;
}

std::map<std::string, Rings> by_id(const FootprintLayer& l) {
  std::map<std::string, Rings> m;
  for (const auto& f : l.features) m[f.id] = f.rings;
  return m;
}

// Same rings up to the start vertex of each ring, within tol.
bool same_ring(const std::vector<std::array<double, 2>>& a,
               const std::vector<std::array<double, 2>>& b, double tol) {
  if (a.size() != b.size() || a.empty()) return false;
  for (std::size_t s = 0; s < b.size(); ++s) {
    bool ok = true;
    for (std::size_t i = 0; i < a.size() && ok; ++i) {
      const auto& p = a[i];
      const auto& q = b[(i + s) % b.size()];
      ok = std::abs(p[0] - q[0]) <= tol && std::abs(p[1] - q[1]) <= tol;
    }
    if (ok) return true;
  }
  return false;
}

void expect_same(const FootprintLayer& want, const FootprintLayer& got, double tol,
                 const std::string& what) {
  const auto a = by_id(want), b = by_id(got);
  ASSERT_EQ(a.size(), b.size()) << what;
  int bad = 0;
  for (const auto& [id, rings] : a) {
    auto it = b.find(id);
    if (it == b.end()) {
      if (++bad < 5) ADD_FAILURE() << what << ": id " << id << " missing";
      continue;
    }
    bool ok = rings.size() == it->second.size();
    for (std::size_t r = 0; ok && r < rings.size(); ++r)
      ok = same_ring(rings[r], it->second[r], tol);
    if (!ok && ++bad < 5) ADD_FAILURE() << what << ": rings of " << id << " differ";
  }
  EXPECT_EQ(bad, 0) << what;
}

FootprintLayer gpkg() {
  FootprintReadOptions o;
  o.layer = "bgt";
  o.id_attribute = "gml_id";
  return read_footprints(shared("delft/bgt_pand.gpkg"), o);
}

double ring_area(const std::vector<std::array<double, 2>>& r) {
  double a = 0;
  for (std::size_t i = 0, j = r.size() - 1; i < r.size(); j = i++)
    a += r[j][0] * r[i][1] - r[i][0] * r[j][1];
  return 0.5 * a;
}

}  // namespace

TEST(Footprints, GeoPackage) {
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  const FootprintLayer l = gpkg();
  EXPECT_EQ(l.driver, "GPKG");
  EXPECT_EQ(l.layer, "bgt");
  EXPECT_EQ(l.crs, "EPSG:28992");
  EXPECT_EQ(l.crs_epsg, 28992);
  EXPECT_NE(l.crs_wkt.find("Amersfoort"), std::string::npos);
  EXPECT_EQ(l.source_features, 160u);
  EXPECT_EQ(l.skipped, 0u);
  EXPECT_GE(l.features.size(), 160u);
  std::map<std::string, int> ids;
  for (const auto& f : l.features) {
    ++ids[f.id];
    ASSERT_FALSE(f.rings.empty());
    EXPECT_GT(ring_area(f.rings[0]), 0) << f.id << ": exterior ring counter-clockwise";
    for (std::size_t h = 1; h < f.rings.size(); ++h) EXPECT_LT(ring_area(f.rings[h]), 0) << f.id;
    for (const auto& r : f.rings) {
      EXPECT_GE(r.size(), 3u);
      EXPECT_NE(r.front(), r.back()) << "rings are closed implicitly";
    }
    EXPECT_TRUE(f.attributes.contains("gml_id")) << f.id;
    EXPECT_EQ(f.attributes["gml_id"].get<std::string>(), f.source_id);
    if (f.part == 0) {
      EXPECT_EQ(f.id, f.source_id);
    } else {
      EXPECT_EQ(f.id, f.source_id + "-" + std::to_string(f.part));
    }
    // inside the layer's extent (RD New, Delft)
    EXPECT_GT(f.rings[0][0][0], 84800);
    EXPECT_LT(f.rings[0][0][0], 85100);
    EXPECT_GT(f.rings[0][0][1], 447400);
    EXPECT_LT(f.rings[0][0][1], 447700);
  }
  for (const auto& [id, n] : ids) EXPECT_EQ(n, 1) << "duplicate id " << id;
  // typed attributes
  const auto& a = l.features[0].attributes;
  ASSERT_TRUE(a.contains("identificatiebagpnd"));
  EXPECT_TRUE(a["identificatiebagpnd"].is_number_integer() || a["identificatiebagpnd"].is_null());
}

TEST(Footprints, FidIdsWithoutIdAttribute) {
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  const FootprintLayer l = read_footprints(shared("delft/bgt_pand.gpkg"));  // the only layer
  EXPECT_EQ(l.layer, "bgt");
  ASSERT_FALSE(l.features.empty());
  EXPECT_EQ(l.features[0].source_id, std::to_string(l.features[0].fid));
}

TEST(Footprints, SqliteSameAsGeoPackage) {
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.sqlite"));
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  FootprintReadOptions o;
  o.layer = "buildingpart";
  o.id_attribute = "gml_id";
  const FootprintLayer s = read_footprints(shared("delft/bgt_pand.sqlite"), o);
  EXPECT_EQ(s.driver, "SQLite");
  EXPECT_EQ(s.crs_epsg, 28992);
  EXPECT_EQ(s.source_features, 160u);
  expect_same(gpkg(), s, 1e-9, "sqlite");
}

TEST(Footprints, GeoJsonShapefileFlatGeobufWrittenByGdalSameAsGeoPackage) {
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  if (!have_ogr2ogr()) GTEST_SKIP() << "ogr2ogr (gdal-bin) not installed";
  const std::string src = shared("delft/bgt_pand.gpkg");
  const FootprintLayer want = gpkg();
  struct Case {
    const char* driver;
    const char* file;
    const char* extra;
    double tol;
  };
  for (const Case& c : {Case{"GeoJSON", "bgt.geojson", "-lco COORDINATE_PRECISION=6", 1e-6},
                        Case{"ESRI Shapefile", "bgt_shp", "", 1e-9},
                        Case{"FlatGeobuf", "bgt.fgb", "-nlt PROMOTE_TO_MULTI", 1e-9}}) {
    const std::string out = convert(src, c.driver, c.file, c.extra);
    ASSERT_FALSE(out.empty()) << "ogr2ogr -f " << c.driver << " failed";
    FootprintReadOptions o;
    o.id_attribute = "gml_id";
    const FootprintLayer l = read_footprints(out, o);
    EXPECT_EQ(l.source_features, 160u) << c.driver;
    EXPECT_EQ(l.crs_epsg, 28992) << c.driver << " " << l.crs;
    expect_same(want, l, c.tol, c.driver);
  }
}

TEST(Footprints, MeshCityGeoJsonMatchesTheGeoPackage) {
  const std::string p = shared("mesh_city/footprints_bgt_rd.geojson");
  CITYLOD_REQUIRE_SHARED(p);
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  FootprintReadOptions o;
  o.id_attribute = "id";
  const FootprintLayer j = read_footprints(p, o);
  EXPECT_EQ(j.driver, "GeoJSON");
  EXPECT_EQ(j.crs_epsg, 28992);
  EXPECT_EQ(j.source_features, 26u);
  // that file was cut from an other BGT extract: every id is in the
  // GeoPackage, and all but one building (b1105d28c: 8 more vertices there)
  // have the very same outline
  const auto g = by_id(gpkg());
  int found = 0, same = 0;
  for (const auto& f : j.features) {
    auto it = g.find(f.id);
    if (it == g.end()) continue;
    ++found;
    if (same_ring(f.rings[0], it->second[0], 1e-6)) ++same;
  }
  EXPECT_EQ(found, static_cast<int>(j.features.size()));
  EXPECT_GE(same, found - 1);
}

TEST(Footprints, ReprojectedToWgs84) {
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  FootprintReadOptions o;
  o.id_attribute = "gml_id";
  o.target_crs = "EPSG:4326";
  const FootprintLayer l = read_footprints(shared("delft/bgt_pand.gpkg"), o);
  EXPECT_EQ(l.crs, "EPSG:4326");
  ASSERT_FALSE(l.features.empty());
  const auto& p = l.features[0].rings[0][0];
  EXPECT_NEAR(p[0], 4.36, 0.02);  // longitude first
  EXPECT_NEAR(p[1], 52.00, 0.02);
}

TEST(Footprints, InvalidPolygonsRepairedOrReported) {
  const std::string gj = R"({"type":"FeatureCollection",
   "crs":{"type":"name","properties":{"name":"urn:ogc:def:crs:EPSG::28992"}},
   "features":[
    {"type":"Feature","properties":{"name":"bowtie"},"geometry":{"type":"Polygon",
      "coordinates":[[[0,0],[10,10],[10,0],[0,10],[0,0]]]}},
    {"type":"Feature","properties":{"name":"dups"},"geometry":{"type":"Polygon",
      "coordinates":[[[0,0],[4,0],[4,0],[4,4],[4,4],[0,4],[0,0]]]}},
    {"type":"Feature","properties":{"name":"flat"},"geometry":{"type":"Polygon",
      "coordinates":[[[0,0],[5,0],[10,0],[0,0]]]}},
    {"type":"Feature","properties":{"name":"line"},"geometry":{"type":"LineString",
      "coordinates":[[0,0],[1,1]]}},
    {"type":"Feature","properties":{"name":"none"},"geometry":null},
    {"type":"Feature","properties":{"name":"cw"},"geometry":{"type":"MultiPolygon",
      "coordinates":[[[[0,0],[0,2],[2,2],[2,0],[0,0]]],[[[5,5],[5,6],[6,6],[6,5],[5,5]]]]}}
   ]})";
  const std::string p = write_file("invalid.geojson", gj);
  FootprintReadOptions o;
  o.id_attribute = "name";
  const auto t0 = std::chrono::steady_clock::now();
  const FootprintLayer l = read_footprints(p, o);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(20));
  EXPECT_EQ(l.source_features, 6u);
  const auto m = by_id(l);
  std::string all;
  for (const auto& s : l.problems) all += s + "\n";

  if (footprint_repair_available()) {
    // the bowtie: two triangles
    ASSERT_TRUE(m.count("bowtie")) << all;
    ASSERT_TRUE(m.count("bowtie-1")) << all;
    EXPECT_NEAR(std::abs(ring_area(m.at("bowtie")[0])), 25.0, 1e-9);
    EXPECT_NEAR(std::abs(ring_area(m.at("bowtie-1")[0])), 25.0, 1e-9);
    EXPECT_NE(all.find("(bowtie)"), std::string::npos) << all;
    EXPECT_NE(all.find("repaired into 2 polygons"), std::string::npos) << all;
    EXPECT_EQ(l.repaired, 1u);
  } else {
    EXPECT_EQ(m.count("bowtie"), 0u);
    EXPECT_NE(all.find("(bowtie): invalid polygon"), std::string::npos) << all;
  }
  // repeated vertices are dropped, not an error
  ASSERT_TRUE(m.count("dups"));
  EXPECT_EQ(m.at("dups")[0].size(), 4u);
  // zero area, not a polygon, no geometry: reported and skipped
  EXPECT_EQ(m.count("flat"), 0u);
  EXPECT_NE(all.find("(flat): "), std::string::npos) << all;
  EXPECT_NE(all.find("(line): not a polygon (LINESTRING); skipped"), std::string::npos) << all;
  EXPECT_NE(all.find("(none): no geometry; skipped"), std::string::npos) << all;
  // a MultiPolygon: one feature per part; clockwise input comes out counter-clockwise
  ASSERT_TRUE(m.count("cw"));
  ASSERT_TRUE(m.count("cw-1"));
  EXPECT_GT(ring_area(m.at("cw")[0]), 0);
  EXPECT_EQ(l.skipped, footprint_repair_available() ? 3u : 4u);
}

TEST(Footprints, BadSourcesAreClearErrors) {
  expect_io_error([] { read_footprints("/nonexistent/footprints.gpkg"); },
                  "/nonexistent/footprints.gpkg: cannot open");
  const std::string junk = write_file("junk.gpkg", "not a geopackage");
  expect_io_error([&] { read_footprints(junk); }, junk + ": cannot open");
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  const std::string g = shared("delft/bgt_pand.gpkg");
  FootprintReadOptions o;
  o.layer = "gebouwen";
  std::string w = expect_io_error([&] { read_footprints(g, o); }, "has no layer 'gebouwen'");
  EXPECT_NE(w.find(g), std::string::npos) << w;
  EXPECT_NE(w.find("bgt"), std::string::npos) << "lists the layers: " << w;
  o.layer = "";
  o.id_attribute = "identificatie";
  w = expect_io_error([&] { read_footprints(g, o); }, "has no attribute 'identificatie'");
  EXPECT_NE(w.find("gml_id"), std::string::npos) << "lists the attributes: " << w;
  o.id_attribute = "";
  o.target_crs = "EPSG:99999999";
  expect_io_error([&] { read_footprints(g, o); }, "EPSG:99999999");
  EXPECT_EQ(footprint_layers(g), std::vector<std::string>{"bgt"});
}

TEST(Footprints, PostgisConnectionWithoutServerIsAClearError) {
  // No PostgreSQL server listens on port 1: a prompt error naming the source,
  // with the password masked.
  const std::string pg = "PG:host=127.0.0.1 port=1 dbname=city user=citylod password=s3cret";
  const auto t0 = std::chrono::steady_clock::now();
  const std::string w = expect_io_error([&] { read_footprints(pg); }, "cannot open");
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(15));
  EXPECT_NE(w.find("PG:host=127.0.0.1"), std::string::npos) << w;
  EXPECT_EQ(w.find("s3cret"), std::string::npos) << w;
}

TEST(Footprints, ReaderVersion) {
  const std::string v = footprint_reader_version();
  EXPECT_EQ(v.rfind("GDAL ", 0), 0u) << v;
  EXPECT_NE(v.find("GEOS"), std::string::npos) << v;
}

// With a PostgreSQL + PostGIS server: CITYLOD_TEST_PG="PG:host=... dbname=..." (e.g. a
// throw-away cluster: initdb, pg_ctl start, CREATE EXTENSION postgis). The test loads the
// GeoPackage into table citylod_test_bgt with ogr2ogr and reads it back.
TEST(Footprints, PostgisSameAsGeoPackage) {
  const char* pg = std::getenv("CITYLOD_TEST_PG");
  if (!pg || !*pg) GTEST_SKIP() << "CITYLOD_TEST_PG not set (no PostGIS server to test against)";
  CITYLOD_REQUIRE_SHARED(shared("delft/bgt_pand.gpkg"));
  if (!have_ogr2ogr()) GTEST_SKIP() << "ogr2ogr (gdal-bin) not installed";
  const std::string cmd = std::string(
                              "ogr2ogr -overwrite -nlt PROMOTE_TO_MULTI -nln citylod_test_bgt "
                              "-f PostgreSQL '") +
                          pg + "' '" + shared("delft/bgt_pand.gpkg") + "' >/dev/null 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "ogr2ogr into " << pg << " failed";
  FootprintReadOptions o;
  o.layer = "citylod_test_bgt";
  o.id_attribute = "gml_id";
  const FootprintLayer l = read_footprints(pg, o);
  EXPECT_EQ(l.driver, "PostgreSQL");
  EXPECT_EQ(l.crs_epsg, 28992);
  EXPECT_EQ(l.source_features, 160u);
  expect_same(gpkg(), l, 1e-9, "PostGIS");
  // without a layer name: the database has several tables, or one
  try {
    read_footprints(pg);
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("citylod_test_bgt"), std::string::npos) << e.what();
  }
}
