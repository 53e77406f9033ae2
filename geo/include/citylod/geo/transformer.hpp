// citylod::geo::Transformer — CRS coordinates <-> WGS84 geodetic (lon, lat, ellipsoidal height).
#pragma once

#include "citylod/geo/crs.hpp"
#include "citylod/geo/types.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <string>
#include <vector>

namespace citylod::geo {

/// How the z of the input becomes a WGS84 ellipsoidal height.
enum class HeightMode {
  /// Use the CRS's vertical datum through PROJ when it has one (compound CRS, e.g.
  /// "EPSG:32631+5773"). If PROJ lacks the grids it needs (RD + NAP needs
  /// nl_nsgi_nlgeo2018.tif, not in Debian's proj-data) fall back to EGM96 with a warning.
  /// Without a vertical datum, z is taken as ellipsoidal (same as Ellipsoidal).
  FromCrs,
  /// z is already an ellipsoidal height: h = z * vertical unit factor.
  Ellipsoidal,
  /// z is an orthometric height on EGM96 (`--geoid egm96`): h = z * factor + N_EGM96(lon, lat),
  /// N from PROJ's egm96_15.gtx grid (proj-data).
  Egm96,
};

struct TransformOptions {
  HeightMode height = HeightMode::FromCrs;
  /// WGS84 UTM horizontals through GeographicLib's TransverseMercator (Krueger series, no PROJ)
  /// instead of PROJ. Both agree to ~1e-8 m; off by default because PROJ's batch path measured
  /// ~2.5x faster (5 vs 2 Mpts/s per core). Useful as an independent check of PROJ.
  bool utm_geographiclib = false;
};

/// Transforms between a CRS (its own units, e.g. feet) and WGS84 `LonLatH`.
///
/// Owns one PROJ context: NOT safe to share between threads — clone() one per thread. Setting
/// one up (construction, clone()) asks PROJ's database for the operations (RD New + NAP:
/// ~65-75 ms the first time in a process, ~30 ms after), so a Transformer is built once per
/// CRS and options where possible. Results are
/// deterministic (same input -> same bits). All failures throw GeoError.
class Transformer {
 public:
  explicit Transformer(const Crs& crs, TransformOptions options = {});
  ~Transformer();
  Transformer(Transformer&&) noexcept;
  Transformer& operator=(Transformer&&) noexcept;
  Transformer(const Transformer&) = delete;
  Transformer& operator=(const Transformer&) = delete;

  /// An independent Transformer (own PROJ context) with the same CRS and options.
  Transformer clone() const;

  const Crs& crs() const;
  const TransformOptions& options() const;
  /// True when horizontals go through GeographicLib's UTM instead of PROJ.
  bool uses_geographiclib_utm() const;
  /// The height treatment actually used, after fallbacks (FromCrs may end as Egm96).
  HeightMode effective_height_mode() const;
  /// Human-readable description of the PROJ operation(s) in use.
  std::string description() const;
  /// Remarks such as the NAP -> EGM96 fallback. The library never prints them.
  const std::vector<std::string>& warnings() const;
  /// PROJ grids the CRS's vertical datum needs that are not installed, when FromCrs fell back
  /// to EGM96 (e.g. {"nl_nsgi_nlgeo2018.tif", ...}); empty otherwise.
  const std::vector<std::string>& missing_grids() const;

  /// (x, y, z) in CRS units -> (lon deg, lat deg, ellipsoidal h m).
  LonLatH to_wgs84(const Eigen::Vector3d& crs_point);
  /// Batch, in place: each column (x, y, z) in CRS units becomes (lon, lat, h).
  /// A std::vector<Eigen::Vector3d> v maps as Eigen::Map<Eigen::Matrix3Xd>(v[0].data(), 3, n).
  void to_wgs84_inplace(Eigen::Ref<Eigen::Matrix3Xd> points);

  /// (lon deg, lat deg, ellipsoidal h m) -> (x, y, z) in CRS units. Exact inverse of to_wgs84
  /// (PROJ's 2D inverse is refined by one correction step: round trips close to ~1e-8 m).
  Eigen::Vector3d from_wgs84(const LonLatH& geodetic);
  /// Batch inverse, in place.
  void from_wgs84_inplace(Eigen::Ref<Eigen::Matrix3Xd> points);

  /// Throws GeoError "coordinates (x, y) lie outside the area of use of EPSG:28992 (...)" when a
  /// corner or the centre of `bbox` (CRS units; z ignored) maps outside the CRS's area of use
  /// widened by `margin_deg` degrees (UTM: at least 3 degrees in longitude, since national
  /// grids routinely stretch a zone), or cannot be transformed at all. Without a recorded area
  /// it checks only that the points transform to valid coordinates.
  void check_in_area(const Eigen::AlignedBox3d& bbox, double margin_deg = 1.0);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Full path of PROJ's EGM96 grid (egm96_15.gtx) found in PROJ's search paths.
/// Throws GeoError naming the searched paths when it is missing (install proj-data).
std::string egm96_grid_path();

}  // namespace citylod::geo
