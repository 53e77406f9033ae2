// libFuzzer harness of the footprint reader (io::read_footprints, GDAL/OGR) on
// GeoJSON: geometry types, rings, holes, CRS members, ids.
#include <cstdint>
#include <string>

#include "citylod/io/footprints.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string path = citylod::fuzz::write_input("input.geojson", data, size);
  try {
    citylod::io::read_footprints(path);
  } catch (const std::exception& e) {
    citylod::fuzz::expect_names_file(e, path);
  }
  return 0;
}
