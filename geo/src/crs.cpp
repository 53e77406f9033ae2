#include "citylod/geo/crs.hpp"

#include "proj_util.hpp"

#include <proj_experimental.h>

#include <algorithm>
#include <cctype>
#include <cmath>

namespace citylod::geo {

using detail::Context;
using detail::PjPtr;

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r\n");
  const auto e = s.find_last_not_of(" \t\r\n");
  return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

std::string upper(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::optional<int> epsg_id(const PJ* p) {
  const char* auth = proj_get_id_auth_name(p, 0);
  const char* code = proj_get_id_code(p, 0);
  if (auth && code && upper(auth) == "EPSG") {
    try {
      return std::stoi(code);
    } catch (...) {
    }
  }
  return std::nullopt;
}

/// The best EPSG equivalent of `p` with at least `min_confidence` (PROJ scale 0..100).
PjPtr identify(Context& ctx, const PJ* p, int min_confidence) {
  int* confidence = nullptr;
  PJ_OBJ_LIST* list = proj_identify(ctx.get(), p, "EPSG", nullptr, &confidence);
  PjPtr best;
  if (list) {
    if (proj_list_get_count(list) > 0 && confidence && confidence[0] >= min_confidence)
      best.reset(proj_list_get(ctx.get(), list, 0));
    proj_int_list_destroy(confidence);
    proj_list_destroy(list);
  }
  ctx.clear();
  return best;
}

std::optional<AreaOfUse> area_of(Context& ctx, const PJ* p) {
  double w, s, e, n;
  const char* name = nullptr;
  if (!p || !proj_get_area_of_use(ctx.get(), p, &w, &s, &e, &n, &name) || w < -1000) {
    ctx.clear();
    return std::nullopt;
  }
  return AreaOfUse{w, s, e, n, name ? name : ""};
}

Unit axis_unit(Context& ctx, const PJ* crs, int axis) {
  PjPtr cs(proj_crs_get_coordinate_system(ctx.get(), crs));
  const char* unit_name = nullptr;
  double factor = 1.0;
  if (!cs || axis >= proj_cs_get_axis_count(ctx.get(), cs.get()) ||
      !proj_cs_get_axis_info(ctx.get(), cs.get(), axis, nullptr, nullptr, nullptr, &factor,
                             &unit_name, nullptr, nullptr))
    throw GeoError("cannot read the axis units of CRS '" + std::string(proj_get_name(crs)) +
                   "': " + ctx.take_error());
  const PJ_COORDINATE_SYSTEM_TYPE type = proj_cs_get_type(ctx.get(), cs.get());
  const bool angular = type == PJ_CS_TYPE_ELLIPSOIDAL && axis < 2;
  return Unit{unit_name ? unit_name : "", factor, angular};
}

double param_si(Context& ctx, const PJ* op, const char* name) {
  const int i = proj_coordoperation_get_param_index(ctx.get(), op, name);
  double value = NAN, factor = 1.0;
  if (i < 0 || !proj_coordoperation_get_param(ctx.get(), op, i, nullptr, nullptr, nullptr, &value,
                                              nullptr, &factor, nullptr, nullptr, nullptr, nullptr))
    return NAN;
  return value * factor;
}

/// UTM when the projection is Transverse Mercator with UTM parameters, in metres.
std::optional<UtmZone> utm_of(Context& ctx, const PJ* projected) {
  PjPtr op(proj_crs_get_coordoperation(ctx.get(), projected));
  if (!op) return ctx.clear(), std::nullopt;
  const char* code = nullptr;
  proj_coordoperation_get_method_info(ctx.get(), op.get(), nullptr, nullptr, &code);
  if (!code || std::string(code) != "9807") return std::nullopt;  // Transverse Mercator
  const double deg = M_PI / 180.0;
  const double lat0 = param_si(ctx, op.get(), "Latitude of natural origin") / deg;
  const double lon0 = param_si(ctx, op.get(), "Longitude of natural origin") / deg;
  const double k0 = param_si(ctx, op.get(), "Scale factor at natural origin");
  const double fe = param_si(ctx, op.get(), "False easting");
  const double fn = param_si(ctx, op.get(), "False northing");
  const double zone = (lon0 + 183.0) / 6.0;
  const int izone = static_cast<int>(std::lround(zone));
  if (std::abs(lat0) > 1e-9 || std::abs(k0 - 0.9996) > 1e-12 || std::abs(fe - 500000) > 1e-6 ||
      std::abs(zone - izone) > 1e-9 || izone < 1 || izone > 60)
    return std::nullopt;
  if (std::abs(fn) < 1e-6) return UtmZone{izone, true};
  if (std::abs(fn - 10000000) < 1e-6) return UtmZone{izone, false};
  return std::nullopt;
}

bool on_wgs84_datum(Context& ctx, const PJ* crs) {
  PjPtr geod(proj_crs_get_geodetic_crs(ctx.get(), crs));
  if (!geod) return ctx.clear(), false;
  PjPtr datum(proj_crs_get_datum_forced(ctx.get(), geod.get()));
  if (!datum) return ctx.clear(), false;
  const std::string name = proj_get_name(datum.get());
  return name.rfind("World Geodetic System 1984", 0) == 0;
}

/// "EPSG:<digits>[+<digits>]", spaces around, any case. A hand parser: a
/// std::regex match recurses once per character and a long code overflowed the stack.
bool is_epsg_code(const std::string& s) {
  const std::size_t n = s.size();
  std::size_t i = 0;
  auto space = [&](std::size_t k) { return std::isspace(static_cast<unsigned char>(s[k])) != 0; };
  auto digits = [&]() {
    const std::size_t b = i;
    while (i < n && std::isdigit(static_cast<unsigned char>(s[i]))) ++i;
    return i > b;
  };
  while (i < n && space(i)) ++i;
  if (n - i < 5) return false;
  for (const char c : std::string("EPSG:"))
    if (std::toupper(static_cast<unsigned char>(s[i++])) != c) return false;
  if (!digits()) return false;
  if (i < n && s[i] == '+') {
    ++i;
    if (!digits()) return false;
  }
  while (i < n && space(i)) ++i;
  return i == n;
}

/// At most 80 characters of a user's text in a message.
std::string clip(const std::string& s) {
  return s.size() <= 80 ? s : s.substr(0, 77) + "...";
}

std::string type_name(PJ_TYPE t) {
  switch (t) {
    case PJ_TYPE_GEOCENTRIC_CRS:
      return "geocentric";
    case PJ_TYPE_VERTICAL_CRS:
      return "vertical";
    case PJ_TYPE_ENGINEERING_CRS:
      return "engineering";
    case PJ_TYPE_TEMPORAL_CRS:
      return "temporal";
    default:
      return "unsupported";
  }
}

}  // namespace

/// Fills a Crs from PROJ (the only place that knows Crs's private members).
class CrsBuilder {
 public:
  static Crs build(const std::string& spec, const std::string& definition) {
    Context ctx;
    PjPtr crs;
    try {
      crs = detail::create_crs(ctx, definition, spec);
    } catch (const GeoError&) {
      if (is_epsg_code(spec))
        throw GeoError("unknown CRS '" + clip(trim(spec)) + "': PROJ has no such code");
      throw;
    }
    return describe(ctx, crs.get(), spec, definition);
  }

