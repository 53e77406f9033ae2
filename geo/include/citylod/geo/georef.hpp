// citylod::geo::Georef — the georeferencing of one scene: CRS <-> local ENU at a scene origin.
#pragma once

#include "citylod/geo/crs.hpp"
#include "citylod/geo/local_frame.hpp"
#include "citylod/geo/transformer.hpp"

#include <memory>
#include <optional>

namespace citylod::geo {
namespace detail {
class Lattice;
}

/// How a scene's coordinates relate to its CRS.
///  - `enu`: local east-north-up metres at the origin (the earth's curvature and the
///    geoid are in them: the same building gets other coordinates elsewhere);
///  - `projected`: the CRS's own axes converted to metres, minus the origin (x, y) and
///    heights as the input gives them minus the origin's: a translation and the units'
///    scale only, so the same points have the same coordinates wherever they lie. The
///    curvature and the geoid enter when the tiles are written (to_enu_inplace).
enum class SceneFrame { enu, projected };

/// After ingest all geometry is float64 metres in the scene frame (`scene_frame()`). Georef
/// converts CRS coordinates (their own units) to that frame and back, from the scene frame to
/// the ENU frame of the tiles at `frame()`, and gives what 3D Tiles needs (root transform,
/// bounding regions of ENU boxes).
///
/// Holds a Transformer, so it is NOT thread-safe: clone() one per thread.
class Georef {
 public:
  /// Scene in `crs`; the ENU origin is the point `origin_crs` (CRS units, z included) mapped to
  /// WGS84. Throws GeoError if the origin cannot be transformed.
  static Georef from_crs(const Crs& crs, const Eigen::Vector3d& origin_crs,
                         TransformOptions options = {});
  /// Scene in `crs` with data bounding box `bbox_crs` (CRS units): checks the box against the
  /// CRS's area of use (GeoError if outside, see Transformer::check_in_area; also when it is
  /// inside only read in the other unit, metre <-> foot: see unit_swap_evidence) and puts the
  /// origin at the box centre.
  static Georef from_crs_bbox(const Crs& crs, const Eigen::AlignedBox3d& bbox_crs,
                              TransformOptions options = {}, double area_margin_deg = 1.0);
  /// The same with a Transformer already set up (e.g. VerticalChoice::transformer): setting
  /// one up asks PROJ's database for its operations (RD New + NAP: ~65-75 ms the first time
  /// in a process, ~30 ms after), so one is not built twice.
  static Georef from_transformer_bbox(std::unique_ptr<Transformer> transformer,
                                      const Eigen::AlignedBox3d& bbox_crs,
                                      double area_margin_deg = 1.0);
  /// Data already in local ENU metres at `origin` (`--origin LAT,LON,H`): no CRS, to_local is
  /// the identity.
  static Georef local(const LonLatH& origin);

  /// Puts the scene in the projected frame at `origin_crs` (CRS units; the ENU frame of the
  /// tiles moves to it too). For a Georef with a CRS.
  void use_projected_frame(const Eigen::Vector3d& origin_crs);
  SceneFrame scene_frame() const { return scene_; }

  Georef clone() const;
  ~Georef();
  Georef(Georef&&) noexcept;
  Georef& operator=(Georef&&) noexcept;

  bool has_crs() const { return transformer_ != nullptr; }
  const Crs& crs() const;  ///< throws GeoError when !has_crs()
  const LocalFrame& frame() const { return frame_; }
  /// The origin in CRS units (ENU (0,0,0)); for local scenes, (0,0,0).
  const Eigen::Vector3d& origin_crs() const { return origin_crs_; }
  /// Warnings of the CRS and the transformer (e.g. the NAP -> EGM96 fallback).
  std::vector<std::string> warnings() const;

  /// CRS units -> scene metres.
  Eigen::Vector3d to_local(const Eigen::Vector3d& crs_point);
  /// Batch, in place: columns in CRS units become scene metres. Projected frame: the
  /// translation and scale. ENU frame: for a projected CRS
  /// through a lattice of 64 m cells (geo/src/lattice.hpp: PROJ at its nodes,
  /// biquadratic in between, each cell checked against PROJ to 0.1 micrometre, else
  /// PROJ point by point; tests/geo/test_lattice.cpp: within 2e-8 m of PROJ, 2.5-8x
  /// faster);
  /// to_local() is PROJ itself.
  void to_local_inplace(Eigen::Ref<Eigen::Matrix3Xd> points);
  /// Every point of to_local_inplace through PROJ (no lattice): for tests.
  void set_exact(bool exact) { exact_ = exact; }
  /// Scene metres -> CRS units (GeoError for local scenes).
  Eigen::Vector3d to_crs(const Eigen::Vector3d& scene);
  void to_crs_inplace(Eigen::Ref<Eigen::Matrix3Xd> points);
  /// Scene metres -> ENU metres at frame() (the tiles' frame), in place: the identity in the
  /// ENU frame; in the projected frame the CRS's transformation (through the lattice).
  void to_enu_inplace(Eigen::Ref<Eigen::Matrix3Xd> points);
  /// ENU metres at frame() -> scene metres, in place (the inverse of to_enu_inplace).
  void enu_to_scene_inplace(Eigen::Ref<Eigen::Matrix3Xd> points);

  Eigen::Vector3d to_ecef(const Eigen::Vector3d& enu) const { return frame_.enu_to_ecef(enu); }
  /// Geodetic coordinates of a scene point, and back.
  LonLatH to_geodetic(const Eigen::Vector3d& scene);
  Eigen::Vector3d from_geodetic(const LonLatH& g);
  /// Root `transform` for tileset.json (column-major ENU -> ECEF).
  std::array<double, 16> root_transform() const { return frame_.enu_to_ecef_matrix(); }
  /// 3D Tiles region of a local ENU box.
  BoundingRegion bounding_region(const Eigen::AlignedBox3d& enu_box) const {
    return frame_.bounding_region(enu_box);
  }

 private:
  Georef(LocalFrame frame, Eigen::Vector3d origin_crs, std::unique_ptr<Transformer> t);
  /// CRS units -> ENU metres, in place (the lattice for projected CRSs).
  void crs_to_enu_inplace(Eigen::Ref<Eigen::Matrix3Xd> points);
  LocalFrame frame_;
  SceneFrame scene_ = SceneFrame::enu;
  double h_to_si_ = 1, v_to_si_ = 1;  // projected frame: the CRS's units
  Eigen::Vector3d origin_crs_;
  std::unique_ptr<Transformer> transformer_;
  std::unique_ptr<detail::Lattice> lattice_;  // made on first use
  bool exact_ = false;
};

}  // namespace citylod::geo
