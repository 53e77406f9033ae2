// `citylod eval MODEL --ref INPUT`: validity and fidelity of a model (any
// triangle mesh: ours, QEM, City3D, ...) against the input it represents.
#include "cli_common.hpp"
#include "lod_io.hpp"

#include "citylod/io/reader.hpp"
#include "citylod/lod/lod.hpp"

#include <nlohmann/json.hpp>

#include <cstdio>

namespace citylod::tiler {

namespace {

lod::Vec3 shifted(const io::Vec3d& v, const io::Vec3d& o) { return lod::Vec3(v[0] - o[0], v[1] - o[1], v[2] - o[2]); }

}  // namespace

int cmd_eval(ArgParser& args) {
  args.usage("MODEL...")
      .describe(
          "Evaluate triangle-mesh models against a reference (the input they were made from):\n"
          "closed, edge-manifold, oriented, self-intersections, volume, e1 (model -> reference)\n"
          "and e2 (reference -> model) RMSE in % of the reference's bbox diagonal, Hausdorff (m).");
  args.option("ref", 'r', "INPUT", "reference point cloud or mesh (PLY/OBJ/OFF/XYZ/LAS)");
  args.option("samples", 0, "N", "samples per surface for e1/e2", "20000");
  args.flag("json", 'j', "print JSON");
  args.positional("MODEL", "model mesh file(s) (PLY/OBJ/OFF)", Arity::one_or_more);
  if (!args.parse()) return 0;
  if (!args.has("ref")) throw UsageError("missing --ref INPUT");
  const std::string ref_path = args.get("ref");
  const int samples = int(args.get_int("samples"));
  if (samples < 1) throw UsageError("--samples must be >= 1");

  // The reference, moved next to the origin (its bbox centre); models follow.
  const LoadedBuilding reference = load_building(ref_path);
  const lod::BuildingInput& ref = reference.input;
  const io::Vec3d& origin = reference.origin;
  nlohmann::json out = nlohmann::json::array();
  for (const auto& path : args.positionals()) {
    const io::TriangleMesh m = io::read_mesh(path);
    lod::TriangleMesh model;
    for (const auto& v : m.vertices) model.vertices.push_back(shifted(v, origin));
    for (const auto& t : m.triangles) model.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
    const lod::ModelEvaluation e = lod::evaluate_model(model, ref, samples);
    out.push_back({{"model", path},
                   {"reference", ref_path},
                   {"triangles", e.triangles},
                   {"closed", e.check.closed},
                   {"edge_manifold", e.check.edge_manifold},
                   {"oriented", e.check.oriented},
                   {"self_intersecting", e.check.self_intersecting},
                   {"boundary_edges", e.check.boundary_edges},
                   {"nonmanifold_edges", e.check.nonmanifold_edges},
                   {"volume", e.volume},
                   {"e1_percent", e.e1},
                   {"e2_percent", e.e2},
                   {"hausdorff_m", e.hausdorff},
                   {"reference_diagonal_m", e.diagonal}});
    if (!args.has("json"))
      std::printf("%s: %zu triangles, %s, %s, %s, volume %.3f m3, e1 %.3f %%, e2 %.3f %%, Hausdorff %.3f m\n",
                  path.c_str(), e.triangles, e.check.closed ? "closed" : "open",
                  e.check.edge_manifold ? "edge-manifold" : "non-manifold",
                  e.check.self_intersecting ? "self-intersecting" : "no self-intersections", e.volume, e.e1, e.e2,
                  e.hausdorff);
  }
  if (args.has("json")) std::printf("%s\n", out.dump(2).c_str());
  return 0;
}

}  // namespace citylod::tiler
