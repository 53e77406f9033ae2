#include "citylod/geo/transformer.hpp"

#include "proj_util.hpp"

#include <GeographicLib/TransverseMercator.hpp>

#include <cmath>
#include <mutex>

namespace citylod::geo {

using detail::fmt;
using detail::PjPtr;

namespace {

constexpr const char* kEgm96Grid = "egm96_15.gtx";
// (lon deg, lat deg, H) -> (lon deg, lat deg, h = H + N): forward adds the EGM96 undulation.
constexpr const char* kEgm96Pipeline =
    "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
    "+step +proj=vgridshift +grids=egm96_15.gtx +multiplier=1 "
    "+step +proj=unitconvert +xy_in=rad +xy_out=deg";

struct OpList {
  PJ_OBJ_LIST* list = nullptr;
  PJ_OPERATION_FACTORY_CONTEXT* factory = nullptr;
  PJ_CONTEXT* ctx = nullptr;
  ~OpList() {
    if (list) proj_list_destroy(list);
    if (factory) proj_operation_factory_context_destroy(factory);
  }
};

void create_operations(OpList& ops, PJ_CONTEXT* ctx, const PJ* src, const PJ* dst,
                       PROJ_GRID_AVAILABILITY_USE grids) {
  ops.ctx = ctx;
  ops.factory = proj_create_operation_factory_context(ctx, nullptr);
  proj_operation_factory_context_set_grid_availability_use(ctx, ops.factory, grids);
  proj_operation_factory_context_set_spatial_criterion(ctx, ops.factory,
                                                       PROJ_SPATIAL_CRITERION_PARTIAL_INTERSECTION);
  ops.list = proj_create_operations(ctx, src, dst, ops.factory);
}

/// Name of an operation; crs_to_crs objects with several alternatives have none of their own.
std::string op_name(PJ* op) {
  if (const char* n = proj_get_name(op)) return n;
  const PJ_PROJ_INFO info = proj_pj_info(op);
  return info.description ? info.description : "PROJ operation";
}

}  // namespace

struct Transformer::Impl {
  Crs crs;
  TransformOptions options;
  detail::Context ctx;
  PjPtr horizontal;  // horizontal CRS -> WGS 84 2D (lon, lat), unless the UTM fast path is used
  PjPtr full3d;      // compound CRS -> WGS 84 3D, when PROJ has what the vertical datum needs
  PjPtr geoid;       // EGM96 pipeline, for HeightMode::Egm96
  bool utm_fast = false;
  double lon0 = 0, false_northing = 0;  // UTM fast path
  HeightMode effective = HeightMode::Ellipsoidal;
  double vertical_factor = 1.0;
  std::vector<std::string> warnings;
  std::vector<std::string> missing_grids;  // of the vertical datum's PROJ path (FromCrs fallback)

  Impl(Crs c, TransformOptions o) : crs(std::move(c)), options(o) {
    warnings = crs.warnings();
    vertical_factor = crs.vertical_unit().to_si;
    PjPtr src = detail::create_crs(ctx, crs.definition(), crs.label());

    effective = options.height;
    if (options.height == HeightMode::FromCrs) {
      effective = HeightMode::Ellipsoidal;
      if (crs.has_vertical_datum()) {
        // One search of PROJ's database for both questions (~40-70 ms each): the
        // operations ranked with grid availability ignored are the ones ranked
        // with missing grids discarded, in the same order, plus those.
        PjPtr dst(proj_create(ctx.get(), "EPSG:4979"));
        OpList ops;
        create_operations(ops, ctx.get(), src.get(), dst.get(), PROJ_GRID_AVAILABILITY_IGNORED);
        if (try_full3d(ops)) {
          effective = HeightMode::FromCrs;
        } else {
          effective = HeightMode::Egm96;
          warnings.push_back(missing_vertical_message(ops));
        }
        ctx.clear();
      }
    }
    if (effective == HeightMode::Egm96) {
      egm96_grid_path();  // a clear error when proj-data is missing
      geoid.reset(proj_create(ctx.get(), kEgm96Pipeline));
      if (!geoid) throw GeoError(std::string("cannot set up the EGM96 geoid: ") + ctx.take_error());
    }
    if (full3d) return;

    if (options.utm_geographiclib && crs.is_wgs84_utm()) {
      utm_fast = true;
      lon0 = crs.utm()->zone * 6.0 - 183.0;
      false_northing = crs.utm()->north ? 0.0 : 10'000'000.0;
      return;
    }
    PjPtr horiz = detail::horizontal_part(ctx, src.get());
    PjPtr wgs84(proj_create(ctx.get(), "EPSG:4326"));
    PjPtr op(proj_create_crs_to_crs_from_pj(ctx.get(), horiz.get(), wgs84.get(), nullptr, nullptr));
    if (!op)
      throw GeoError("no PROJ transformation from " + crs.label() +
                     " to WGS 84: " + ctx.take_error());
    horizontal.reset(proj_normalize_for_visualization(ctx.get(), op.get()));
    if (!horizontal) throw GeoError("cannot normalise axis order: " + ctx.take_error());
  }

