// Fidelity against size (issue: "fidelity and speed measured against peers"):
// for a mesh input, every candidate LOD model of citylod versus QEM
// simplification of the input (meshoptimizer's meshopt_simplify, the
// edge-collapse simplifier gltfpack uses) at the same triangle count; e1/e2
// of both against the input (lod::evaluate_model). Prints a markdown table.
//
//   fidelity_bench [MESH...]    (default: ../shared/data/noisy_mesh/easy3d_building.off)
#include "lod_io.hpp"

#include "citylod/lod/lod.hpp"

#include <meshoptimizer.h>

#include <cstdio>
#include <string>
#include <vector>

using namespace citylod;

namespace {

/// meshopt_simplify to about `target` triangles (error bound lifted: the count decides).
lod::TriangleMesh qem(const lod::BuildingInput& in, std::size_t target) {
  std::vector<float> pos;
  for (const auto& p : in.points) {
    pos.push_back(float(p.x()));
    pos.push_back(float(p.y()));
    pos.push_back(float(p.z()));
  }
  std::vector<unsigned> idx;
  for (const auto& t : in.triangles)
    for (int v : t) idx.push_back(unsigned(v));
  std::vector<unsigned> out(idx.size());
  float err = 0;
  const std::size_t n = meshopt_simplify(out.data(), idx.data(), idx.size(), pos.data(), in.points.size(),
                                         3 * sizeof(float), std::max<std::size_t>(3, 3 * target), 1e9f, 0, &err);
  lod::TriangleMesh m;
  m.vertices = in.points;
  for (std::size_t i = 0; i + 2 < n; i += 3) m.triangles.push_back({int(out[i]), int(out[i + 1]), int(out[i + 2])});
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> files;
  for (int i = 1; i < argc; ++i) files.push_back(argv[i]);
  if (files.empty()) files = {std::string(CITYLOD_SHARED_DATA) + "/noisy_mesh/easy3d_building.off"};
  for (const auto& f : files) {
    const auto b = tiler::load_building(f);
    if (!b.is_mesh) {
      std::fprintf(stderr, "%s: not a mesh, skipped\n", f.c_str());
      continue;
    }
    lod::LodParams p;
    p.budget.time_budget_s = 0;
    const lod::LodResult r = lod::build_lod_tree(b.input, p);
    std::printf("\n%s (%zu input triangles)\n\n", f.c_str(), b.input.triangles.size());
    std::printf("| model | kind | triangles | ours e1 %% | ours e2 %% | QEM triangles | QEM e1 %% | QEM e2 %% | QEM closed |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& m : r.models) {
      const lod::TriangleMesh q = qem(b.input, m.mesh.triangles.size());
      const lod::ModelEvaluation eo = lod::evaluate_model(m.mesh, b.input, 5000);
      const lod::ModelEvaluation eq = lod::evaluate_model(q, b.input, 5000);
      std::printf("| %d | %s | %zu | %.3f | %.3f | %zu | %.3f | %.3f | %s |\n", m.step, lod::to_string(m.kind),
                  m.mesh.triangles.size(), eo.e1, eo.e2, q.triangles.size(), eq.e1, eq.e2,
                  eq.check.closed ? "yes" : "no");
      std::fflush(stdout);
    }
  }
  return 0;
}
