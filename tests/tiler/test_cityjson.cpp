// CityJSON 2.0 output (tiler/cityjson.hpp): structure by the specification's
// rules, round trip back to the models in the input's CRS, semantics, lod
// mapping, validity records, determinism, bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "citylod/geo/georef.hpp"
#include "citylod/io/error.hpp"
#include "citylod/io/glb_reader.hpp"
#include "citylod/io/writers.hpp"
#include "citylod/lod/validity.hpp"
#include "citylod/tiler/assemble.hpp"
#include "citylod/tiler/cityjson.hpp"
#include "citylod/tiler/workdir.hpp"
#include "support/cityjson_check.hpp"
#include "support/cli_run.hpp"
#include "support/val3dity.hpp"

namespace citylod::test {
namespace {

using io::PolygonMesh;
using io::Vec3d;
using nlohmann::json;

/// A convex solid's polygons, each turned to face away from the centroid.
PolygonMesh convex(const std::vector<Vec3d>& v, const std::vector<std::vector<std::uint32_t>>& f) {
  PolygonMesh m;
  m.vertices = v;
  Vec3d c{0, 0, 0};
  for (const auto& p : v)
    for (int k = 0; k < 3; ++k) c[size_t(k)] += p[size_t(k)] / double(v.size());
  for (auto face : f) {
    Vec3d n{0, 0, 0}, g{0, 0, 0};
    for (std::size_t i = 0; i < face.size(); ++i) {
      const Vec3d &a = v[face[i]], &b = v[face[(i + 1) % face.size()]];
      n[0] += (a[1] - b[1]) * (a[2] + b[2]);
      n[1] += (a[2] - b[2]) * (a[0] + b[0]);
      n[2] += (a[0] - b[0]) * (a[1] + b[1]);
      for (int k = 0; k < 3; ++k) g[size_t(k)] += a[size_t(k)] / double(face.size());
    }
    if (n[0] * (g[0] - c[0]) + n[1] * (g[1] - c[1]) + n[2] * (g[2] - c[2]) < 0)
      std::reverse(face.begin(), face.end());
    m.faces.push_back(face);
  }
  return m;
}

/// Box [x0,x1]x[y0,y1]x[z0,z1] (6 quads).
PolygonMesh box(double x0, double y0, double z0, double x1, double y1, double z1) {
  std::vector<Vec3d> v;
  for (int i = 0; i < 8; ++i)
    v.push_back({(i & 1) ? x1 : x0, (i & 2) ? y1 : y0, (i & 4) ? z1 : z0});
  return convex(
      v, {{0, 1, 3, 2}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 3, 7, 5}});
}

/// Gable house on [x0,x0+w]x[y0,y0+d], walls h, ridge along x at rise r (7 faces).
PolygonMesh house(double x0, double y0, double w, double d, double h, double r) {
  std::vector<Vec3d> v{{x0, y0, 0},
                       {x0 + w, y0, 0},
                       {x0 + w, y0 + d, 0},
                       {x0, y0 + d, 0},
                       {x0, y0, h},
                       {x0 + w, y0, h},
                       {x0 + w, y0 + d, h},
                       {x0, y0 + d, h},
                       {x0, y0 + d / 2, h + r},
                       {x0 + w, y0 + d / 2, h + r}};
  return convex(v, {{0, 1, 2, 3},
                    {0, 1, 5, 4},
                    {3, 2, 6, 7},
                    {0, 3, 7, 8, 4},
                    {1, 2, 6, 9, 5},
                    {4, 5, 9, 8},
                    {7, 6, 9, 8}});
}

// The scene: EPSG:28992 with its origin in Delft; models are made in RD
// coordinates (the truth) and moved to each chunk's ENU frame the way split
// moves the points, so the exporter has to find the RD coordinates again.
const Vec3d kOriginRd{85000, 447500, 0};

struct Scene {
  std::string work;
  tiler::Manifest man;
  geo::Georef georef;
};

Scene make_scene(const std::string& name) {
  Scene s{(fs::path(CITYLOD_TEST_TMP) / "cityjson" / name).string(),
          {},
          geo::Georef::from_crs(geo::Crs::parse("EPSG:28992"),
                                Eigen::Vector3d(kOriginRd[0], kOriginRd[1], kOriginRd[2]))};
  fs::remove_all(s.work);
  fs::create_directories(s.work);
  s.man.scene.crs = "EPSG:28992";
  s.man.scene.origin_crs = {kOriginRd[0], kOriginRd[1], kOriginRd[2]};
  const auto& o = s.georef.frame().origin();
  s.man.scene.origin_lon = o[0];
  s.man.scene.origin_lat = o[1];
  s.man.scene.origin_h = o[2];
  return s;
}

struct Model {
  PolygonMesh rd;  // in RD
  std::string kind = "anchor";
  int level = 0, step = 0;
  bool obj = true;  // write the merged polygons next to the PLY
};

/// Adds a building whose models are given in RD: chunk origin = ENU of the
/// first model's first vertex (rounded), files relative to it.
void add_building(Scene& s, const std::string& id, const std::vector<Model>& models,
                  const std::string& source = "") {
  tiler::ChunkRecord r;
  r.id = id;
  r.source = source;
  const Eigen::Vector3d o = s.georef.to_local(Eigen::Vector3d(
      models[0].rd.vertices[0][0], models[0].rd.vertices[0][1], models[0].rd.vertices[0][2]));
  r.origin = {std::round(o[0]), std::round(o[1]), std::round(o[2])};
  r.status = tiler::Status::ok;
  const std::string dir = tiler::lod_dir(s.work, id);
  fs::create_directories(dir);
  tiler::LodReport rep;
  rep.input = "synthetic";
  rep.status = tiler::Status::ok;
  rep.bbox_diagonal_m = 20;
  for (const Model& m : models) {
    PolygonMesh local = m.rd;
    for (auto& v : local.vertices) {
      const Eigen::Vector3d e = s.georef.to_local(Eigen::Vector3d(v[0], v[1], v[2]));
      v = {e[0] - r.origin[0], e[1] - r.origin[1], e[2] - r.origin[2]};
    }
    char stem[64];
    std::snprintf(stem, sizeof stem, "model_%d_%s_L%d", m.step, m.kind.c_str(), m.level);
    const io::TriangleMesh tri =
        io::triangulate_polygons(local);  // ear clipping: L-shaped walls too
    io::write_ply((fs::path(dir) / (std::string(stem) + ".ply")).string(), tri);
    if (m.obj) io::write_obj((fs::path(dir) / (std::string(stem) + ".obj")).string(), local);
    tiler::ModelRecord mr;
    mr.file = std::string(stem) + ".ply";
    mr.kind = tiler::model_kind_from_string(m.kind);
    mr.level = m.level;
    mr.step = m.step;
    mr.triangles = tri.triangles.size();
    mr.e2 = 1.5 - 0.5 * m.step;                  // % of the 20 m diagonal
    if (m.step == 1) mr.roof_rmse_m = 0.123456;  // measured on airborne LiDAR only
    rep.models.push_back(mr);
  }
  tiler::write_lod_report(tiler::lod_report_path(s.work, id), rep);
  s.man.chunks.push_back(r);
  tiler::write_manifest(s.work, s.man);
}

/// box (anchor L0) -> low gable (interpolation L1) -> gable (anchor L1), in RD.
std::vector<Model> chain(double x0, double y0) {
  return {{box(x0, y0, 0, x0 + 12, y0 + 9, 8), "anchor", 0, 0, true},
          {house(x0, y0, 12, 9, 8, 1.5), "interpolation", 1, 1, true},
          {house(x0, y0, 12, 9, 8, 3.0), "anchor", 1, 2, true}};
}

tiler::CityJsonOptions opts(int threads = 2) {
  tiler::CityJsonOptions o;
  o.threads = threads;
  return o;
}

const json& object_of(const json& f) {
  return f["CityObjects"][f["id"].get<std::string>()];
}

/// The whole chain (support/cityjson_check.hpp), its objects checked.
std::vector<std::pair<json, json>> chain_of(const json& f) {
  for (const auto& p : chain_problems(f)) ADD_FAILURE() << p;
  return feature_chain(f);
}

TEST(CityJson, StructureFollowsTheSpecification) {
  Scene s = make_scene("structure");
  add_building(s, "fp-A1", chain(85010, 447510), "footprint:A1");
  add_building(s, "fp-B2", chain(85040, 447530), "footprint:B2");
  const std::string out = s.work + "/structure.city.jsonl";
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.buildings, 2u);
  EXPECT_EQ(st.geometries, 6u);
  EXPECT_EQ(st.chain_objects, 2u);
  EXPECT_EQ(st.invalid, 0u);
  EXPECT_EQ(st.multi_lod, 2u);
  EXPECT_EQ(st.full_semantics, 2u);
  EXPECT_EQ(st.triangulated, 0u);
  const CjSeq seq = read_cjseq(out);
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  EXPECT_EQ(seq.header["metadata"]["referenceSystem"],
            "https://www.opengis.net/def/crs/EPSG/0/28992");
  EXPECT_EQ(seq.header["transform"]["scale"][0], 0.0001);
  ASSERT_EQ(seq.features.size(), 2u);
  // the footprint's own id, the chunk id as an attribute
  EXPECT_EQ(seq.features[0]["id"], "A1");
  EXPECT_EQ(object_of(seq.features[0])["type"], "Building");
  EXPECT_EQ(object_of(seq.features[0])["attributes"]["citylod_id"], "fp-A1");
  // one geometry per lod on the Building (the block LoD1.2, the finest
  // LoD2.2), with the per-model attributes aligned; the rest of the chain
  // (the low gable) as a +LodTreeModel object of the Extension
  EXPECT_EQ(seq.header["extensions"]["LodTree"]["version"], "1.0");
  const json& o = object_of(seq.features[1]);
  ASSERT_EQ(o["geometry"].size(), 2u);
  EXPECT_EQ(o["geometry"][0]["lod"], "1.2");
  EXPECT_EQ(o["geometry"][1]["lod"], "2.2");
  EXPECT_FALSE(o.contains("children"));  // val3dity would read them as BuildingParts
  ASSERT_EQ(seq.features[1]["CityObjects"].size(), 2u);
  const json& ms = o["attributes"]["citylod_models"];
  ASSERT_EQ(ms.size(), 2u);
  EXPECT_EQ(ms[1]["triangles"], 16);  // fan: 5 quads x 2 + 2 pentagons x 3
  EXPECT_EQ(ms[1]["polygons"], 7);
  EXPECT_EQ(ms[1]["error_m"], 0.0);
  const auto whole = chain_of(seq.features[1]);
  ASSERT_EQ(whole.size(), 3u);
  EXPECT_EQ(whole[1].first["lod"], "2.1");
  EXPECT_EQ(whole[1].second["kind"], "interpolation");
  EXPECT_EQ(whole[1].second["level"], 1);
  EXPECT_EQ(whole[1].second["step"], 1);
  EXPECT_NEAR(whole[1].second["rmse_m"].get<double>(), 0.01 * 20, 1e-9);     // e2 1 % of 20 m
  EXPECT_NEAR(whole[1].second["roof_rmse_m"].get<double>(), 0.1235, 1e-12);  // to 0.1 mm
  EXPECT_FALSE(whole[0].second.contains("roof_rmse_m"));
  for (const auto& [g, m] : whole) {
    EXPECT_EQ(m["lod"], g["lod"]);
    EXPECT_TRUE(m["valid"].get<bool>());
  }
  // the extent is in RD
  const auto& e = seq.header["metadata"]["geographicalExtent"];
  EXPECT_NEAR(e[0].get<double>(), 85010, 1e-3);
  EXPECT_NEAR(e[4].get<double>(), 447539, 1e-3);
  EXPECT_NEAR(e[5].get<double>(), 11, 1e-3);
}

