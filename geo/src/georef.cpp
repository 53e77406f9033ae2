#include "citylod/geo/georef.hpp"

#include "citylod/geo/units.hpp"
#include "lattice.hpp"

namespace citylod::geo {

namespace {
constexpr double kLatticeCell = 64.0;       // metres
constexpr double kLatticeTolerance = 1e-7;  // metres, at a cell's check points
}  // namespace

Georef::Georef(LocalFrame frame, Eigen::Vector3d origin_crs, std::unique_ptr<Transformer> t)
    : frame_(std::move(frame)), origin_crs_(std::move(origin_crs)), transformer_(std::move(t)) {}
Georef::~Georef() = default;
Georef::Georef(Georef&&) noexcept = default;
Georef& Georef::operator=(Georef&&) noexcept = default;

Georef Georef::from_crs(const Crs& crs, const Eigen::Vector3d& origin_crs, TransformOptions opts) {
  auto t = std::make_unique<Transformer>(crs, opts);
  const LonLatH origin = t->to_wgs84(origin_crs);
  return Georef(LocalFrame(origin), origin_crs, std::move(t));
}

Georef Georef::from_crs_bbox(const Crs& crs, const Eigen::AlignedBox3d& bbox_crs,
                             TransformOptions opts, double area_margin_deg) {
  return from_transformer_bbox(std::make_unique<Transformer>(crs, opts), bbox_crs, area_margin_deg);
}

Georef Georef::from_transformer_bbox(std::unique_ptr<Transformer> t,
                                     const Eigen::AlignedBox3d& bbox_crs, double area_margin_deg) {
  if (!t) throw GeoError("from_transformer_bbox: no transformer");
  const Crs& crs = t->crs();
  // metre data under a feet CRS (or the reverse) is refused, also when it lands within the
  // margin of the area test; when the area test fails, the unit is named as the likely cause
  const std::string swapped = unit_swap_evidence(crs, bbox_crs);
  if (!swapped.empty()) throw GeoError(swapped);
  // a unit that makes the scene smaller than a building (or wider than the earth) likewise
  const std::string scale = unit_scale_evidence(crs, bbox_crs);
  if (!scale.empty()) throw GeoError(scale);
  t->check_in_area(bbox_crs, area_margin_deg);
  // the same transformer (setting one up asks PROJ's database for its operations: ~0.1 s)
  const Eigen::Vector3d origin_crs = bbox_crs.center();
  const LonLatH origin = t->to_wgs84(origin_crs);
  return Georef(LocalFrame(origin), origin_crs, std::move(t));
}

Georef Georef::local(const LonLatH& origin) {
  return Georef(LocalFrame(origin), Eigen::Vector3d::Zero(), nullptr);
}

void Georef::use_projected_frame(const Eigen::Vector3d& origin_crs) {
  const Crs& c = crs();  // throws for local scenes
  h_to_si_ = c.horizontal_unit().to_si;
  v_to_si_ = c.vertical_unit().to_si;
  origin_crs_ = origin_crs;
  frame_ = LocalFrame(transformer_->to_wgs84(origin_crs));
  scene_ = SceneFrame::projected;
}

Georef Georef::clone() const {
  Georef g(frame_, origin_crs_,
           transformer_ ? std::make_unique<Transformer>(transformer_->clone()) : nullptr);
  g.exact_ = exact_;
  g.scene_ = scene_;
  g.h_to_si_ = h_to_si_;
  g.v_to_si_ = v_to_si_;
  return g;
}

const Crs& Georef::crs() const {
  if (!transformer_) throw GeoError("this scene is in a local frame (--origin) and has no CRS");
  return transformer_->crs();
}

std::vector<std::string> Georef::warnings() const {
  return transformer_ ? transformer_->warnings() : std::vector<std::string>{};
}

Eigen::Vector3d Georef::to_local(const Eigen::Vector3d& p) {
  if (!transformer_) return p;
  if (scene_ == SceneFrame::projected)
    return {(p[0] - origin_crs_[0]) * h_to_si_, (p[1] - origin_crs_[1]) * h_to_si_,
            (p[2] - origin_crs_[2]) * v_to_si_};
  return frame_.geodetic_to_enu(transformer_->to_wgs84(p));
}

void Georef::to_local_inplace(Eigen::Ref<Eigen::Matrix3Xd> points) {
  if (!transformer_) return;
  if (scene_ == SceneFrame::projected) {
    for (Eigen::Index i = 0; i < points.cols(); ++i) points.col(i) = to_local(points.col(i));
    return;
  }
  crs_to_enu_inplace(points);
}

void Georef::crs_to_enu_inplace(Eigen::Ref<Eigen::Matrix3Xd> points) {
  const auto exact = [this](Eigen::Ref<Eigen::Matrix3Xd> p) {
    transformer_->to_wgs84_inplace(p);
    for (Eigen::Index i = 0; i < p.cols(); ++i) p.col(i) = frame_.geodetic_to_enu(p.col(i));
  };
  const Crs& crs = transformer_->crs();
  if (exact_ || !crs.is_projected()) return exact(points);
  if (!lattice_) {
    const double h = crs.horizontal_unit().to_si, v = crs.vertical_unit().to_si;
    lattice_ = std::make_unique<detail::Lattice>(kLatticeCell / h, 1000.0 / v, kLatticeTolerance);
  }
  lattice_->apply(points, exact);
}

Eigen::Vector3d Georef::to_crs(const Eigen::Vector3d& p) {
  crs();  // throws for local scenes
  if (scene_ == SceneFrame::projected)
    return {p[0] / h_to_si_ + origin_crs_[0], p[1] / h_to_si_ + origin_crs_[1],
            p[2] / v_to_si_ + origin_crs_[2]};
  return transformer_->from_wgs84(frame_.enu_to_geodetic(p));
}

void Georef::to_crs_inplace(Eigen::Ref<Eigen::Matrix3Xd> points) {
  crs();  // throws for local scenes
  if (scene_ == SceneFrame::projected) {
    for (Eigen::Index i = 0; i < points.cols(); ++i) points.col(i) = to_crs(points.col(i));
    return;
  }
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    points.col(i) = frame_.enu_to_geodetic(points.col(i));
  transformer_->from_wgs84_inplace(points);
}

void Georef::to_enu_inplace(Eigen::Ref<Eigen::Matrix3Xd> points) {
  if (scene_ != SceneFrame::projected) return;
  to_crs_inplace(points);
  crs_to_enu_inplace(points);
}

void Georef::enu_to_scene_inplace(Eigen::Ref<Eigen::Matrix3Xd> points) {
  if (scene_ != SceneFrame::projected) return;
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    points.col(i) = frame_.enu_to_geodetic(points.col(i));
  transformer_->from_wgs84_inplace(points);
  to_local_inplace(points);
}

Eigen::Vector3d Georef::from_geodetic(const LonLatH& g) {
  if (scene_ == SceneFrame::projected) return to_local(transformer_->from_wgs84(g));
  return frame_.geodetic_to_enu(g);
}

LonLatH Georef::to_geodetic(const Eigen::Vector3d& p) {
  if (scene_ == SceneFrame::projected) return transformer_->to_wgs84(to_crs(p));
  return frame_.enu_to_geodetic(p);
}

}  // namespace citylod::geo
