// Internal: the fallback model of a building whose LOD-Tree could not be built:
// its 2D convex outline extruded from the lowest point to the roof height.
#pragma once

#include "citylod/lod/lod.hpp"

namespace citylod::lod::detail {

/// Prism over the convex hull of the xy of `points` (footprint when given),
/// from min z (or ground_z) to the 95th percentile of z. Closed, outward,
/// edge-manifold. Throws LodError when the points span no area.
LodModel extruded_outline(const BuildingInput& in);

}  // namespace citylod::lod::detail
