// val3dity 2.6.0 (../shared/tools/val3dity, the validator 3DBAG publishes
// with) on a CityJSON / CityJSONSeq file at its default tolerances (snap
// 1 mm, planarity 1 cm / 20 degrees): the figures of its JSON report.
#pragma once

#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "support/cli_run.hpp"

namespace citylod::test {

struct Val3dityResult {
  bool ran = false;
  std::string why;  ///< when it did not run
  std::size_t features = 0, valid_features = 0, primitives = 0, valid_primitives = 0;
  std::map<int, std::size_t> errors;  ///< code -> occurrences
  std::string first_error;            ///< "code id" of the first one
};

/// The prebuilt validator beside the shared data; empty when absent.
inline std::filesystem::path val3dity_binary() {
  const std::filesystem::path p =
      std::filesystem::path(CITYLOD_SHARED_DATA).parent_path() / "tools" / "val3dity" / "val3dity";
  return std::filesystem::exists(p) ? p : std::filesystem::path();
}

inline Val3dityResult run_val3dity(const std::filesystem::path& file,
                                   const std::filesystem::path& report) {
  Val3dityResult r;
  const std::filesystem::path bin = val3dity_binary();
  if (bin.empty()) {
    r.why = "val3dity not found beside the shared data";
    return r;
  }
  std::filesystem::remove(report);
  const CliRun c = sh(q(bin) + " " + q(file) + " --report " + q(report) + " 2>&1");
  if (!std::filesystem::exists(report)) {
    r.why =
        "val3dity wrote no report (exit " + std::to_string(c.code) + "): " + c.out.substr(0, 300);
    return r;
  }
  std::ifstream in(report);
  const nlohmann::json j = nlohmann::json::parse(in);
  r.ran = true;
  for (const auto& o : j["features_overview"]) {
    r.features += o["total"].get<std::size_t>();
    r.valid_features += o["valid"].get<std::size_t>();
  }
  for (const auto& o : j["primitives_overview"]) {
    r.primitives += o["total"].get<std::size_t>();
    r.valid_primitives += o["valid"].get<std::size_t>();
  }
  for (const auto& f : j["features"])
    for (const auto& e : f.value("errors", nlohmann::json::array())) {
      ++r.errors[e["code"].get<int>()];
      if (r.first_error.empty())
        r.first_error = std::to_string(e["code"].get<int>()) + " " + e.value("id", "");
    }
  return r;
}

}  // namespace citylod::test
