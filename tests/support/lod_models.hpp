// Picking models out of a LodResult (tests of the LOD engine).
#pragma once

#include "citylod/lod/lod.hpp"

namespace citylod::test {

inline const lod::LodModel* first_anchor(const lod::LodResult& r) {
  for (const auto& m : r.models)
    if (m.kind == lod::ModelKind::Anchor) return &m;
  return nullptr;
}

/// The finest anchor (the last one of the candidate set).
inline const lod::LodModel* last_anchor(const lod::LodResult& r) {
  const lod::LodModel* a = nullptr;
  for (const auto& m : r.models)
    if (m.kind == lod::ModelKind::Anchor) a = &m;
  return a;
}

inline int count_models(const lod::LodResult& r, lod::ModelKind k) {
  int n = 0;
  for (const auto& m : r.models) n += m.kind == k;
  return n;
}

}  // namespace citylod::test