TEST(CityJson, RoundTripGivesBackTheModelsInTheCrs) {
  Scene s = make_scene("roundtrip");
  const std::vector<Model> models = chain(85110.1234, 447610.5678);
  add_building(s, "b-1", models);
  const std::string out = s.work + "/roundtrip.city.jsonl";
  tiler::write_cityjson(s.work, out, opts());
  const CjSeq seq = read_cjseq(out);
  ASSERT_EQ(seq.features.size(), 1u);
  EXPECT_EQ(seq.features[0]["id"], "b-1");  // no footprint: the chunk id
  const auto v = feature_vertices(seq.header, seq.features[0]);
  const auto whole = chain_of(seq.features[0]);
  ASSERT_EQ(whole.size(), models.size());
  // quantized to 0.1 mm: each coordinate within half a step (+ the ENU round trip)
  const double tol = 0.00005 + 1e-6;
  for (std::size_t g = 0; g < models.size(); ++g) {
    const PolygonMesh& truth = models[g].rd;
    const json& b = whole[g].first["boundaries"];
    ASSERT_EQ(b.size(), 1u);
    ASSERT_EQ(b[0].size(), truth.faces.size()) << "geometry " << g;
    // face by face, vertex by vertex, in the same order
    for (std::size_t f = 0; f < truth.faces.size(); ++f) {
      const json& ring = b[0][f][0];
      ASSERT_EQ(ring.size(), truth.faces[f].size());
      for (std::size_t i = 0; i < ring.size(); ++i) {
        const auto& p = v[ring[i].get<std::size_t>()];
        const Vec3d& q = truth.vertices[truth.faces[f][i]];
        for (int k = 0; k < 3; ++k)
          EXPECT_NEAR(p[size_t(k)], q[size_t(k)], tol) << "geometry " << g << " face " << f;
      }
    }
    const SolidCheck c = check_solid(b, feature_vertices(seq.header, seq.features[0], true));
    EXPECT_TRUE(c.valid()) << "geometry " << g;
  }
  // one vertex list for the building: the box's 8 corners are shared by the houses
  EXPECT_EQ(v.size(), 8u + 2u + 2u);
}

