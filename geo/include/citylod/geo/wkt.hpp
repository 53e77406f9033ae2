// What `citylod info` shows of a WKT CRS (LAS WKT VLRs), read by PROJ.
#pragma once

#include <string>

namespace citylod::geo {

struct WktSummary {
  std::string name;       ///< horizontal CRS name
  int epsg = 0;           ///< EPSG id of the horizontal CRS as written in the WKT (0 = none)
  int vertical_epsg = 0;  ///< of the vertical CRS in a compound CRS
  std::string unit;       ///< "metre", "foot", "US survey foot", or the name in the WKT ("" for geographic)
  double unit_m = 0;      ///< metres per unit
};

/// Never throws; returns an empty summary for text PROJ does not understand.
WktSummary summarize_wkt(const std::string& wkt);

}  // namespace citylod::geo
