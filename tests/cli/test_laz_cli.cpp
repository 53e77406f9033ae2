// `citylod info --verify` on the shared LAZ/COPC files: the published digests.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "support/cli_run.hpp"

using namespace citylod::test;

namespace {

void expect_digest(const std::string& rel, const std::string& sha) {
  const std::string p = std::string(CITYLOD_SHARED_DATA) + "/" + rel;
  if (!std::filesystem::exists(p)) GTEST_SKIP() << "shared data missing: " << p;
  CliRun r = run("info --verify '" + p + "'");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("sha256:         " + sha), std::string::npos) << r.out;
}

}  // namespace

TEST(CliLaz, InfoVerifyPrintsThePublishedDigests) {
  expect_digest("laz/simple.laz",
                "0717948a72e6bf719db8d96ded1e76b760d73fb683347ebe3dd603832e3d5015");
  expect_digest("laz/autzen_trim.laz",
                "f4eb6d80bf1fa507ffdcdaa73606d09041982659a50ee3895957e0b2b347f54b");
  expect_digest("laz/lone-star.copc.laz",
                "fb81e03fca9a6e3569feb6aa6e9eb92ddbca58ac10cb29fc8ba5e7eec4027dd3");
  expect_digest("laz/1.2-with-color.copc.laz",
                "361eda6829430490b1bba3a2665408642d16211f6c349b2f11edf451c8164422");
}

TEST(CliLaz, InfoVerifyLazAndLasTwinAgree) {
  const std::string d = CITYLOD_SHARED_DATA;
  if (!std::filesystem::exists(d + "/delft/ahn3_cropped_2.laz")) GTEST_SKIP() << "no shared data";
  CliRun a = run("info --verify -j '" + d + "/delft/ahn3_cropped_2.laz'");
  CliRun b = run("info --verify -j '" + d + "/delft/ahn3_cropped_2.las'");
  ASSERT_EQ(a.code, 0) << a.out;
  ASSERT_EQ(b.code, 0) << b.out;
  auto sha = [](const std::string& s) {
    const auto k = s.find("\"sha256\": \"");
    return k == std::string::npos ? std::string() : s.substr(k + 11, 64);
  };
  EXPECT_EQ(sha(a.out).size(), 64u) << a.out;
  EXPECT_EQ(sha(a.out), sha(b.out));
}
