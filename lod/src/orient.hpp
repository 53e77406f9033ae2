// Internal: consistent outward orientation of the detected planes (orient.cpp).
#pragma once

#include "planes.hpp"

namespace citylod::lod::detail {

/// Turns round the planes whose front (normal side) the other planes' alpha
/// shapes see as inside (> half the rays vote in) and whose back they see as
/// outside, by a clear margin. Returns how many.
/// Deterministic for any number of `threads`.
int orient_primitives(std::vector<Primitive>& prims, const Samples& s, const OrientParams& p,
                      int threads);

}  // namespace citylod::lod::detail
