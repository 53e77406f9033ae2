// citylod::lod — the LOD-Tree method (paper Sections 4.1-4.2, appendices B-C)
// for one building. Entry point: build_lod_tree().
#pragma once

#include "citylod/lod/kinds.hpp"
#include "citylod/lod/params.hpp"
#include "citylod/lod/types.hpp"

#include <stdexcept>
#include <string>
#include <vector>

namespace citylod::lod {

/// Error raised by the engine for input it cannot model at all.
class LodError : public std::runtime_error {
 public:
  LodError(const std::string& stage, const std::string& reason)
      : std::runtime_error(stage + ": " + reason), stage_(stage) {}
  const std::string& stage() const { return stage_; }

 private:
  std::string stage_;
};

/// Thrown when the progress callback asks to stop (ProgressFn returned false):
/// a cancelled building has no result at all, not a fallback.
class LodCancelled : public LodError {
 public:
  explicit LodCancelled(const std::string& stage) : LodError(stage, "cancelled") {}
};

/// Thrown when a building runs over budget.time_budget_s: it gets the
/// fallback model, and no other way round (another labelling, the block) is
/// tried, since the time is spent.
class LodBudgetExceeded : public LodError {
 public:
  explicit LodBudgetExceeded(const std::string& stage) : LodError(stage, "time budget exceeded") {}
};

/// One candidate LOD model of the set M.
struct LodModel {
  ModelKind kind = ModelKind::anchor;
  int level = 0;  ///< level set index k (anchor: finished level; interpolation: level in progress)
  int step = 0;   ///< number of coarser models in M before this one
  int cuts = 0;   ///< BSP-node splits needed to reach this model
  double diff_sum = 0.0;    ///< m^3, summed diff-value of the queue when extracted
  PolygonMesh polygons;     ///< merged coplanar polygons (outward CCW)
  TriangleMesh mesh;        ///< the same surface triangulated
  double volume = 0.0;      ///< m^3
  double e1 = -1.0;         ///< RMSE model->input, % of bbox diagonal (-1: not computed)
  double e2 = -1.0;         ///< RMSE input->model, % of bbox diagonal
  double hausdorff = -1.0;  ///< m, symmetric Hausdorff estimate (sampled)
  /// m, airborne LiDAR (a roof height field): RMSE of the vertical residuals
  /// of the returns well inside the outline to the model's top, as the scanner
  /// saw the roof (-1: not measured)
  double roof_rmse = -1.0;
  /// Input colours on the faces (colour.cpp: colour_model): one per face of
  /// `polygons` and one per triangle of `mesh`, or both empty (input without
  /// colours). a = 0: no colour (too few points on the face's plane region).
  std::vector<Rgba8> polygon_colours, triangle_colours;
};

/// A planar primitive as reported (for --dump-planes and reports).
struct PlaneReport {
  Vec3 normal;
  double d = 0.0;  ///< n.x + d = 0
  int level = -1;  ///< 0 = principal (S0), k = level set S_k, -1 = unused
  int cluster = -1;
  double area = 0.0;  ///< m^2 alpha-shape area
  std::vector<Vec3> inlier_points;
  bool from_template = false;  ///< cuboid template face
  bool inferred = false;       ///< closure plane (ground or outline wall)
};

struct LodStats {
  int input_points = 0, input_faces = 0;
  bool normals_estimated = false;
  bool walls_inferred = false;
  int planes_detected = 0;   ///< P (after the planes.max_planes cap)
  int planes_found = 0;      ///< planes region growing found (before the cap)
  bool bsp_cap_hit = false;  ///< a BSP stopped at bsp.max_cells (IO-View or LOD-Tree)
  int planes_turned = 0;     ///< planes turned round by the orientation check
  int planes_sorted = 0;     ///< S (after regularization/templates)
  int principal = 0;
  int add_ons = 0, cut_outs = 0;  ///< secondary structures
  int clusters = 0;
  int level_sets = 0;  ///< N_l
  int ioview_cells = 0;
  int bsp_nodes = 0;  ///< nodes of the LOD-Tree's BSP
  int lod_nodes = 0;
  int lod_tree_cuts_to_finest = 0;
  int baseline_bsp_nodes = 0;  ///< plain BSP-Tree (area order, binary)
  int baseline_cuts_to_finest = 0;
  double bbox_diagonal = 0.0;
  bool block_first = false;  ///< model 0 is the airborne LoD1.2 block
  int worse_than_block =
      0;  ///< models dropped: they fit the points and the roof worse than the block
  /// Airborne: the IO-View failure a low object's chain was built past (every
  /// plane bounding its core principal), with what the scan saw; empty when
  /// the IO-View did not fail. The reason of the fallback when no model of
  /// the chain fits better than the block.
  std::string low_object;
  double t_samples = 0.0;    ///< s, the input's oriented samples (normals estimated)
  double t_ioview = 0.0;     ///< T1 s (incl. plane detection)
  double t_tree = 0.0;       ///< T2 s
  double t_traversal = 0.0;  ///< T3 s (incl. mesh extraction)
  double t_metrics = 0.0;
  double t_colour = 0.0;           ///< s, input colours onto the faces (0: no colours)
  std::vector<std::string> notes;  ///< caps hit, fallbacks, estimations
};

struct LodResult {
  Status status = Status::ok;    ///< ok or fallback (the engine returns no other)
  std::string reason;            ///< why a fallback was used
  std::vector<LodModel> models;  ///< candidate set M, coarse to fine
  std::vector<PlaneReport> planes;
  LodStats stats;
};

/// How build_lod_tree runs, as opposed to what it computes (LodParams): the
/// result does not depend on any of it.
struct LodExecution {
  int threads = 1;                ///< OpenMP threads inside the building (< 1 means 1)
  ProgressFn progress = nullptr;  ///< told each stage; returning false cancels
  void* user = nullptr;           ///< passed to `progress`
};

/// The method for one building, top to bottom. Never throws for geometric
/// trouble inside the pipeline: a fallback model with a reason is returned.
/// Throws LodError only for input that is not a building at all (empty, NaN),
/// and LodCancelled when `exec.progress` returns false.
LodResult build_lod_tree(const BuildingInput& input, const LodParams& params,
                         const LodExecution& exec = {});

/// The fallback result alone (outline extruded to the roof height) with
/// `reason`, for a building the caller decides not to run (e.g. it crashed the
/// process before). Throws LodError when the points span no area.
LodResult fallback_result(const BuildingInput& input, const std::string& reason);

/// Mesh validity, checked by exact edge incidence on vertex indices.
struct MeshCheck {
  bool closed =
      false;  ///< every edge has exactly two incident faces (as a set with orientation pairs)
  bool edge_manifold = false;     ///< no edge with more than two faces
  bool oriented = false;          ///< each edge appears once in each direction
  bool self_intersecting = true;  ///< any two non-adjacent triangles intersect
  int boundary_edges = 0, nonmanifold_edges = 0;
  /// Vertices whose incident triangles form more than one fan through shared
  /// edges (two solids touching at a point, or a cone pinched to one vertex).
  int pinched_vertices = 0;
  /// Edge-connected components of the triangles enclosing a positive volume
  /// (outer shells: 1 for one solid).
  int shells = 0;
  /// Components enclosing a negative volume: cavities (interior shells of a
  /// solid, e.g. rooms seen through windows). Allowed in a valid solid.
  int cavities = 0;
  /// A valid solid: closed, oriented, no pinched vertex, one outer shell (with
  /// any cavities), no self-intersection (only meaningful when
  /// self-intersections were tested).
  bool valid() const {
    return closed && oriented && pinched_vertices == 0 && shells == 1 && !self_intersecting;
  }
};
MeshCheck check_mesh(const TriangleMesh& mesh, bool test_self_intersections = true);
double mesh_volume(const TriangleMesh& mesh);

/// Quality of any model against a reference (`citylod eval`): validity,
/// volume, e1/e2 RMSE in % of the reference's bbox diagonal (surfaces sampled
/// by area; a point reference is used as is) and the symmetric Hausdorff
/// estimate in metres.
struct ModelEvaluation {
  MeshCheck check;
  std::size_t triangles = 0;
  double volume = 0, e1 = 0, e2 = 0, hausdorff = 0, diagonal = 0;
};
ModelEvaluation evaluate_model(const TriangleMesh& model, const BuildingInput& reference,
                               int samples = 20000);

}  // namespace citylod::lod
