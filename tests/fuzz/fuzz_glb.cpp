// libFuzzer harness of the glb reader (io::parse_glb): container, glTF JSON
// (tinygltf), accessors, node tree, EXT_mesh_features / EXT_structural_metadata.
#include <cstdint>
#include <string>

#include "citylod/io/glb_reader.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string name = "fuzz-input.glb";
  try {
    citylod::io::parse_glb(std::string(reinterpret_cast<const char*>(data), size), name);
  } catch (const std::exception& e) {
    citylod::fuzz::expect_names_file(e, name);
  }
  return 0;
}