TEST(CityJson, SemanticsFromFaceNormals) {
  Scene s = make_scene("semantics");
  // an overhang: an upper box wider than the lower one (its underside faces down, 3 m up)
  PolygonMesh m;
  m.vertices = {{0, 0, 0},  {10, 0, 0}, {10, 10, 0}, {0, 10, 0},    // 0-3 ground
                {0, 0, 6},  {12, 0, 6}, {12, 10, 6}, {0, 10, 6},    // 4-7 roof
                {10, 0, 3}, {12, 0, 3}, {12, 10, 3}, {10, 10, 3}};  // 8-11 overhang
  for (auto& p : m.vertices) p = {p[0] + 85000, p[1] + 447500, p[2]};
  m.faces = {{0, 3, 2, 1},          // ground (down)
             {4, 5, 6, 7},          // roof (up)
             {8, 11, 10, 9},        // overhang underside (down, 3 m up)
             {0, 1, 8, 9, 5, 4},    // south wall (y = 0)
             {3, 7, 6, 10, 11, 2},  // north wall (y = 10)
             {0, 4, 7, 3},          // west wall
             {1, 2, 11, 8},         // east wall, lower part (x = 10)
             {9, 10, 6, 5}};        // east wall, upper part (x = 12)
  add_building(s, "b-overhang", {{m, "anchor", 0, 0, true}});
  const std::string out = s.work + "/semantics.city.jsonl";
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.invalid, 0u);
  const CjSeq seq = read_cjseq(out);
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  const json& g = object_of(seq.features[0])["geometry"][0];
  std::vector<std::string> types;
  for (const auto& i : g["semantics"]["values"][0])
    types.push_back(g["semantics"]["surfaces"][i.get<std::size_t>()]["type"]);
  const std::vector<std::string> want{"GroundSurface", "RoofSurface", "OuterCeilingSurface",
                                      "WallSurface",   "WallSurface", "WallSurface",
                                      "WallSurface",   "WallSurface"};
  EXPECT_EQ(types, want);
  EXPECT_EQ(g["lod"], "2.2");  // the finest (only) model
}

