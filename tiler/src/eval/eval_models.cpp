// `citylod eval MODEL... --ref INPUT` (eval.hpp): any triangle meshes against one input.
#include "citylod/io/error.hpp"
#include "citylod/io/reader.hpp"
#include "citylod/tiler/bridge.hpp"
#include "citylod/tiler/eval.hpp"

namespace citylod::tiler {

std::vector<ModelFileEval> evaluate_models(const std::vector<std::string>& models,
                                           const std::string& ref_path, int samples) {
  // The reference, moved next to the origin (its bbox centre); models follow.
  const LoadedBuilding reference = load_building(ref_path);
  std::vector<ModelFileEval> out;
  for (const auto& path : models) {
    const lod::TriangleMesh model = to_lod_mesh(io::read_mesh(path), reference.origin);
    if (model.triangles.empty()) throw io::IoError(path, "the model has no triangles");
    out.push_back({path, ref_path, lod::evaluate_model(model, reference.input, samples)});
  }
  return out;
}

}  // namespace citylod::tiler
