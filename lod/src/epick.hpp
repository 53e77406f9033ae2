// Internal, for the .cpp files that already use CGAL's EPICK kernel (samples,
// planes, regularization): the kernel's types and the conversions from and to
// Eigen vectors. Do not include it where CGAL is not needed.
#pragma once

#include "citylod/lod/types.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

namespace citylod::lod::detail::epick {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using P3 = K::Point_3;
using V3 = K::Vector_3;
using P2 = K::Point_2;

inline P3 toP(const Vec3& v) {
  return P3(v.x(), v.y(), v.z());
}
inline Vec3 toE(const P3& p) {
  return Vec3(p.x(), p.y(), p.z());
}
inline Vec3 toE(const V3& p) {
  return Vec3(p.x(), p.y(), p.z());
}

}  // namespace citylod::lod::detail::epick
