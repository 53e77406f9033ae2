// `citylod eval`: a unit cube against points sampled on it (exact answers), and usage errors.
#include <gtest/gtest.h>

#include "support/cli_run.hpp"

#include <fstream>

namespace {

using namespace citylod::test;

TEST(EvalCli, CubeAgainstItsOwnSurfaceSamples) {
  const fs::path d = tmp_dir("eval_cli_cube");
  {
    std::ofstream obj(d / "cube.obj");
    obj << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
           "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    std::ofstream xyz(d / "ref.xyz");
    for (int i = 0; i <= 20; ++i)
      for (int j = 0; j <= 20; ++j) {
        const double a = i / 20.0, b = j / 20.0;
        xyz << a << ' ' << b << " 0\n"
            << a << ' ' << b << " 1\n"
            << a << " 0 " << b << '\n'
            << a << " 1 " << b << '\n'
            << "0 " << a << ' ' << b << '\n'
            << "1 " << a << ' ' << b << '\n';
      }
  }
  const CliRun r = run("eval " + q(d / "cube.obj") + " --ref " + q(d / "ref.xyz") + " --json");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("\"closed\": true"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"triangles\": 12"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"volume\": 1.0"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\"e2_percent\": 0.0"), std::string::npos)
      << r.out;  // reference points lie on the model
}

TEST(EvalCli, UsageAndInputErrors) {
  const fs::path d = tmp_dir("eval_cli_bad");
  EXPECT_EQ(run("eval model.obj").code, 2);  // no --ref
  const CliRun r = run("eval " + q(d / "missing.obj") + " --ref " + q(d / "missing.xyz"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("missing.xyz"), std::string::npos) << r.out;
}

}  // namespace
