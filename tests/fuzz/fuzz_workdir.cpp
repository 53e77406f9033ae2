// libFuzzer harness of the work directory's records (tiler/src/workdir.cpp):
// the first byte chooses the record (manifest.json, lod/<id>/report.json,
// overrides.json, run_report.json), the rest is its content. Besides the
// error policy, every id a record yields must be a safe file name.
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "citylod/tiler/workdir.hpp"
#include "fuzz_support.hpp"

namespace {

void check_id(const std::string& id) {
  if (!citylod::tiler::is_safe_id(id)) {
    std::fprintf(stderr, "FINDING: a record yields the unsafe id '%s'\n", id.c_str());
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace citylod;
  if (size == 0) return 0;
  const std::string work = fuzz::scratch_dir() + "/work";
  std::filesystem::create_directories(work + "/lod/fp-1");
  const int which = data[0] % 4;
  const char* names[] = {"manifest.json", "lod/fp-1/report.json", "overrides.json",
                         "run_report.json"};
  const std::string path =
      fuzz::write_input(std::string("work/") + names[which], data + 1, size - 1);
  try {
    if (which == 0) {
      for (const auto& c : tiler::read_manifest(work).chunks) check_id(c.id);
    } else if (which == 1) {
      const tiler::LodReport r = tiler::read_lod_report(path);
      if (!r.id.empty()) check_id(r.id);
      for (const auto& m : r.all_models())
        if (m.file.empty() || m.file.find('/') != std::string::npos || m.file[0] == '.') {
          std::fprintf(stderr, "FINDING: model file '%s' leaves its folder\n", m.file.c_str());
          std::abort();
        }
    } else if (which == 2) {
      for (const auto& [id, o] : tiler::read_overrides(work)) check_id(id);
    } else {
      for (const auto& b : tiler::read_run_report(work).buildings) check_id(b.id);
    }
  } catch (const std::exception& e) {
    fuzz::expect_names_file(e, path);
  }
  std::filesystem::remove(path);
  return 0;
}
