#include "proj_util.hpp"

#include <cstdio>
#include <locale>
#include <sstream>

namespace citylod::geo::detail {

Context::Context() : ctx_(proj_context_create()) {
  if (!ctx_) throw GeoError("cannot create a PROJ context");
  proj_log_func(ctx_, this, &Context::log);
  proj_log_level(ctx_, PJ_LOG_ERROR);
}

Context::~Context() {
  proj_context_destroy(ctx_);
}

void Context::log(void* self, int level, const char* msg) {
  if (level > PJ_LOG_ERROR || !msg) return;
  auto* c = static_cast<Context*>(self);
  c->last_error_ = msg;
}

std::string Context::take_error(const PJ* p) {
  std::string e;
  e.swap(last_error_);
  if (e.empty()) {
    int err = p ? proj_errno(p) : proj_context_errno(ctx_);
    if (err) e = proj_context_errno_string(ctx_, err);
  }
  return e.empty() ? "unknown PROJ error" : e;
}

PjPtr create_crs(Context& ctx, const std::string& definition, const std::string& spec) {
  ctx.clear();
  PjPtr crs(proj_create(ctx.get(), definition.c_str()));
  // at most 80 characters of the user's text in the message
  const std::string shown = spec.size() <= 80 ? spec : spec.substr(0, 77) + "...";
  if (!crs) throw GeoError("cannot parse CRS '" + shown + "': " + ctx.take_error());
  if (!proj_is_crs(crs.get())) throw GeoError("'" + shown + "' is not a CRS definition");
  return crs;
}

PjPtr horizontal_part(Context& ctx, const PJ* crs) {
  if (proj_get_type(crs) == PJ_TYPE_COMPOUND_CRS) {
    PjPtr h(proj_crs_get_sub_crs(ctx.get(), crs, 0));
    if (!h) throw GeoError("compound CRS without a horizontal part: " + ctx.take_error());
    return h;
  }
  return PjPtr(proj_clone(ctx.get(), crs));
}

std::string fmt(double v, int digits) {
  std::ostringstream os;
  os.imbue(std::locale::classic());
  os.precision(digits);
  os << v;
  return os.str();
}

}  // namespace citylod::geo::detail