TEST(CityJson, TriangulatedAndInvalidModelsAreRecorded) {
  Scene s = make_scene("records");
  // no OBJ: the PLY's triangles are the faces
  add_building(s, "b-tri", {{box(85000, 447500, 0, 85010, 447508, 6), "anchor", 0, 0, false}});
  // an open box (no ground): not a valid solid even welded: left out, the
  // Building is written without geometry and a warning names it
  PolygonMesh open = box(85030, 447500, 0, 85040, 447508, 6);
  open.faces.erase(std::remove_if(open.faces.begin(), open.faces.end(),
                                  [&](const auto& f) {
                                    for (auto i : f)
                                      if (open.vertices[i][2] != 0) return false;
                                    return true;
                                  }),
                   open.faces.end());
  ASSERT_EQ(open.faces.size(), 5u);
  add_building(s, "b-open", {{open, "anchor", 0, 0, true}});
  const std::string out = s.work + "/records.city.jsonl";
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.buildings, 2u);
  EXPECT_EQ(st.triangulated, 1u);
  EXPECT_EQ(st.invalid, 1u);
  ASSERT_EQ(st.warnings.size(), 2u);
  EXPECT_NE(st.warnings[0].find("b-open model step 0 left out"), std::string::npos)
      << st.warnings[0];
  EXPECT_NE(st.warnings[0].find("error 302"), std::string::npos) << st.warnings[0];
  EXPECT_NE(st.warnings[1].find("b-open has no model"), std::string::npos) << st.warnings[1];
  const CjSeq seq = read_cjseq(out);
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  const json& open_obj = object_of(seq.features[0]);  // "b-open" < "b-tri"
  EXPECT_TRUE(open_obj["geometry"].empty());
  EXPECT_TRUE(open_obj["attributes"]["citylod_models"].empty());
  const json& tri = object_of(seq.features[1]);
  EXPECT_EQ(tri["geometry"][0]["boundaries"][0].size(), 12u);
  EXPECT_TRUE(tri["attributes"]["citylod_models"][0]["valid"].get<bool>());
  EXPECT_EQ(tri["geometry"][0]["lod"], "2.2");
}

// A model that is a sliver (a prism on a triangle 5 mm across, as the LOD stage
// made for City3D's scene building 07000) has no face left once welded: it is
// left out with a warning naming it, the building keeps its other model, and
// the writer does not fail (it read past the per-face errors of no face).
TEST(CityJson, ASliverModelIsLeftOut) {
  Scene s = make_scene("sliver");
  const double x = 85000, y = 447500;
  const std::vector<Vec3d> tri = {
      {x + 0.918, y + 1.841, 0}, {x + 0.9222, y + 1.8437, 0}, {x + 0.922, y + 1.844, 0}};
  std::vector<Vec3d> v = tri;
  for (const auto& q : tri) v.push_back({q[0], q[1], 1.85});
  const PolygonMesh sliver =
      convex(v, {{0, 1, 2}, {3, 4, 5}, {0, 1, 4, 3}, {1, 2, 5, 4}, {2, 0, 3, 5}});
  add_building(s, "b-sliver",
               {{box(x - 2, y - 2, 0, x + 4, y + 4, 3), "anchor", 0, 0, true},
                {sliver, "anchor", 1, 1, true}});
  const std::string out = s.work + "/sliver.city.jsonl";
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.buildings, 1u);
  EXPECT_EQ(st.invalid, 1u);
  ASSERT_EQ(st.warnings.size(), 1u);
  EXPECT_NE(st.warnings[0].find("b-sliver model step 1 left out"), std::string::npos)
      << st.warnings[0];
  const CjSeq seq = read_cjseq(out);
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  EXPECT_EQ(object_of(seq.features[0])["attributes"]["citylod_models"].size(), 1u);
}

