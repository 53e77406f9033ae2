// The georeferencing of a work directory's scene, rebuilt from its manifest
// (scene.crs, origin_crs, the WGS84 origin, the frame): how the chunks' and
// models' coordinates (the scene frame plus a chunk origin) reach the tiles'
// ENU frame (3D Tiles) and the input's CRS (CityJSON), and back. One place for
// what assemble, cityjson and eval need.
#pragma once

#include <Eigen/Core>

#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "citylod/geo/georef.hpp"
#include "citylod/tiler/workdir.hpp"

namespace citylod::tiler {

class SceneGeoref {
 public:
  /// From the manifest of `work_dir`. The height mode (the CRS's own vertical datum, or
  /// EGM96 for `--geoid egm96`) is the one that reproduces the manifest's WGS84 origin:
  /// either way the inverse of what split did. Throws io::IoError naming the manifest when
  /// neither does. Local scenes (`--origin`, no CRS): ENU metres, no CRS.
  SceneGeoref(const Manifest& man, const std::string& work_dir);

  bool has_crs() const { return bool(proto_); }
  /// Chunk coordinates are the CRS's axes in metres (geo::SceneFrame::projected).
  bool projected() const { return projected_; }

  /// Scene metres -> ENU metres at the manifest's origin (the tiles' frame), in place:
  /// the identity for ENU scenes. Thread-safe.
  void to_enu(Eigen::Ref<Eigen::Matrix3Xd> points) const;
  /// ENU metres at the origin -> scene metres, in place. Thread-safe.
  void from_enu(Eigen::Ref<Eigen::Matrix3Xd> points) const;
  /// Scene metres -> CRS units, in place (exact for a projected frame). Thread-safe;
  /// std::logic_error for local scenes.
  void to_crs(Eigen::Ref<Eigen::Matrix3Xd> points) const;
  /// CRS units -> scene metres, in place (exact for a projected frame). Thread-safe;
  /// std::logic_error for local scenes.
  void from_crs(Eigen::Ref<Eigen::Matrix3Xd> points) const;

 private:
  std::unique_ptr<geo::Georef> acquire() const;
  template <class F>
  void with_georef(F&& f) const;  // f(Georef&) on a clone lent for the call
  void release(std::unique_ptr<geo::Georef> g) const;

  std::unique_ptr<geo::Georef> proto_;  // null: local scene
  bool projected_ = false;
  mutable std::mutex mutex_;
  mutable std::vector<std::unique_ptr<geo::Georef>> free_;  // clones (a Georef is not thread-safe)
};

}  // namespace citylod::tiler