  static Crs describe(Context& ctx, const PJ* crs, const std::string& spec,
                      const std::string& definition) {
    Crs c;
    c.spec_ = trim(spec);
    c.definition_ = definition;
    c.name_ = proj_get_name(crs);
    c.epsg_ = epsg_id(crs);
    const PJ_TYPE type = proj_get_type(crs);
    PjPtr horiz = detail::horizontal_part(ctx, crs);
    const PJ_TYPE htype = proj_get_type(horiz.get());
    c.projected_ = htype == PJ_TYPE_PROJECTED_CRS;
    c.geographic_ = htype == PJ_TYPE_GEOGRAPHIC_2D_CRS || htype == PJ_TYPE_GEOGRAPHIC_3D_CRS;
    if (!c.projected_ && !c.geographic_)
      throw GeoError("CRS '" + c.spec_.substr(0, 60) + "' (" + c.name_ + ") is a " +
                     type_name(htype) + " CRS; citylod needs a projected or geographic CRS");
    if (!c.epsg_) {
      if (PjPtr same = identify(ctx, crs, 100)) c.epsg_ = epsg_id(same.get());
    }

    c.horizontal_unit_ = axis_unit(ctx, horiz.get(), 0);
    if (type == PJ_TYPE_COMPOUND_CRS) {
      PjPtr vert(proj_crs_get_sub_crs(ctx.get(), crs, 1));
      if (!vert) throw GeoError("compound CRS '" + c.name_ + "' has no vertical part");
      c.has_vertical_ = true;
      c.vertical_name_ = proj_get_name(vert.get());
      c.vertical_unit_ = axis_unit(ctx, vert.get(), 0);
    } else if (proj_cs_get_axis_count(
                   ctx.get(),
                   PjPtr(proj_crs_get_coordinate_system(ctx.get(), horiz.get())).get()) == 3) {
      c.vertical_unit_ = axis_unit(ctx, horiz.get(), 2);  // ellipsoidal height axis
    } else {
      c.vertical_unit_ = c.projected_ ? c.horizontal_unit_ : Unit{"metre", 1.0, false};
    }

    // Area of use: the CRS itself, its horizontal part, an EPSG equivalent, the base datum.
    c.area_ = area_of(ctx, crs);
    if (!c.area_) c.area_ = area_of(ctx, horiz.get());
    if (!c.area_) {
      if (PjPtr same = identify(ctx, horiz.get(), 70)) c.area_ = area_of(ctx, same.get());
    }
    if (!c.area_ && c.projected_) {
      PjPtr geod(proj_crs_get_geodetic_crs(ctx.get(), horiz.get()));
      c.area_ = area_of(ctx, geod.get());
      if (!c.area_ && geod) {
        if (PjPtr same = identify(ctx, geod.get(), 70)) c.area_ = area_of(ctx, same.get());
      }
    }

    if (c.projected_ && c.horizontal_unit_.to_si == 1.0) c.utm_ = utm_of(ctx, horiz.get());
    c.wgs84_datum_ = on_wgs84_datum(ctx, horiz.get());
    return c;
  }

