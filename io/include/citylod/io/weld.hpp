// Welding of integer (quantized) vertices and the triangles that survive it:
// the one rule the glb writer (int16 positions, io/src/gltf.cpp) and the
// CityJSON writer (integer vertices, tiler/src/export/cityjson.cpp) apply when
// rounding made a valid model invalid.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace citylod::io {

/// Two integer points within `d` steps of each other on every axis (Chebyshev distance d).
struct NearPair {
  std::uint32_t a = 0, b = 0;  ///< indices into the points, a != b
  std::uint32_t d = 0;         ///< max over the axes of |difference|
};

/// Every pair of `points` within `r` steps on every axis (d <= r; r >= 0), each once.
std::vector<NearPair> near_pairs(const std::vector<std::array<std::int64_t, 3>>& points,
                                 std::uint32_t r);

/// The points joined by the pairs with d <= r, transitively: for each point,
/// the representative of its cluster, the point of lowest `rank` in it (ranks
/// are distinct: e.g. the index itself, or the position in a sorted order).
std::vector<std::uint32_t> weld(const std::vector<NearPair>& pairs, std::uint32_t r,
                                const std::vector<std::uint32_t>& rank);

/// The triangles (vertex ids after welding) that stay a surface: without the
/// collapsed ones (two equal corners) and without pairs of opposite triangles
/// (the same corners in reverse order: a zero-volume fin, both go). In input
/// order; from[i] = the input index of output triangle i.
std::vector<std::array<std::uint32_t, 3>> drop_collapsed_and_fins(
    const std::vector<std::array<std::uint32_t, 3>>& triangles, std::vector<std::size_t>& from);

/// Collinear spikes: a ring that runs out along a line and comes back on it
/// (i -> j -> k on one line in the integer coordinates, i and k on the same side
/// of j: a zero-width hair, which a validator sees as a fold, a self-touching
/// ring or a triangle on a line). j leaves the ring, and the nearer of i and k
/// goes into the face across the longer of the two edges (between its ends), so
/// that every edge keeps its opposite. A spike onto one vertex (i == k) loses
/// its tip and return. Faces left with fewer than 3 vertices go. `faces` index
/// `points`; returns the input indices of the faces kept, in order, and
/// replaces `faces` by them.
std::vector<std::size_t> remove_collinear_spikes(
    std::vector<std::vector<std::uint32_t>>& faces,
    const std::vector<std::array<std::int64_t, 3>>& points);

}  // namespace citylod::io