/// The first geometry of a file's first feature as a validator reads it
/// (vertices relative to translate, every shell).
lod::PolygonSolid written_solid(const CjSeq& seq) {
  lod::PolygonSolid solid;
  for (const auto& p : feature_vertices(seq.header, seq.features[0], true))
    solid.vertices.emplace_back(p[0], p[1], p[2]);
  for (const auto& shell : object_of(seq.features[0])["geometry"][0]["boundaries"]) {
    solid.shells.emplace_back();
    for (const auto& f : shell) solid.shells.back().push_back(f[0].get<std::vector<int>>());
  }
  return solid;
}

/// val3dity itself, when beside the shared data, finds every Solid of `file` valid.
void expect_val3dity_valid(const std::string& file, std::size_t solids) {
  if (val3dity_binary().empty()) return;
  const Val3dityResult v3 = run_val3dity(file, file + ".val3dity.json");
  ASSERT_TRUE(v3.ran) << v3.why;
  EXPECT_EQ(v3.primitives, solids);
  EXPECT_EQ(v3.valid_primitives, solids) << v3.first_error;
}

// Issue 26: a vertex 0.3 mm from a corner (a T-junction on the top face's edge
// and on the wall's) is exact and closed, but a validator snaps it onto the
// corner (val3dity: 102 CONSECUTIVE_POINTS_SAME). The writer welds it away.
TEST(CityJson, VerticesWithinTheValidatorsSnapAreWelded) {
  Scene s = make_scene("weld");
  const double x0 = 85000, y0 = 447500, x1 = 85010, y1 = 447508, h = 6;
  std::vector<Vec3d> v;
  for (int i = 0; i < 8; ++i) v.push_back({(i & 1) ? x1 : x0, (i & 2) ? y1 : y0, (i & 4) ? h : 0});
  v.push_back({x0, y1 - 0.0003, h});  // 8: on the edge 6-4
  const PolygonMesh m = convex(
      v,
      {{0, 2, 3, 1}, {4, 5, 7, 6, 8}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 8, 6, 2}, {1, 3, 7, 5}});
  add_building(s, "b-weld", {{m, "anchor", 0, 0, true}});
  const std::string out = s.work + "/weld.city.jsonl";
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.invalid, 0u);
  EXPECT_EQ(st.triangulated, 0u);  // the polygons, welded
  const CjSeq seq = read_cjseq(out);
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  const json& o = object_of(seq.features[0]);
  ASSERT_EQ(o["geometry"].size(), 1u);
  EXPECT_NEAR(o["attributes"]["citylod_models"][0]["snapped_m"].get<double>(), 0.0011, 1e-12);
  EXPECT_EQ(seq.features[0]["vertices"].size(), 8u);
  // what the validator reads: valid, no two vertices within 1 mm
  const lod::PolygonSolid solid = written_solid(seq);
  const lod::SolidCheck c = lod::check_solid(solid);
  EXPECT_TRUE(c.valid()) << c.error << " " << c.detail;
  EXPECT_GT(lod::min_vertex_distance(solid), 0.001);
  for (const auto& f : solid.shells[0]) EXPECT_EQ(f.size(), 4u);
  expect_val3dity_valid(out, 1);
}

