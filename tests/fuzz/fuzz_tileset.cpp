// libFuzzer harness of the tileset.json reader (tiler::walk_tileset, the walker
// of `citylod eval TILESET`). The input is up to four files separated by NUL
// bytes (JSON has none): tileset.json, a.json, b.json and sub/c.json, so
// external tilesets, cycles and relative paths are reached. Besides the error
// policy (every error names a file), a result must keep the reader's bounds.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "citylod/io/error.hpp"
#include "eval/tileset_walk.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace citylod;
  const std::string dir = fuzz::scratch_dir() + "/ts";
  std::filesystem::create_directories(dir + "/sub");
  const char* names[] = {"ts/tileset.json", "ts/a.json", "ts/b.json", "ts/sub/c.json"};
  std::size_t begin = 0;
  for (int i = 0; i < 4; ++i) {  // the i-th NUL-separated piece (empty when absent)
    std::size_t end = begin;
    while (end < size && data[end] != 0) ++end;
    fuzz::write_input(names[i], data + begin, end - begin);
    begin = end < size ? end + 1 : size;
  }
  try {
    const tiler::TilesetWalk w = tiler::walk_tileset(dir + "/tileset.json");
    if (w.depth > 256 + 9 || w.tiles > 5'000'000 || w.contents.size() > 5'000'000) {
      std::fprintf(stderr, "FINDING: bounds not kept: depth %d, %zu tiles\n", w.depth, w.tiles);
      std::abort();
    }
    for (const auto& c : w.contents)
      if (c.file.empty() || c.rel.empty()) {
        std::fprintf(stderr, "FINDING: a content without a path\n");
        std::abort();
      }
  } catch (const io::IoError& e) {
    // the file named may be a content or external tileset the input points to
    if (e.file().empty()) fuzz::expect_names_file(e, dir);
  } catch (const std::exception& e) {
    fuzz::expect_names_file(e, dir);
  }
  return 0;
}