  static Crs alter_unit(const Crs& in, const Unit& unit) {
    if (!in.is_projected()) throw GeoError("cannot change the linear unit of a geographic CRS");
    Context ctx;
    PjPtr crs = detail::create_crs(ctx, in.definition(), in.spec_);
    PjPtr horiz = detail::horizontal_part(ctx, crs.get());
    PjPtr altered(proj_crs_alter_cs_linear_unit(ctx.get(), horiz.get(), unit.name.c_str(),
                                                unit.to_si, nullptr, nullptr));
    if (!altered)
      throw GeoError("cannot change the unit of '" + in.name() + "': " + ctx.take_error());
    if (proj_get_type(crs.get()) == PJ_TYPE_COMPOUND_CRS) {
      PjPtr vert(proj_crs_get_sub_crs(ctx.get(), crs.get(), 1));
      altered.reset(proj_create_compound_crs(ctx.get(), proj_get_name(altered.get()), altered.get(),
                                             vert.get()));
      if (!altered) throw GeoError("cannot rebuild compound CRS: " + ctx.take_error());
    }
    const char* json = proj_as_projjson(ctx.get(), altered.get(), nullptr);
    if (!json) throw GeoError("cannot export CRS '" + in.name() + "': " + ctx.take_error());
    Crs out = describe(ctx, altered.get(), in.spec_, json);
    out.epsg_ = std::nullopt;  // no longer the EPSG definition
    if (!out.area_) out.area_ = in.area_;
    const bool vertical_followed =
        !in.has_vertical_ && in.vertical_unit_.to_si == in.horizontal_unit_.to_si;
    out.vertical_unit_ = vertical_followed ? out.horizontal_unit_ : in.vertical_unit_;
    out.warnings_ = in.warnings_;
    return out;
  }