  /// Best PROJ operation compound CRS -> EPSG:4979 (of `ops`, ranked with grid
  /// availability ignored) that has all its grids and no ballpark step.
  bool try_full3d(const OpList& ops) {
    const int n = ops.list ? proj_list_get_count(ops.list) : 0;
    for (int i = 0; i < n; ++i) {
      PjPtr op(proj_list_get(ctx.get(), ops.list, i));
      if (!op || proj_coordoperation_has_ballpark_transformation(ctx.get(), op.get()) ||
          !proj_coordoperation_is_instantiable(ctx.get(), op.get()))
        continue;
      full3d.reset(proj_normalize_for_visualization(ctx.get(), op.get()));
      if (full3d) return true;
    }
    return false;
  }

  /// The warning when no operation of `ops` has its grids: the missing grids of the best one.
  std::string missing_vertical_message(const OpList& ops) {
    std::string grids;
    if (ops.list && proj_list_get_count(ops.list) > 0) {
      PjPtr best(proj_list_get(ctx.get(), ops.list, 0));
      const int ng = proj_coordoperation_get_grid_used_count(ctx.get(), best.get());
      for (int g = 0; g < ng; ++g) {
        const char* name = nullptr;
        int available = 1;
        proj_coordoperation_get_grid_used(ctx.get(), best.get(), g, &name, nullptr, nullptr,
                                          nullptr, nullptr, nullptr, &available);
        if (!available && name) {
          grids += std::string(grids.empty() ? "" : ", ") + name;
          missing_grids.emplace_back(name);
        }
      }
    }
    return crs.label() + " heights (" + crs.vertical_name() +
           ") to ellipsoidal need PROJ grid(s) " +
           (grids.empty() ? std::string("that are not installed") : grids + ", not installed") +
           ": using the EGM96 geoid instead (" + kEgm96Grid +
           "); heights may be off by decimetres up to ~1 m";
  }

  void check(const Eigen::Ref<Eigen::Matrix3Xd>& p, const Eigen::Matrix3Xd& in, const PJ* op,
             const char* direction) {
    for (Eigen::Index i = 0; i < p.cols(); ++i) {
      if (p.col(i).allFinite() && std::abs(p(0, i)) < 1e30 && std::abs(p(1, i)) < 1e30) continue;
      throw GeoError("cannot transform point #" + std::to_string(i) + " (" + fmt(in(0, i)) + ", " +
                     fmt(in(1, i)) + ", " + fmt(in(2, i)) + ") " + direction + ": " +
                     (op ? ctx.take_error(op) : std::string("outside the projection's domain")));
    }
  }

  void run(const PJ* op, PJ_DIRECTION dir, Eigen::Ref<Eigen::Matrix3Xd>& p, bool with_z) {
    const size_t stride = sizeof(double) * static_cast<size_t>(p.outerStride());
    const size_t n = static_cast<size_t>(p.cols());
    proj_errno_reset(op);
    proj_trans_generic(const_cast<PJ*>(op), dir, &p(0, 0), stride, n, &p(1, 0), stride, n,
                       with_z ? &p(2, 0) : nullptr, with_z ? stride : 0, with_z ? n : 0, nullptr, 0,
                       0);
  }

