// evaluate_model(): the metrics of the paper's quantitative evaluation for any
// model against a reference surface (used by `citylod eval`).
#include "citylod/lod/lod.hpp"
#include "primitives.hpp"

#include <algorithm>

namespace citylod::lod {

ModelEvaluation evaluate_model(const TriangleMesh& model, const BuildingInput& reference,
                               int samples) {
  if (reference.points.empty()) throw LodError("eval", "empty reference");
  ModelEvaluation ev;
  ev.check = check_mesh(model);
  ev.triangles = model.triangles.size();
  ev.volume = mesh_volume(model);
  detail::Samples s;
  if (reference.is_mesh()) {
    s = detail::make_samples(reference, NormalParams{});  // area-weighted samples of the faces
  } else {
    s.points = reference.points;  // distances need no normals
    s.weights.assign(s.points.size(), 1.0);
  }
  Vec3 lo = reference.points.front(), hi = lo;
  for (const auto& p : reference.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  ev.diagonal = (hi - lo).norm();
  const detail::Fidelity f =
      detail::FidelityMeter(reference, s, std::max(1e-9, ev.diagonal), std::max(1, samples))
          .measure(model);
  ev.e1 = f.e1;
  ev.e2 = f.e2;
  ev.hausdorff = f.hausdorff;
  return ev;
}

}  // namespace citylod::lod
