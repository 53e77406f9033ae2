// summarize_wkt() (wkt.hpp): the WKT of a LAS file read by PROJ.
#include "citylod/geo/wkt.hpp"

#include <cmath>
#include <cstdlib>
#include <cstring>

#include "proj_util.hpp"

namespace citylod::geo {

namespace {

using detail::PjPtr;

/// The CRS itself, or the source CRS of a BoundCRS (WKT1 with TOWGS84).
PjPtr unbound(PJ_CONTEXT* ctx, PjPtr crs) {
  if (crs && proj_get_type(crs.get()) == PJ_TYPE_BOUND_CRS) return PjPtr(proj_get_source_crs(ctx, crs.get()));
  return crs;
}

int epsg_id(const PJ* p) {
  if (!p) return 0;
  const char* auth = proj_get_id_auth_name(p, 0);
  const char* code = proj_get_id_code(p, 0);
  if (!auth || !code || std::strcmp(auth, "EPSG") != 0) return 0;
  char* end = nullptr;
  const long v = std::strtol(code, &end, 10);
  return *end == '\0' && v > 0 && v < 1000000 ? int(v) : 0;
}

bool is_geographic(const PJ* p) {
  const PJ_TYPE t = proj_get_type(p);
  return t == PJ_TYPE_GEOGRAPHIC_2D_CRS || t == PJ_TYPE_GEOGRAPHIC_3D_CRS || t == PJ_TYPE_GEOGRAPHIC_CRS;
}

}  // namespace

WktSummary summarize_wkt(const std::string& wkt) {
  WktSummary out;
  if (wkt.empty()) return out;
  try {
    detail::Context ctx;
    PjPtr crs = unbound(ctx.get(), PjPtr(proj_create(ctx.get(), wkt.c_str())));
    if (!crs) return out;
    PjPtr horiz;
    if (proj_get_type(crs.get()) == PJ_TYPE_COMPOUND_CRS) {
      horiz = unbound(ctx.get(), PjPtr(proj_crs_get_sub_crs(ctx.get(), crs.get(), 0)));
      PjPtr vert = unbound(ctx.get(), PjPtr(proj_crs_get_sub_crs(ctx.get(), crs.get(), 1)));
      out.vertical_epsg = epsg_id(vert.get());
    } else {
      horiz = std::move(crs);
    }
    if (!horiz) return out;
    if (const char* n = proj_get_name(horiz.get())) out.name = n;
    out.epsg = epsg_id(horiz.get());
    if (is_geographic(horiz.get())) return out;
    PjPtr cs(proj_crs_get_coordinate_system(ctx.get(), horiz.get()));
    double f = 0;
    const char* unit_name = nullptr;
    if (!cs || !proj_cs_get_axis_info(ctx.get(), cs.get(), 0, nullptr, nullptr, nullptr, &f, &unit_name, nullptr,
                                      nullptr))
      return out;
    out.unit_m = f;
    if (std::abs(f - 1.0) < 1e-12) out.unit = "metre";
    else if (std::abs(f - 0.3048) < 1e-12) out.unit = "foot";
    else if (std::abs(f - 1200.0 / 3937.0) < 1e-12) out.unit = "US survey foot";
    else out.unit = unit_name ? unit_name : "";
  } catch (...) {  // never throws
    return WktSummary{};
  }
  return out;
}

}  // namespace citylod::geo
