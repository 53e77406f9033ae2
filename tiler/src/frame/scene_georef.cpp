// SceneGeoref (scene_georef.hpp): the manifest's georeferencing, rebuilt once,
// lent out one Georef clone per concurrent caller.
#include "citylod/tiler/scene_georef.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "citylod/geo/crs.hpp"
#include "citylod/io/error.hpp"

namespace citylod::tiler {

SceneGeoref::SceneGeoref(const Manifest& man, const std::string& work_dir) {
  const SceneInfo& sc = man.scene;
  if (sc.crs.empty()) return;
  const std::string where = manifest_path(work_dir);
  try {
    const geo::Crs crs = geo::Crs::parse(sc.crs);
    const Eigen::Vector3d o(sc.origin_crs[0], sc.origin_crs[1], sc.origin_crs[2]);
    for (geo::HeightMode mode : {geo::HeightMode::FromCrs, geo::HeightMode::Egm96}) {
      geo::TransformOptions to;
      to.height = mode;
      geo::Georef r = geo::Georef::from_crs(crs, o, to);
      const geo::LonLatH& f = r.frame().origin();
      if (std::fabs(f[0] - sc.origin_lon) < 1e-9 && std::fabs(f[1] - sc.origin_lat) < 1e-9 &&
          std::fabs(f[2] - sc.origin_h) < 1e-3) {
        if (sc.projected_frame) r.use_projected_frame(o);
        proto_ = std::make_unique<geo::Georef>(std::move(r));
        break;
      }
    }
    if (!proto_)
      throw io::IoError(where, "the scene origin (" + std::to_string(sc.origin_lon) + ", " +
                                   std::to_string(sc.origin_lat) + ", " +
                                   std::to_string(sc.origin_h) + ") is not where " + sc.crs +
                                   " puts origin_crs: cannot convert back to the CRS");
  } catch (const geo::GeoError& e) {
    throw io::IoError(where, e.what());
  }
  projected_ = sc.projected_frame;
}

std::unique_ptr<geo::Georef> SceneGeoref::acquire() const {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!free_.empty()) {
      std::unique_ptr<geo::Georef> g = std::move(free_.back());
      free_.pop_back();
      return g;
    }
  }
  std::lock_guard<std::mutex> lock(mutex_);  // clone() reads proto_ (PROJ context set-up)
  return std::make_unique<geo::Georef>(proto_->clone());
}

void SceneGeoref::release(std::unique_ptr<geo::Georef> g) const {
  std::lock_guard<std::mutex> lock(mutex_);
  free_.push_back(std::move(g));
}

template <class F>
void SceneGeoref::with_georef(F&& f) const {
  std::unique_ptr<geo::Georef> g = acquire();
  try {
    f(*g);
  } catch (...) {
    release(std::move(g));
    throw;
  }
  release(std::move(g));
}

void SceneGeoref::to_crs(Eigen::Ref<Eigen::Matrix3Xd> points) const {
  if (!proto_) throw std::logic_error("SceneGeoref::to_crs: a local scene has no CRS");
  if (points.cols() == 0) return;
  with_georef([&](geo::Georef& g) { g.to_crs_inplace(points); });
}

void SceneGeoref::to_enu(Eigen::Ref<Eigen::Matrix3Xd> points) const {
  if (!projected_ || points.cols() == 0) return;
  with_georef([&](geo::Georef& g) { g.to_enu_inplace(points); });
}

void SceneGeoref::from_enu(Eigen::Ref<Eigen::Matrix3Xd> points) const {
  if (!projected_ || points.cols() == 0) return;
  with_georef([&](geo::Georef& g) { g.enu_to_scene_inplace(points); });
}

void SceneGeoref::from_crs(Eigen::Ref<Eigen::Matrix3Xd> points) const {
  if (!proto_) throw std::logic_error("SceneGeoref::from_crs: a local scene has no CRS");
  if (points.cols() == 0) return;
  with_georef([&](geo::Georef& g) { g.to_local_inplace(points); });
}

}  // namespace citylod::tiler
