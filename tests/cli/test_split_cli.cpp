// `citylod split` end to end: the real binary on good and bad inputs.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include "support/cli_run.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "citylod/io/hash.hpp"
#include "citylod/io/writers.hpp"
#include "citylod/tiler/workdir.hpp"
#include "fixtures/synthetic_city.hpp"
#include "support/las_write.hpp"

namespace fs = std::filesystem;
using namespace citylod;

namespace {

using namespace citylod::test;

const std::string kData = CITYLOD_SHARED_DATA;

/// The error line of a failed run: exactly one "citylod: error:" line naming `file`.
void expect_one_line_error(const CliRun& r, const std::string& file, const std::string& reason) {
  EXPECT_EQ(r.code, 1) << r.out;
  std::size_t lines = 0, pos = 0;
  std::string err;
  while ((pos = r.out.find("citylod: error:", pos)) != std::string::npos) {
    ++lines;
    err = r.out.substr(pos, r.out.find('\n', pos) - pos);
    ++pos;
  }
  EXPECT_EQ(lines, 1u) << r.out;
  EXPECT_NE(err.find(file), std::string::npos) << err;
  EXPECT_NE(err.find(reason), std::string::npos) << err;
}

/// Nothing of a failed run may remain: the work dir is absent (it did not exist before).
void expect_no_work(const fs::path& work) {
  EXPECT_FALSE(fs::exists(work)) << work;
}

std::string write_city_ply(const fs::path& dir) {
  test::SynthCity city;
  const std::string p = (dir / "city.ply").string();
  io::write_ply(p, test::make_city_points(city));
  return p;
}

TEST(SplitCli, HelpListsTheOptions) {
  const CliRun r = run("split --help");
  EXPECT_EQ(r.code, 0);
  for (const char* opt :
       {"--crs", "--origin", "--geoid", "--footprints", "--memory-limit", "--cell-size", "--out"})
    EXPECT_NE(r.out.find(opt), std::string::npos) << opt;
  EXPECT_EQ(run("split").code, 2);
  EXPECT_EQ(run("split x.ply").code, 2) << "--out is required";
  EXPECT_EQ(run("split x.ply -o w --memory-limit lots").code, 2);
}

TEST(SplitCli, SplitsThenUpToDate) {
  const fs::path dir = tmp_dir("split_cli_ok");
  const std::string in = write_city_ply(dir);
  const fs::path work = dir / "work";
  const std::string args =
      "split " + q(in) + " --origin 52,4.36,45 --cell-size 50 --halo 10 -o " + q(work);
  CliRun r = run(args);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("3 chunks"), std::string::npos) << r.out;
  const tiler::Manifest m = tiler::read_manifest(work.string());
  EXPECT_EQ(m.chunks.size(), 3u);
  for (const auto& c : m.chunks) EXPECT_TRUE(fs::exists(tiler::chunk_path(work.string(), c.id)));
  r = run(args);
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("up to date"), std::string::npos) << r.out;
  // Touching the input makes it stale.
  fs::last_write_time(in, fs::last_write_time(in) + std::chrono::seconds(5));
  r = run(args);
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.out.find("up to date"), std::string::npos) << r.out;
}

TEST(SplitCli, BadInputs) {
  const fs::path dir = tmp_dir("split_cli_bad");
  const std::string good = write_city_ply(dir);
  const fs::path work = dir / "work";
  const std::string tail = " --origin 52,4.36,45 -o " + q(work);

  // Truncated PLY.
  const fs::path trunc = dir / "truncated.ply";
  fs::copy_file(good, trunc);
  fs::resize_file(trunc, fs::file_size(trunc) / 2);
  expect_one_line_error(run("split " + q(trunc) + tail), trunc.string(), "truncated");
  expect_no_work(work);

  // Empty file.
  const fs::path empty = dir / "empty.ply";
  std::ofstream(empty).close();
  expect_one_line_error(run("split " + q(empty) + tail), empty.string(), "");
  expect_no_work(work);

  // NaN / Inf coordinates.
  for (double bad :
       {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
    io::PointSet ps;
    for (int i = 0; i < 100; ++i) ps.positions.push_back({double(i), 0, 0});
    ps.positions[50][1] = bad;
    const fs::path f = dir / (std::isnan(bad) ? "nan.ply" : "inf.ply");
    io::write_ply(f.string(), ps);
    expect_one_line_error(run("split " + q(f) + tail), f.string(),
                          std::isnan(bad) ? "NaN" : "infinite");
    expect_no_work(work);
  }

  // LAS whose header count lies, truncated LAS, unknown EPSG, CRS area that misses the data.
  test::SynthCity city;
  const io::PointSet ps = test::make_city_points(city);
  auto write_las = [&](const fs::path& f, std::int64_t lie) {
    test::LasWriter w(f.string(), {0.001, 0.001, 0.001}, {85000, 447000, 0});
    for (std::size_t k = 0; k < ps.size(); ++k)
      w.add(ps.positions[k][0] + 85000, ps.positions[k][1] + 447400, ps.positions[k][2],
            ps.classes[k]);
    w.close(lie);
  };
  const fs::path lies = dir / "lies.las";
  write_las(lies, std::int64_t(ps.size()) - 1000);
  expect_one_line_error(run("split " + q(lies) + " --crs EPSG:28992 -o " + q(work)), lies.string(),
                        "point count");
  expect_no_work(work);

  const fs::path las = dir / "city.las";
  write_las(las, -1);
  const fs::path tlas = dir / "truncated.las";
  fs::copy_file(las, tlas);
  fs::resize_file(tlas, fs::file_size(tlas) - 28 * 500 - 3);
  expect_one_line_error(run("split " + q(tlas) + " --crs EPSG:28992 -o " + q(work)), tlas.string(),
                        "truncated");
  expect_no_work(work);

  expect_one_line_error(run("split " + q(las) + " --crs EPSG:99999 -o " + q(work)), las.string(),
                        "99999");
  expect_no_work(work);
  expect_one_line_error(run("split " + q(las) + " --crs EPSG:2056 -o " + q(work)), las.string(),
                        "area of use");
  expect_no_work(work);
  expect_one_line_error(run("split " + q(las) + " -o " + q(work)), las.string(), "no CRS");
  expect_no_work(work);
  expect_one_line_error(run("split " + q(dir / "missing.las") + " --crs EPSG:28992 -o " + q(work)),
                        (dir / "missing.las").string(), "no such file");
  expect_no_work(work);

  // The good LAS splits, and a later failure leaves that result untouched.
  ASSERT_EQ(run("split " + q(las) + " --crs EPSG:28992 --cell-size 60 -o " + q(work)).code, 0);
  const std::string before = [&] {
    std::ifstream f(tiler::manifest_path(work.string()));
    return std::string(std::istreambuf_iterator<char>(f), {});
  }();
  expect_one_line_error(run("split " + q(tlas) + " --crs EPSG:28992 -o " + q(work)), tlas.string(),
                        "truncated");
  std::ifstream f(tiler::manifest_path(work.string()));
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(f), {}), before);
  for (const auto& e : fs::directory_iterator(work))
    EXPECT_TRUE(e.path().filename() == "manifest.json" || e.path().filename() == "chunks")
        << e.path();
}

