// Internal: e1/e2 RMSE and Hausdorff estimate of a model against the input
// surface (paper App. D). Implemented in fidelity.cpp (CGAL inside).
#pragma once

#include "samples.hpp"

#include <memory>
#include <vector>

namespace citylod::lod::detail {

/// e1 (model -> input) and e2 (input -> model) RMSE in % of `diag`, and the
/// symmetric Hausdorff estimate in metres. The input surface is the mesh when
/// `in` is a mesh, else the points.
struct Fidelity {
  double e1 = 0, e2 = 0, hausdorff = 0;
};
Fidelity measure_fidelity(const TriangleMesh& model, const BuildingInput& in, const Samples& s,
                          double diag, int model_samples);

/// The same, for many models of one building: the input's search structures
/// are built once. e2 uses at most `samples` input samples (an even stride
/// over them, weights kept). measure() is const and thread-safe.
class FidelityMeter {
 public:
  FidelityMeter(const BuildingInput& in, const Samples& s, double diag, int samples);
  ~FidelityMeter();
  Fidelity measure(const TriangleMesh& model) const;
  /// measure() of every model, on `threads` threads: the same values. e2 takes
  /// the models in order and searches, per input sample, only the triangles new
  /// in a model while the one nearest to it in the last model is still there.
  std::vector<Fidelity> measure_all(const std::vector<const TriangleMesh*>& models,
                                    int threads) const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace citylod::lod::detail