  static void set_vertical_unit(Crs& c, const Unit& u) { c.vertical_unit_ = u; }
  static void warn(Crs& c, std::string w) { c.warnings_.push_back(std::move(w)); }
};

Crs Crs::parse(const std::string& spec_in) {
  const std::string spec = trim(spec_in);
  if (spec.empty()) throw GeoError("empty CRS definition");
  std::string def = spec;
  if (std::all_of(spec.begin(), spec.end(),
                  [](char ch) { return std::isdigit(static_cast<unsigned char>(ch)); })) {
    def = "EPSG:" + spec;
  } else if ((spec[0] == '+' || spec.rfind("proj=", 0) == 0) &&
             spec.find("type=crs") == std::string::npos) {
    def = spec + " +type=crs";
  }
  return CrsBuilder::build(def == spec ? spec : def, def);
}

Crs Crs::from_geotiff(const GeoTiffKeys& k) {
  auto valid = [](int code) { return code > 0 && code < 32767; };
  std::string spec;
  if (k.projected_cs == 32767 || (k.model_type == 1 && !valid(k.projected_cs)))
    throw GeoError("user-defined GeoTIFF projection (ProjectedCSTypeGeoKey " +
                   std::to_string(k.projected_cs) +
                   ") is not supported: use the file's WKT record or give the CRS as EPSG code");
  if (valid(k.projected_cs)) {
    spec = "EPSG:" + std::to_string(k.projected_cs);
  } else if (valid(k.geographic_cs)) {
    spec = "EPSG:" + std::to_string(k.geographic_cs);
  } else {
    throw GeoError(
        "GeoTIFF keys name no EPSG coordinate system (ProjectedCSTypeGeoKey / "
        "GeographicTypeGeoKey missing or user-defined)");
  }
  if (valid(k.vertical_cs)) spec += "+" + std::to_string(k.vertical_cs);
  Crs crs = parse(spec);

  if (k.linear_units && crs.is_projected()) {
    const Unit u = unit_from_epsg(k.linear_units);
    if (std::abs(u.to_si - crs.horizontal_unit().to_si) > 1e-12) {
      const std::string declared = crs.horizontal_unit().name;
      crs = CrsBuilder::alter_unit(crs, u);
      CrsBuilder::warn(crs, spec + " is defined in " + declared +
                                " but ProjLinearUnitsGeoKey says " + u.name + ": reading x, y in " +
                                u.name);
    }
  }
  if (k.vertical_units) {
    const Unit u = unit_from_epsg(k.vertical_units);
    if (!crs.has_vertical_datum()) {
      CrsBuilder::set_vertical_unit(crs, u);
    } else if (std::abs(u.to_si - crs.vertical_unit().to_si) > 1e-12) {
      CrsBuilder::warn(crs, "VerticalUnitsGeoKey (" + u.name +
                                ") disagrees with the vertical CRS " + crs.vertical_name() + " (" +
                                crs.vertical_unit().name + "); the vertical CRS wins");
    }
  }
  return crs;
}

std::string Crs::label() const {
  return epsg_ ? "EPSG:" + std::to_string(*epsg_) : name_;
}

Crs Crs::with_vertical_unit(const Unit& unit) const {
  if (has_vertical_)
    throw GeoError("the vertical unit of '" + name_ + "' is fixed by its vertical CRS " +
                   vertical_name_);
  if (unit.angular || unit.to_si <= 0) throw GeoError("vertical unit must be a length");
  Crs c = *this;
  c.vertical_unit_ = unit;
  return c;
}

void Crs::require_projected(const std::string& what) const {
  if (projected_) return;
  throw GeoError("CRS '" + label() + "' (" + name_ + ") is geographic; a projected CRS is needed " +
                 what);
}

Unit unit_from_epsg(int code) {
  switch (code) {
    case 9001:
      return {"metre", 1.0, false};
    case 9002:
      return {"foot", 0.3048, false};
    case 9003:
      return {"US survey foot", 1200.0 / 3937.0, false};
    default:
      break;
  }
  Context ctx;
  const char* name = nullptr;
  const char* category = nullptr;
  double factor = 0;
  const std::string s = std::to_string(code);
  if (!proj_uom_get_info_from_database(ctx.get(), "EPSG", s.c_str(), &name, &factor, &category) ||
      !category || std::string(category) != "linear")
    throw GeoError("unknown linear unit code " + s +
                   " (EPSG units 9001 metre, 9002 foot, 9003 "
                   "US survey foot, ...)");
  return {name, factor, false};
}

namespace detail {
Crs with_horizontal_unit(const Crs& crs, const Unit& unit) {
  return CrsBuilder::alter_unit(crs, unit);
}
}  // namespace detail

}  // namespace citylod::geo
