// The shared words of kinds.hpp: one spelling each.
#include "citylod/lod/kinds.hpp"

#include <stdexcept>

namespace citylod::lod {

const char* to_string(ModelKind k) {
  switch (k) {
    case ModelKind::anchor:
      return "anchor";
    case ModelKind::interpolation:
      return "interpolation";
    case ModelKind::fallback:
      return "fallback";
  }
  return "?";
}

const char* to_string(Status s) {
  switch (s) {
    case Status::pending:
      return "pending";
    case Status::ok:
      return "ok";
    case Status::fallback:
      return "fallback";
    case Status::failed:
      return "failed";
    case Status::skipped:
      return "skipped";
  }
  return "failed";
}

Status status_from_string(const std::string& s) {
  for (Status v : {Status::pending, Status::ok, Status::fallback, Status::failed, Status::skipped})
    if (s == to_string(v)) return v;
  throw std::invalid_argument("unknown status '" + s + "'");
}

ModelKind model_kind_from_string(const std::string& s) {
  for (ModelKind k : {ModelKind::anchor, ModelKind::interpolation, ModelKind::fallback})
    if (s == to_string(k)) return k;
  throw std::invalid_argument("unknown kind '" + s + "'");
}

}  // namespace citylod::lod
