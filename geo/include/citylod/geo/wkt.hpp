// What `citylod info` shows of a WKT CRS (LAS WKT VLRs): name, EPSG ids and
// linear unit as written, also for incomplete WKT that PROJ would refuse.
#pragma once

#include <string>

namespace citylod::geo {

struct WktSummary {
  std::string name;       ///< horizontal CRS name
  int epsg = 0;           ///< AUTHORITY["EPSG",..] / ID["EPSG",..] of the horizontal CRS
  int vertical_epsg = 0;  ///< of the vertical CRS in a compound CRS
  std::string unit;       ///< "metre", "foot", "US survey foot", or the name in the WKT
  double unit_m = 0;      ///< metres per unit
};

/// Never throws; returns an empty summary for text it does not understand.
WktSummary summarize_wkt(const std::string& wkt);

}  // namespace citylod::geo
