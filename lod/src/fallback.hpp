// Internal: the fallback model of a building whose LOD-Tree could not be built:
// its 2D convex outline extruded from the lowest point to the roof height.
#pragma once

#include "citylod/lod/lod.hpp"

namespace citylod::lod::detail {

/// Prism over the convex hull of the xy of `points` (footprint when given),
/// from min z (or ground_z) to the 95th percentile of z. Closed, outward,
/// edge-manifold. Throws LodError when the points span no area.
LodModel extruded_outline(const BuildingInput& in);

/// The polygons of the prism over a CCW ring from z0 to z1: vertices ring at
/// z0 then ring at z1; faces bottom (CW from above), top, one quad per edge.
PolygonMesh prism_polygons(const std::vector<Vec2>& ring, double z0, double z1);

}  // namespace citylod::lod::detail
