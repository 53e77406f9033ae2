// The city run through the library (no binary): the work directory's records,
// the LOD stage (resume, overrides), run_city(), rebuild() and the
// supervisor's crash path. The scene is the bundled example
// (examples/delft_small, 13 buildings with footprints).
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include "citylod/io/error.hpp"
#include "citylod/io/hash.hpp"
#include "citylod/tiler/city_run.hpp"
#include "citylod/tiler/lod_stage.hpp"
#include "citylod/tiler/supervise.hpp"
#include "citylod/tiler/workdir.hpp"
#include "support/cli_run.hpp"

namespace fs = std::filesystem;
using namespace citylod;
using namespace citylod::tiler;

namespace {

const fs::path kExample = fs::path(CITYLOD_SOURCE_DIR) / "examples" / "delft_small";

fs::path fresh_dir(const std::string& name) {
  return test::tmp_dir("city_run_" + name);
}

CityRunOptions example_options(const fs::path& out) {
  CityRunOptions o;
  o.out_dir = out.string();
  o.split.inputs = {(kExample / "delft_small.las").string()};
  o.split.crs = "EPSG:28992";
  o.split.footprints = (kExample / "footprints.geojson").string();
  o.threads = 2;
  return o;
}

using test::slurp;
using test::tree;

/// supervise() whose first attempt crashes (SIGABRT: not intercepted by ASan)
/// with these buildings' `.running` markers in place; later attempts succeed.
int crash_once(const std::string& work, const std::vector<std::string>& running,
               const fs::path& marker, int& crashes) {
  return supervise(
      work,
      [&]() {
        if (!fs::exists(marker)) {
          std::ofstream(marker) << "1";
          for (const auto& id : running)
            std::ofstream(lod_dir(work, id) + ".running") << id << "\n";
          std::raise(SIGABRT);
        }
        return 0;
      },
      3, &crashes);
}

/// A split work directory of the example (split only: fast).
std::string split_example(const fs::path& dir) {
  CityRunOptions o = example_options(dir);
  o.split.work_dir = (dir / "work").string();
  split_scene(o.split);
  return o.split.work_dir;
}

/// The LOD stage of a work directory with the city parameters, two buildings at once.
LodStageOptions stage_options(const std::string& work) {
  LodStageOptions o;
  o.work_dir = work;
  o.params = city_lod_params();
  o.threads = 2;
  return o;
}

/// The first non-skipped building of the manifest.
std::string first_building(const std::string& work) {
  for (const auto& c : read_manifest(work).chunks)
    if (!c.skipped()) return c.id;
  return "";
}

}  // namespace

// ------------------------------------------------------------ records
TEST(WorkDir, LodReportRoundTripsByteForByte) {
  const fs::path d = fresh_dir("report_roundtrip");
  LodReport r;
  r.input = "chunk.ply";
  r.status = Status::fallback;
  r.reason = "planes: no plane found";
  r.id = "fp-1";
  r.key = "0123456789abcdef";
  r.parameters = {{"planes.epsilon", "0.15"}};
  r.threads = 3;
  r.counts = {{"P", 12}, {"models", 2}};
  r.timings_s = {{"T1_ioview", 0.25}};
  r.notes = {"a note"};
  ModelRecord m;
  m.file = "model_00_anchor_L0.ply";
  m.e1 = 1.5;
  m.e2 = 0.1234567890123;
  m.roof_rmse_m = 0.25;  // airborne only: written when measured
  r.models = {m};
  m.file = "model_01_interpolation_L1.ply";
  m.roof_rmse_m = -1;
  m.kind = ModelKind::interpolation;
  m.step = 1;
  r.models_all = std::vector<ModelRecord>{r.models[0], m};
  r.selected_steps = {0};
  const std::string path = (d / "report.json").string();
  EXPECT_TRUE(write_lod_report(path, r));
  const std::string bytes = slurp(path);
  const LodReport back = read_lod_report(path);
  EXPECT_EQ(back.status, Status::fallback);
  // The threads sit among the recorded parameters (the format's place for them)
  // and come back as the execution setting, not as a parameter.
  EXPECT_NE(bytes.find("\"threads\": \"3\""), std::string::npos) << bytes;
  EXPECT_EQ(back.threads, 3);
  EXPECT_EQ(back.parameters, r.parameters);
  EXPECT_EQ(back.models.size(), 1u);
  ASSERT_TRUE(back.models_all.has_value());
  EXPECT_EQ(back.all_models()[1].kind, ModelKind::interpolation);
  EXPECT_EQ(back.models[0].roof_rmse_m, 0.25);
  EXPECT_EQ(back.all_models()[1].roof_rmse_m, -1);
  EXPECT_EQ(bytes.find("\"roof_rmse_m\"", bytes.find("model_01")), std::string::npos) << bytes;
  EXPECT_FALSE(write_lod_report(path, back));  // same bytes: not rewritten
  EXPECT_EQ(slurp(path), bytes);
}

