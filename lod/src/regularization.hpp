// Internal: adaptive regularization (paper Section 4.1) of the principal
// planes and of the secondary structures relative to their host, with cuboid
// templates for windows. Implemented in regularization.cpp (CGAL inside).
#pragma once

#include "grouping.hpp"

#include <vector>

namespace citylod::lod::detail {

/// Mild regularization of the principal primitives (CGAL Shape_regularization:
/// parallelism, orthogonality, coplanarity; angle/distance from p). Only the
/// primitives listed in `which` are changed; shapes are recomputed.
void regularize_principal(std::vector<Primitive>& prims, const std::vector<int>& which,
                          const Samples& s, const RegularizationParams& p, const AlphaParams& a);

/// Adaptive regularization of the secondary structures relative to their host
/// (angle/distance of p), and cuboid templates for clusters of more than three
/// cut-outs on a near-vertical host. New template primitives are appended to
/// `prims` and replace the structure's primitives in its cluster. Returns the
/// number of templates made.
int regularize_secondary(std::vector<Primitive>& prims, Grouping& grouping, const IoView& view,
                         const Bsp& bsp, const Samples& samples, const RegularizationParams& p,
                         const AlphaParams& a);

}  // namespace citylod::lod::detail