// A roof ring that runs out along an edge and comes back on it (4 -> 5 -> m, m
// halfway between 4 and 5: a zero-width hair; the Delft tile had one on a roof,
// val3dity 204 / 104) is exact and closed, but not valid to a validator. The
// writer takes the hair out and puts m on the wall's edge 5 -> 4.
TEST(CityJson, CollinearSpikesAreTakenOut) {
  Scene s = make_scene("spike");
  const double x0 = 85000, y0 = 447500, x1 = 85010, y1 = 447508, h = 6;
  std::vector<Vec3d> v;
  for (int i = 0; i < 8; ++i) v.push_back({(i & 1) ? x1 : x0, (i & 2) ? y1 : y0, (i & 4) ? h : 0});
  v.push_back({(x0 + x1) / 2, y0, h});  // 8 = m
  PolygonMesh m;
  m.vertices = v;
  m.faces = {{0, 2, 3, 1}, {4, 5, 8, 7, 6}, {8, 5, 7},   {0, 1, 5, 4},
             {2, 6, 7, 3}, {0, 4, 6, 2},    {1, 3, 7, 5}};
  add_building(s, "b-spike", {{m, "anchor", 0, 0, true}});
  const std::string out = s.work + "/spike.city.jsonl";
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.invalid, 0u);
  const CjSeq seq = read_cjseq(out);
  const json& o = object_of(seq.features[0]);
  ASSERT_EQ(o["geometry"].size(), 1u);
  std::vector<std::size_t> sizes;
  for (const auto& f : o["geometry"][0]["boundaries"][0]) sizes.push_back(f[0].size());
  // the top loses the tip (4 vertices), the south wall gains m (5)
  EXPECT_EQ(sizes, (std::vector<std::size_t>{4, 4, 3, 5, 4, 4, 4}));
  EXPECT_TRUE(lod::check_solid(written_solid(seq)).valid());
  expect_val3dity_valid(out, 1);
  // as it was, the validator rejects it
  lod::PolygonSolid before;
  for (const auto& p : m.vertices) before.vertices.emplace_back(p[0] - x0, p[1] - y0, p[2]);
  before.shells.emplace_back();
  for (const auto& f : m.faces) before.shells[0].emplace_back(f.begin(), f.end());
  EXPECT_FALSE(lod::check_solid(before).valid());
}

/// `m` with the faces of `other` added (turned round: facing into it).
void add_faces(PolygonMesh& m, const PolygonMesh& other, bool turned) {
  const auto base = std::uint32_t(m.vertices.size());
  m.vertices.insert(m.vertices.end(), other.vertices.begin(), other.vertices.end());
  for (auto f : other.faces) {
    if (turned) std::reverse(f.begin(), f.end());
    for (auto& i : f) i += base;
    m.faces.push_back(f);
  }
}

/// `m` as the one anchor model of building `id`, written to `out`: no model
/// left out, no structure problem; the file read back.
CjSeq write_one_model(Scene& s, const std::string& id, const PolygonMesh& m,
                      const std::string& out) {
  add_building(s, id, {{m, "anchor", 0, 0, true}});
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.invalid, 0u);
  CjSeq seq = read_cjseq(out);
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  return seq;
}

// A model with a cavity (a room seen through windows) is one Solid with an
// inner shell: val3dity reads the faces of one shell as one connected surface
// (305 otherwise).
TEST(CityJson, CavitiesAreInnerShells) {
  Scene s = make_scene("cavity");
  PolygonMesh m = box(85000, 447500, 0, 85010, 447508, 6);
  add_faces(m, box(85003, 447503, 2, 85005, 447505, 4), true);  // facing into the cavity
  const std::string out = s.work + "/cavity.city.jsonl";
  const CjSeq seq = write_one_model(s, "b-cavity", m, out);
  const json& g = object_of(seq.features[0])["geometry"][0];
  ASSERT_EQ(g["boundaries"].size(), 2u);  // outer shell, then the cavity
  EXPECT_EQ(g["boundaries"][0].size(), 6u);
  EXPECT_EQ(g["boundaries"][1].size(), 6u);
  EXPECT_EQ(g["semantics"]["values"].size(), 2u);
  // the outer shell holds the outer box: its x extent is 10 m
  const auto v = feature_vertices(seq.header, seq.features[0]);
  double lo = 1e300, hi = -1e300;
  for (const auto& f : g["boundaries"][0])
    for (const auto& i : f[0]) {
      lo = std::min(lo, v[i.get<std::size_t>()][0]);
      hi = std::max(hi, v[i.get<std::size_t>()][0]);
    }
  EXPECT_NEAR(hi - lo, 10, 1e-3);
  EXPECT_TRUE(lod::check_solid(written_solid(seq)).valid());
  expect_val3dity_valid(out, 1);
}

// A model in two pieces apart (an annex no plane connects) is a MultiSolid of
// two one-shell Solids: as one Solid the second piece would be a cavity
// oriented outwards (val3dity's 307).
TEST(CityJson, PiecesApartAreAMultiSolid) {
  Scene s = make_scene("pieces");
  PolygonMesh m = box(85000, 447500, 0, 85010, 447508, 6);
  add_faces(m, box(85014, 447500, 0, 85018, 447504, 3), false);  // the annex, 4 m apart
  const std::string out = s.work + "/pieces.city.jsonl";
  const CjSeq seq = write_one_model(s, "b-pieces", m, out);
  const json& g = object_of(seq.features[0])["geometry"][0];
  EXPECT_EQ(g["type"], "MultiSolid");
  ASSERT_EQ(g["boundaries"].size(), 2u);  // two Solids of one shell each
  const auto v = feature_vertices(seq.header, seq.features[0], true);
  double volume = 0;
  for (const auto& solid : g["boundaries"]) {
    ASSERT_EQ(solid.size(), 1u);
    EXPECT_EQ(solid[0].size(), 6u);
    const SolidCheck c = check_solid(solid, v);
    EXPECT_TRUE(c.valid());
    volume += c.volume;
  }
  EXPECT_NEAR(volume, 10 * 8 * 6 + 4 * 4 * 3, 1e-3);
  EXPECT_TRUE(check_geometry(g, v).valid());
  EXPECT_EQ(g["semantics"]["values"].size(), 2u);
  expect_val3dity_valid(out, 1);
}