TEST(WorkDir, FaceColoursRoundTripAsRuns) {
  const fs::path d = fresh_dir("report_colours");
  LodReport r;
  r.status = Status::ok;
  ModelRecord m;
  m.file = "model_00_anchor_L0.ply";
  m.polygons = 4;
  m.triangles = 6;
  const FaceColour red{200, 10, 10, 255}, none{0, 0, 0, 0};
  m.polygon_colours = {red, red, none, FaceColour{1, 2, 3, 255}};
  m.triangle_colours = {none, none, red, red, red, none};
  r.models = {m};
  const std::string path = (d / "report.json").string();
  write_lod_report(path, r);
  const nlohmann::json j = nlohmann::json::parse(slurp(path));
  EXPECT_EQ(j["models"][0]["colours"]["polygons"].dump(), "[[2,200,10,10],[1],[1,1,2,3]]");
  EXPECT_EQ(j["models"][0]["colours"]["triangles"].dump(), "[[2],[3,200,10,10],[1]]");
  const LodReport back = read_lod_report(path);
  EXPECT_EQ(back.models[0].polygon_colours, m.polygon_colours);
  EXPECT_EQ(back.models[0].triangle_colours, m.triangle_colours);
  // runs that do not add up to the faces, or values beyond a byte: one error naming the file
  for (const char* bad :
       {R"([[3,1,2,3]])", R"([[4,1,2,300]])", R"([[2],[2,1,2]])", R"([[0],[4]])"}) {
    nlohmann::json k = j;
    k["models"][0]["colours"]["polygons"] = nlohmann::json::parse(bad);
    std::ofstream(path, std::ios::trunc) << k.dump();
    try {
      read_lod_report(path);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const citylod::io::IoError& e) {
      EXPECT_NE(std::string(e.what()).find("report.json"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("colours"), std::string::npos) << e.what();
    }
  }
}

TEST(WorkDir, DefaultsOfAbsentFieldsAreTheDocumentedOnes) {
  const fs::path d = fresh_dir("report_defaults");
  const fs::path path = d / "report.json";
  std::ofstream(path)
      << R"({"models": [{"file": "a.ply"}, {"file": "b.ply", "kind": "interpolation"}]})";
  const LodReport r = read_lod_report(path.string());
  EXPECT_EQ(r.status, Status::failed);  // no status: not trusted
  ASSERT_EQ(r.models.size(), 2u);
  EXPECT_EQ(r.models[0].kind, ModelKind::anchor);
  EXPECT_EQ(r.models[1].step, 1);  // its index
  std::ofstream(path, std::ios::trunc)
      << R"({"status": "ok", "models": [{"file": "a.ply", "kind": "coarse"}]})";
  EXPECT_THROW(read_lod_report(path.string()), io::IoError);
  std::ofstream(path, std::ios::trunc) << R"({"status": "great", "models": []})";
  EXPECT_THROW(read_lod_report(path.string()), io::IoError);
  std::ofstream(path, std::ios::trunc) << "{ not json";
  EXPECT_THROW(read_lod_report(path.string()), io::IoError);
}

TEST(WorkDir, OverridesRoundTrip) {
  const fs::path d = fresh_dir("overrides");
  EXPECT_TRUE(read_overrides(d.string()).empty());
  Overrides o;
  o["fp-1"].set = {{"planes.epsilon", "0.2"}};
  o["fp-2"].select = {0, 3};
  o["fp-3"];  // empty: not written
  write_overrides(d.string(), o);
  const Overrides back = read_overrides(d.string());
  EXPECT_EQ(back.size(), 2u);
  EXPECT_EQ(back.at("fp-1").set.at("planes.epsilon"), "0.2");
  EXPECT_EQ(back.at("fp-2").select, (std::vector<int>{0, 3}));
  std::ofstream(overrides_path(d.string()), std::ios::trunc) << R"({"something": 1})";
  EXPECT_THROW(read_overrides(d.string()), std::runtime_error);
}

// ------------------------------------------------------------ the LOD stage
TEST(LodStage, RunsEveryBuildingAndResumesWithoutRecomputing) {
  const fs::path d = fresh_dir("lod_stage");
  const std::string work = split_example(d);
  const LodStageOptions o = stage_options(work);
  const LodStagePlan before = plan_lod_stage(o);
  ASSERT_GT(before.items.size(), 5u);
  EXPECT_EQ(before.up_to_date(), 0u);
  const LodStageReport r = run_lod_stage(o);
  EXPECT_EQ(r.total, before.items.size());
  EXPECT_EQ(r.computed, r.total);
  EXPECT_EQ(r.ok + r.fallback + r.failed, r.total);
  for (const auto& it : before.items) {
    const auto rep = find_lod_report(work, it.chunk->id);
    ASSERT_TRUE(rep) << it.chunk->id;
    EXPECT_EQ(rep->key, it.key);
    EXPECT_EQ(rep->id, it.chunk->id);
    EXPECT_FALSE(rep->models.empty());
  }
  // A building killed between writing its output and renaming it into place
  // left "<id>.tmp.<pid>" (a complete report with its key) and its marker's
  // "<id>.running.tmp.<pid>": it is the only one computed again, and what the
  // killed run left is removed. Another shard's leftovers are not touched.
  const std::string gone = before.items.front().chunk->id;
  const std::string stale = lod_dir(work, gone) + ".tmp.4194301";
  fs::rename(lod_dir(work, gone), stale);
  std::ofstream(lod_dir(work, gone) + ".running.tmp.4194301") << gone << "\n";
  const std::string other = before.items.back().chunk->id;  // killed after its rename
  std::ofstream(lod_dir(work, other) + ".running") << other << "\n";
  const std::string foreign = lod_dir(work, "another-shards-building") + ".tmp.4194301";
  fs::create_directories(foreign);
  EXPECT_EQ(plan_lod_stage(o).up_to_date(), r.total - 1);
  const LodStageReport again = run_lod_stage(o);
  EXPECT_EQ(again.computed, 1u);
  EXPECT_EQ(again.reused, r.total - 1);
  EXPECT_TRUE(find_lod_report(work, gone));
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_FALSE(fs::exists(lod_dir(work, gone) + ".running.tmp.4194301"));
  EXPECT_FALSE(fs::exists(lod_dir(work, other) + ".running"));
  EXPECT_TRUE(fs::exists(foreign));
}

TEST(LodStage, OverridesApplyToTheirBuildingOnly) {
  const fs::path d = fresh_dir("lod_overrides");
  const std::string work = split_example(d);
  const LodStageOptions o = stage_options(work);
  run_lod_stage(o);
  const std::string id = first_building(work);
  Overrides ov;
  ov[id].set = {{"planes.epsilon", "0.3"}};
  write_overrides(work, ov);
  const LodStagePlan plan = plan_lod_stage(o);
  EXPECT_EQ(plan.up_to_date(), plan.items.size() - 1);  // only its key changed
  const LodStageReport r = run_lod_stage(o);
  EXPECT_EQ(r.computed, 1u);
  EXPECT_DOUBLE_EQ(std::stod(find_lod_report(work, id)->parameters.at("planes.epsilon")), 0.3);
  for (const auto& it : plan.items) {
    if (it.chunk->id != id) {
      EXPECT_DOUBLE_EQ(
          std::stod(find_lod_report(work, it.chunk->id)->parameters.at("planes.epsilon")), 0.15);
    }
  }
}

// ------------------------------------------------------------ the supervisor's crash path
TEST(Supervise, ACrashMarksTheRunningBuildingAndTheStageGoesOn) {
  const fs::path d = fresh_dir("supervise_crash");
  const std::string work = split_example(d);
  const std::string id = first_building(work);
  fs::create_directories(fs::path(work) / "lod");
  // First attempt: "building id" is running when the process crashes.
  int crashes = -1;
  const int rc = crash_once(work, {id}, d / "crashed_once", crashes);
  EXPECT_EQ(rc, 0);
  EXPECT_EQ(crashes, 1);
  EXPECT_TRUE(fs::exists(lod_dir(work, id) + ".crashed"));
  EXPECT_FALSE(fs::exists(lod_dir(work, id) + ".running"));
  // The LOD stage gives it its fallback without retrying; the others are built.
  const LodStageOptions o = stage_options(work);
  const LodStageReport r = run_lod_stage(o);
  const auto rep = find_lod_report(work, id);
  ASSERT_TRUE(rep);
  EXPECT_EQ(rep->status, Status::fallback);
  EXPECT_NE(rep->reason.find("crashed in an earlier run"), std::string::npos) << rep->reason;
  EXPECT_FALSE(fs::exists(lod_dir(work, id) + ".crashed"));
  EXPECT_GE(r.fallback, 1u);
}

TEST(Supervise, SeveralRunningBuildingsBecomeSuspectsAndRunAlone) {
  const fs::path d = fresh_dir("supervise_suspects");
  const std::string work = split_example(d);
  std::vector<std::string> ids;
  for (const auto& c : read_manifest(work).chunks)
    if (!c.skipped() && ids.size() < 2) ids.push_back(c.id);
  ASSERT_EQ(ids.size(), 2u);
  fs::create_directories(fs::path(work) / "lod");
  int crashes = 0;
  const int rc = crash_once(work, ids, d / "crashed_once", crashes);
  EXPECT_EQ(rc, 0);
  EXPECT_EQ(crashes, 1);
  for (const auto& id : ids) {
    EXPECT_TRUE(fs::exists(lod_dir(work, id) + ".suspect")) << id;
    EXPECT_FALSE(fs::exists(lod_dir(work, id) + ".crashed")) << id;
  }
  // Suspects are retried (one at a time) and, not crashing again, get real models.
  run_lod_stage(stage_options(work));
  for (const auto& id : ids) {
    EXPECT_FALSE(fs::exists(lod_dir(work, id) + ".suspect")) << id;
    EXPECT_EQ(find_lod_report(work, id)->reason.find("crashed"), std::string::npos) << id;
  }
}

TEST(Supervise, AKillFromOutsideIsNotACrash) {
  const fs::path d = fresh_dir("supervise_kill");
  int crashes = 0;
  const int rc = supervise(
      d.string(),
      [&]() {
        std::raise(SIGTERM);
        return 0;
      },
      3, &crashes);
  EXPECT_EQ(rc, 128 + SIGTERM);
  EXPECT_EQ(crashes, 0);
}

// ------------------------------------------------------------ run_city and rebuild
TEST(RunCity, WritesTheTilesetAndTheRunReportAndResumes) {
  const fs::path d = fresh_dir("run_city");
  const CityRunResult r = run_city(example_options(d));
  EXPECT_TRUE(fs::exists(d / "tileset" / "tileset.json"));
  const RunReport rep = read_run_report(d.string());
  EXPECT_EQ(rep.buildings.size(), read_manifest((d / "work").string()).chunks.size());
  EXPECT_EQ(rep.lod.computed, rep.lod.buildings);
  EXPECT_EQ(rep.threads, 2);
  EXPECT_EQ(rep.ok + rep.fallback + rep.failed + rep.skipped, rep.buildings.size());
  EXPECT_EQ(r.lod.buildings, rep.lod.buildings);
  const auto tiles = tree(d / "tileset");
  // Again: everything reused, the same tileset.
  const CityRunResult again = run_city(example_options(d));
  EXPECT_TRUE(again.split.up_to_date);
  EXPECT_EQ(again.lod.computed, 0u);
  EXPECT_EQ(again.lod.reused, rep.lod.buildings);
  EXPECT_EQ(tree(d / "tileset"), tiles);
}

TEST(Rebuild, SetRecomputesOneBuildingAndSelectPinsItsModels) {
  const fs::path d = fresh_dir("rebuild");
  run_city(example_options(d));
  const std::string work = (d / "work").string();
  const std::string id = first_building(work);
  std::map<std::string, std::string> others;
  for (const auto& c : read_manifest(work).chunks)
    if (!c.skipped() && c.id != id) others[c.id] = slurp(lod_report_path(work, c.id));

  RebuildOptions o;
  o.dir = d.string();
  o.building = id;
  o.set = "planes.epsilon=0.3";
  const RebuildResult r = rebuild(o);
  EXPECT_TRUE(r.report_changed);
  EXPECT_FALSE(r.changed.empty());
  EXPECT_EQ(read_overrides(work).at(id).set.at("planes.epsilon"), "0.3");
  EXPECT_DOUBLE_EQ(std::stod(find_lod_report(work, id)->parameters.at("planes.epsilon")), 0.3);
  for (const auto& [other, bytes] : others)
    EXPECT_EQ(slurp(lod_report_path(work, other)), bytes) << other;
  const RunReport rep = read_run_report(d.string());
  ASSERT_TRUE(rep.last_rebuild);
  EXPECT_EQ(rep.last_rebuild->building, id);

  // --select the first anchor only: assemble sees one model, the full list is kept.
  const LodReport lr = *find_lod_report(work, id);
  int anchor = -1;
  for (const auto& m : lr.models)
    if (is_anchor(m.kind) && anchor < 0) anchor = m.step;
  ASSERT_GE(anchor, 0);
  RebuildOptions s;
  s.dir = d.string();
  s.building = id;
  s.select = std::to_string(anchor);
  rebuild(s);
  const LodReport pinned = *find_lod_report(work, id);
  ASSERT_EQ(pinned.models.size(), 1u);
  EXPECT_EQ(pinned.models[0].step, anchor);
  ASSERT_TRUE(pinned.models_all);
  EXPECT_EQ(pinned.models_all->size(), lr.models.size());
  // A selection without an anchor is refused and not kept.
  int interp = -1;
  for (const auto& m : lr.models)
    if (!is_anchor(m.kind)) interp = m.step;
  if (interp >= 0) {
    s.select = std::to_string(interp);
    EXPECT_THROW(rebuild(s), std::runtime_error);
    EXPECT_EQ(read_overrides(work).at(id).select, (std::vector<int>{anchor}));
  }
  // 'all' restores the automatic choice.
  s.select = "all";
  rebuild(s);
  EXPECT_FALSE(find_lod_report(work, id)->models_all);
  EXPECT_EQ(find_lod_report(work, id)->models.size(), lr.models.size());
  EXPECT_THROW(parse_select("1,x"), std::invalid_argument);
}
