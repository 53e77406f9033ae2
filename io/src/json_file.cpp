#include "citylod/io/json_file.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "citylod/io/error.hpp"
#include "citylod/io/file_check.hpp"

namespace citylod::io {

nlohmann::json read_json_file(const std::string& path) {
  const std::uint64_t size = regular_file_size(path);
  // parsed JSON takes ~10x its text in memory: a bound keeps a hostile file under ~3 GB
  if (size > (std::uint64_t(256) << 20))
    throw IoError(path, "larger than 256 MiB; not a citylod JSON record or tileset");
  std::ifstream f(path);
  if (!f) throw IoError(path, "cannot open");
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
