// Private: a small WKT (WKT1 and WKT2) summariser for `citylod info`: CRS
// name, EPSG code, linear unit. Full CRS handling lives in citylod::geo.
#pragma once

#include <string>

namespace citylod::io::detail {

struct WktSummary {
  std::string name;       ///< horizontal CRS name
  int epsg = 0;           ///< AUTHORITY["EPSG",..] / ID["EPSG",..] of the horizontal CRS
  int vertical_epsg = 0;  ///< of the vertical CRS in a compound CRS
  std::string unit;       ///< "metre", "foot", "US survey foot", or the name in the WKT
  double unit_m = 0;      ///< metres per unit
};

/// Never throws; returns an empty summary for text it does not understand.
WktSummary summarize_wkt(const std::string& wkt);

}  // namespace citylod::io::detail