TEST(CityJson, SameBytesWhateverTheThreads) {
  Scene s = make_scene("threads");
  for (int i = 0; i < 12; ++i)
    add_building(s, "b-" + std::to_string(100 + i),
                 chain(85000 + 30 * (i % 4), 447500 + 25 * (i / 4)));
  const std::string a = s.work + "/t1.city.jsonl", b = s.work + "/t3.city.jsonl";
  tiler::write_cityjson(s.work, a, opts(1));
  tiler::write_cityjson(s.work, b, opts(3));
  EXPECT_EQ(slurp(a), slurp(b));
  EXPECT_FALSE(fs::exists(a + ".partial"));
  EXPECT_FALSE(fs::exists(a + ".partial.body"));
}

TEST(CityJson, TakesTheChainsItIsGiven) {
  Scene s = make_scene("chains");
  add_building(s, "fp-A1", chain(85010, 447510));
  add_building(s, "fp-B2", chain(85040, 447530));
  const std::string chosen = s.work + "/chosen.city.jsonl", given = s.work + "/given.city.jsonl";
  tiler::write_cityjson(s.work, chosen, opts());
  // A's chain as assemble would hand it (the finest model only, an error of 0);
  // B is not in the map and is chosen as usual; an index past B's models is ignored.
  std::map<std::string, tiler::ModelChoice> chains;
  chains["fp-A1"] = {{2}, {0.0}, {0.0}};
  tiler::CityJsonOptions o = opts();
  o.chains = &chains;
  tiler::write_cityjson(s.work, given, o);
  const CjSeq a = read_cjseq(chosen), b = read_cjseq(given);
  ASSERT_EQ(b.features.size(), 2u);
  EXPECT_EQ(chain_of(a.features[0]).size(), 3u);
  ASSERT_EQ(object_of(b.features[0])["geometry"].size(), 1u);
  const json &g = object_of(b.features[0])["geometry"][0],
             &finest = object_of(a.features[0])["geometry"][1];  // vertex indices differ
  EXPECT_EQ(g["lod"], finest["lod"]);
  EXPECT_EQ(g["semantics"], finest["semantics"]);
  EXPECT_EQ(g["boundaries"][0].size(), finest["boundaries"][0].size());
  EXPECT_EQ(object_of(b.features[0])["attributes"]["citylod_models"][0]["step"], 2);
  EXPECT_EQ(b.features[1], a.features[1]);
  chains["fp-B2"] = {{0, 7}, {1.0, 0.0}, {1.0, 0.0}};
  tiler::write_cityjson(s.work, given, o);
  EXPECT_EQ(read_cjseq(given).features[1], a.features[1]);
}

TEST(CityJson, LocalSceneKeepsEnuMetresWithoutReferenceSystem) {
  Scene s = make_scene("local");
  s.man.scene.crs = "";
  s.man.scene.origin_crs = {0, 0, 0};
  // with no CRS the "RD" numbers of add_building are only used through the
  // georef to build the chunk files: write a chunk directly in ENU instead
  tiler::ChunkRecord r;
  r.id = "b-local";
  r.origin = {100, 200, 0};
  r.status = tiler::Status::ok;
  const std::string dir = tiler::lod_dir(s.work, r.id);
  fs::create_directories(dir);
  const PolygonMesh m = box(0, 0, 0, 10, 8, 5);
  io::write_ply(dir + "/model_0_anchor_L0.ply", io::triangulate_fan(m));
  io::write_obj(dir + "/model_0_anchor_L0.obj", m);
  tiler::LodReport rep;
  rep.status = tiler::Status::ok;
  tiler::ModelRecord mr;
  mr.file = "model_0_anchor_L0.ply";
  rep.models.push_back(mr);
  tiler::write_lod_report(tiler::lod_report_path(s.work, r.id), rep);
  s.man.chunks = {r};
  tiler::write_manifest(s.work, s.man);
  const std::string out = s.work + "/local.city.jsonl";
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, opts());
  EXPECT_EQ(st.reference_system, "");
  const CjSeq seq = read_cjseq(out);
  for (const auto& p : cjseq_problems(seq)) ADD_FAILURE() << p;
  EXPECT_FALSE(seq.header["metadata"].contains("referenceSystem"));
  const auto& e = seq.header["metadata"]["geographicalExtent"];
  const std::vector<double> want{100, 200, 0, 110, 208, 5};
  for (std::size_t k = 0; k < 6; ++k) EXPECT_NEAR(e[k].get<double>(), want[k], 1e-9);
  EXPECT_TRUE(object_of(seq.features[0])["attributes"]["citylod_models"][0]["rmse_m"].is_null());
}