// Footprints that cannot be used: one error line naming the footprint source.
TEST(SplitCli, FootprintProblemsNameTheSource) {
  const std::string las = kData + "/delft/ahn3_cropped_2.las";
  const std::string gpkg = kData + "/delft/bgt_pand.gpkg";
  if (!fs::exists(las) || !fs::exists(gpkg)) GTEST_SKIP() << "shared data not found: " << kData;
  const fs::path dir = tmp_dir("split_cli_fp_errors");
  // a layer that does not exist: the message lists the layers
  CliRun r = run("split " + q(las) + " --crs EPSG:28992 --footprints " + q(gpkg) +
                 " --footprints-layer nope -o " + q(dir / "w1"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find(gpkg), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bgt"), std::string::npos) << r.out;
  // an id attribute that does not exist
  r = run("split " + q(las) + " --crs EPSG:28992 --footprints " + q(gpkg) +
          " --footprints-id nope -o " + q(dir / "w2"));
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("gml_id"), std::string::npos) << r.out;
  // the footprints in the wrong CRS: RD coordinates labelled UTM 31N meet no data
  const std::string wrong = (dir / "wrong.gpkg").string();
  if (std::system(("ogr2ogr -a_srs EPSG:32631 " + q(wrong) + " " + q(gpkg) + " > /dev/null 2>&1")
                      .c_str()) == 0) {
    r = run("split " + q(las) + " --crs EPSG:28992 --footprints " + q(wrong) + " -o " +
            q(dir / "w3"));
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(wrong), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("meets the data"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir / "w3" / "manifest.json"));
  }
  // --footprints-id gml_id and the layer by name: the same chunk ids as the default
  r = run("split " + q(las) + " --crs EPSG:28992 --footprints " + q(gpkg) +
          " --footprints-layer bgt --footprints-id gml_id -o " + q(dir / "w4"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("outside every footprint"), std::string::npos) << r.out;
  const tiler::Manifest m = tiler::read_manifest((dir / "w4").string());
  ASSERT_FALSE(m.chunks.empty());
  for (const auto& c : m.chunks)
    EXPECT_EQ(c.id, "fp-" + c.attributes.at("gml_id").get<std::string>());
}

TEST(SplitCli, DelftWithFootprintsAndGeoid) {
  const std::string las = kData + "/delft/ahn3_cropped_2.las";
  if (!fs::exists(las)) GTEST_SKIP() << "shared data not found: " << kData;
  const fs::path dir = tmp_dir("split_cli_delft");
  const std::string fp = std::string(CITYLOD_SOURCE_DIR) + "/tests/fixtures/delft_bgt_pand.geojson";
  const CliRun r = run("split " + q(las) + " --crs EPSG:28992 --geoid egm96 --footprints " + q(fp) +
                       " -o " + q(dir / "work"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("EGM96"), std::string::npos) << r.out;
  const tiler::Manifest m = tiler::read_manifest((dir / "work").string());
  EXPECT_EQ(m.scene.crs, "EPSG:28992");
  // NAP ~0-25 m + geoid ~43 m near Delft: the ellipsoidal origin height lies in 40..70 m.
  EXPECT_GT(m.scene.origin_h, 40.0);
  EXPECT_LT(m.scene.origin_h, 70.0);
  std::size_t fp_chunks = 0;
  for (const auto& c : m.chunks)
    fp_chunks += c.id.rfind("fp-", 0) == 0 && c.status == tiler::Status::pending;
  EXPECT_GE(fp_chunks, 22u);
}

}  // namespace
