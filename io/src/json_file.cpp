#include "citylod/io/json_file.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "citylod/io/error.hpp"

namespace citylod::io {

nlohmann::json read_json_file(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw IoError(path, std::filesystem::exists(path) ? "cannot open" : "no such file");
  try {
    nlohmann::json j;
    f >> j;
    return j;
  } catch (const std::exception& e) {
    std::string what = e.what();
    std::replace(what.begin(), what.end(), '\n', ' ');
    throw IoError(path, "not valid JSON (" + what + ")");
  }
}

}  // namespace citylod::io