  void forward(Eigen::Ref<Eigen::Matrix3Xd> p) {
    if (p.cols() == 0) return;
    const Eigen::Matrix3Xd in = p;  // for error messages
    const std::string dir = "from " + crs.label() + " to WGS 84";
    if (full3d) {
      run(full3d.get(), PJ_FWD, p, true);
      return check(p, in, full3d.get(), dir.c_str());
    }
    if (utm_fast) {
      const auto& tm = GeographicLib::TransverseMercator::UTM();
      for (Eigen::Index i = 0; i < p.cols(); ++i) {
        double lat, lon;
        tm.Reverse(lon0, p(0, i) - 500'000.0, p(1, i) - false_northing, lat, lon);
        p(0, i) = lon;
        p(1, i) = lat;
      }
    } else {
      run(horizontal.get(), PJ_FWD, p, false);
    }
    p.row(2) = in.row(2) * vertical_factor;
    check(p, in, horizontal.get(), dir.c_str());
    if (geoid) {
      run(geoid.get(), PJ_FWD, p, true);
      check(p, in, geoid.get(), "to EGM96 ellipsoidal height");
    }
  }

  void inverse(Eigen::Ref<Eigen::Matrix3Xd> p) {
    if (p.cols() == 0) return;
    check_geodetic(p);
    const Eigen::Matrix3Xd in = p;
    const std::string dir = "from WGS 84 to " + crs.label();
    if (full3d) {
      run(full3d.get(), PJ_INV, p, true);
      return check(p, in, full3d.get(), dir.c_str());
    }
    if (geoid) {
      run(geoid.get(), PJ_INV, p, true);
      check(p, in, geoid.get(), "to EGM96 orthometric height");
    }
    p.row(2) /= vertical_factor;
    if (utm_fast) {
      const auto& tm = GeographicLib::TransverseMercator::UTM();
      for (Eigen::Index i = 0; i < p.cols(); ++i) {
        double x, y;
        tm.Forward(lon0, p(1, i), p(0, i), x, y);
        p(0, i) = x + 500'000.0;
        p(1, i) = y + false_northing;
      }
    } else {
      run(horizontal.get(), PJ_INV, p, false);
      check(p, in, horizontal.get(), dir.c_str());
      // PROJ's 2D operations carry a hidden ellipsoidal height through datum shifts (0 on the
      // source side going forward, 0 on the WGS 84 side going back), so INV(FWD(x)) misses x by
      // up to ~1 mm (RD New, LV95). One step x += x - INV(FWD(x)) makes this the exact inverse
      // of to_wgs84.
      Eigen::Matrix3Xd q = p;
      Eigen::Ref<Eigen::Matrix3Xd> qr(q);
      run(horizontal.get(), PJ_FWD, qr, false);
      run(horizontal.get(), PJ_INV, qr, false);
      check(qr, in, horizontal.get(), dir.c_str());
      p.topRows<2>() += p.topRows<2>() - q.topRows<2>();
    }
    check(p, in, horizontal.get(), dir.c_str());
  }

  /// Throws when an input (lon, lat, h) is not a valid geodetic position.
  static void check_geodetic(const Eigen::Ref<Eigen::Matrix3Xd>& p) {
    for (Eigen::Index i = 0; i < p.cols(); ++i)
      if (!p.col(i).allFinite() || std::abs(p(1, i)) > 90.0)
        throw GeoError("invalid geodetic point #" + std::to_string(i) + " (lon " + fmt(p(0, i)) +
                       ", lat " + fmt(p(1, i)) + ", h " + fmt(p(2, i)) +
                       "): latitude must be within [-90, 90]");
  }
};

Transformer::Transformer(const Crs& crs, TransformOptions options)
    : impl_(std::make_unique<Impl>(crs, options)) {}
Transformer::~Transformer() = default;
Transformer::Transformer(Transformer&&) noexcept = default;
Transformer& Transformer::operator=(Transformer&&) noexcept = default;

Transformer Transformer::clone() const {
  return Transformer(impl_->crs, impl_->options);
}
const Crs& Transformer::crs() const {
  return impl_->crs;
}
const TransformOptions& Transformer::options() const {
  return impl_->options;
}
bool Transformer::uses_geographiclib_utm() const {
  return impl_->utm_fast;
}
HeightMode Transformer::effective_height_mode() const {
  return impl_->effective;
}
const std::vector<std::string>& Transformer::missing_grids() const {
  return impl_->missing_grids;
}

const std::vector<std::string>& Transformer::warnings() const {
  return impl_->warnings;
}

std::string Transformer::description() const {
  std::string d;
  if (impl_->full3d)
    d = op_name(impl_->full3d.get());
  else if (impl_->utm_fast)
    d = "GeographicLib UTM zone " + std::to_string(impl_->crs.utm()->zone);
  else if (PjPtr last{proj_trans_get_last_used_operation(impl_->horizontal.get())})
    d = op_name(last.get());
  else
    d = "PROJ " + impl_->crs.label() + " -> WGS 84 (operation chosen per point by area)";
  if (impl_->geoid) d += " + EGM96 geoid (" + std::string(kEgm96Grid) + ")";
  return d;
}

LonLatH Transformer::to_wgs84(const Eigen::Vector3d& crs_point) {
  Eigen::Matrix3Xd p = crs_point;
  impl_->forward(p);
  return p.col(0);
}
void Transformer::to_wgs84_inplace(Eigen::Ref<Eigen::Matrix3Xd> points) {
  impl_->forward(points);
}

Eigen::Vector3d Transformer::from_wgs84(const LonLatH& geodetic) {
  Eigen::Matrix3Xd p = geodetic;
  impl_->inverse(p);
  return p.col(0);
}
void Transformer::from_wgs84_inplace(Eigen::Ref<Eigen::Matrix3Xd> points) {
  impl_->inverse(points);
}

void Transformer::check_in_area(const Eigen::AlignedBox3d& bbox, double margin_deg) {
  if (bbox.isEmpty()) throw GeoError("check_in_area: empty bounding box");
  const Eigen::Vector3d lo = bbox.min(), hi = bbox.max(), c = bbox.center();
  Eigen::Matrix3Xd pts(3, 9);
  pts << lo.x(), hi.x(), hi.x(), lo.x(), c.x(), c.x(), hi.x(), c.x(), lo.x(),  //
      lo.y(), lo.y(), hi.y(), hi.y(), c.y(), lo.y(), c.y(), hi.y(), c.y(),     //
      0, 0, 0, 0, 0, 0, 0, 0, 0;
  const Crs& crs = impl_->crs;
  const auto& area = crs.area_of_use();
  const std::string where =
      area ? " (" + (area->name.size() > 80 ? area->name.substr(0, 77) + "..." : area->name) +
                 ": lon " + fmt(area->west, 6) + ".." + fmt(area->east, 6) + ", lat " +
                 fmt(area->south, 6) + ".." + fmt(area->north, 6) + ")"
           : std::string();
  for (Eigen::Index i = 0; i < pts.cols(); ++i) {
    const std::string xy = "coordinates (" + fmt(pts(0, i)) + ", " + fmt(pts(1, i)) + ")";
    LonLatH g;
    try {
      g = to_wgs84(Eigen::Vector3d(pts.col(i)));
    } catch (const GeoError& e) {
      throw GeoError(xy + " lie outside the area of use of " + crs.label() + where +
                     ": they do not transform (" + e.what() + ")");
    }
    bool inside = std::abs(g.y()) <= 90.0 && std::abs(g.x()) <= 540.0;
    if (inside && area) {
      double west = area->west, east = area->east, lon = g.x();
      if (east < west) east += 360.0;  // area across the antimeridian
      while (lon < west - 180.0) lon += 360.0;
      while (lon > west + 180.0 + 360.0) lon -= 360.0;
      const double lon_margin = crs.utm() ? std::max(margin_deg, 3.0) : margin_deg;
      inside = lon >= west - lon_margin && lon <= east + lon_margin &&
               g.y() >= area->south - margin_deg && g.y() <= area->north + margin_deg;
    }
    if (!inside)
      throw GeoError(xy + " lie outside the area of use of " + crs.label() + where +
                     ": they map to lon " + fmt(g.x(), 8) + ", lat " + fmt(g.y(), 8) +
                     " (wrong CRS or units?)");
  }
}

std::string egm96_grid_path() {
  static std::mutex mutex;  // proj_grid_info / proj_info use PROJ's default context
  std::lock_guard<std::mutex> lock(mutex);
  const PJ_GRID_INFO info = proj_grid_info(kEgm96Grid);
  if (info.filename[0] != '\0') return info.filename;
  const PJ_INFO pinfo = proj_info();
  throw GeoError(std::string("EGM96 geoid grid ") + kEgm96Grid +
                 " not found in PROJ's search path (" + (pinfo.searchpath ? pinfo.searchpath : "") +
                 "): install proj-data");
}

}  // namespace citylod::geo