TEST(CityJson, BadInputIsOneClearError) {
  Scene s = make_scene("bad");
  add_building(s, "b-ok", chain(85000, 447500));
  tiler::ChunkRecord missing;
  missing.id = "b-missing";
  missing.status = tiler::Status::ok;
  s.man.chunks.push_back(missing);
  tiler::write_manifest(s.work, s.man);
  const std::string out = s.work + "/bad.city.jsonl";
  try {
    tiler::write_cityjson(s.work, out, opts());
    ADD_FAILURE() << "no error";
  } catch (const std::exception& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("b-missing"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  }
  EXPECT_FALSE(fs::exists(out));
  EXPECT_FALSE(fs::exists(out + ".partial.body"));
  // skip_missing: the others are written
  tiler::CityJsonOptions o = opts();
  o.skip_missing = true;
  const tiler::CityJsonStats st = tiler::write_cityjson(s.work, out, o);
  EXPECT_EQ(st.buildings, 1u);
  EXPECT_EQ(st.skipped, 1u);
  // no work directory, bad option
  EXPECT_THROW(tiler::write_cityjson(s.work + "/nope", out, opts()), io::IoError);
  o.scale = 0;
  EXPECT_THROW(tiler::write_cityjson(s.work, out, o), std::invalid_argument);
  // a manifest whose origin is not where its CRS puts origin_crs
  s.man.scene.origin_h += 10;
  tiler::write_manifest(s.work, s.man);
  EXPECT_THROW(tiler::write_cityjson(s.work, out, opts()), io::IoError);
}

TEST(CityJson, LodMappingAndReferenceSystem) {
  EXPECT_EQ(tiler::cityjson_lod(true, true, true, 0), "1.2");     // fallback
  EXPECT_EQ(tiler::cityjson_lod(false, true, false, 1), "2.2");   // finest
  EXPECT_EQ(tiler::cityjson_lod(false, false, false, 1), "1.2");  // one flat roof height
  EXPECT_EQ(tiler::cityjson_lod(false, false, false, 3), "1.3");  // flat roofs, several heights
  EXPECT_EQ(tiler::cityjson_lod(false, false, true, 0), "2.1");   // coarser, sloped
  EXPECT_EQ(tiler::cityjson_reference_system("EPSG:28992"),
            "https://www.opengis.net/def/crs/EPSG/0/28992");
  EXPECT_EQ(tiler::cityjson_reference_system("EPSG:7415"),
            "https://www.opengis.net/def/crs/EPSG/0/7415");
  EXPECT_EQ(tiler::cityjson_reference_system(""), "");
}

// Issue 14 item 4: each feature of the tiles carries its model's RMSE to the
// points and its validity, next to its place in the chain (kind, level, step).
TEST(CityJson, TileFeaturesCarryRmseAndValidity) {
  Scene s = make_scene("tile_quality");
  add_building(s, "b-chain", chain(85000, 447500));
  PolygonMesh open = box(85030, 447500, 0, 85040, 447508, 6);
  open.faces.pop_back();  // one wall missing: not closed
  add_building(s, "b-open", {{open, "anchor", 0, 0, true}});
  tiler::AssembleParams p;
  p.threads = 2;
  tiler::assemble(s.work, s.work + "/tiles", p);
  std::map<std::pair<std::string, int>, std::pair<double, double>>
      got;  // (id, step) -> rmse, valid
  for (const auto& e : fs::directory_iterator(s.work + "/tiles/tiles")) {
    const io::GlbDocument d = io::read_glb(e.path().string());
    for (const auto& t : d.property_tables)
      for (std::size_t i = 0; i < t.count; ++i)
        got[{t.strings.at("building_id")[i], int(t.numbers.at("step")[i])}] = {
            t.numbers.at("rmse")[i], t.numbers.at("valid")[i]};
  }
  ASSERT_EQ(got.size(), 4u);  // the chain's 3 kept models + the open box
  for (int step = 0; step < 3; ++step) {
    const auto& [rmse, valid] = got.at({"b-chain", step});
    EXPECT_NEAR(rmse, (1.5 - 0.5 * step) / 100 * 20, 1e-6);  // e2 % x 20 m diagonal
    EXPECT_EQ(valid, 1.0);
  }
  EXPECT_EQ(got.at({"b-open", 0}).second, 0.0);
}

}  // namespace
}  // namespace citylod::test
