// citylod::geo — which vertical datum the input heights are in, decided once per run.
//
// Tilesets always carry WGS 84 ellipsoidal heights. Input heights are
// orthometric when the CRS says so (a compound CRS such as EPSG:7415 = RD New
// + NAP) or when the horizontal CRS's national practice implies a vertical
// datum (the small table below: RD New -> NAP). Orthometric heights go
// through the best model installed: PROJ's own path when its grids are
// present, else the EGM96 geoid (see README.md, "Heights and geoid grids").
#pragma once

#include "citylod/geo/crs.hpp"
#include "citylod/geo/transformer.hpp"

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace citylod::geo {

/// What the user said about heights (`--vertical auto|ellipsoidal|orthometric`).
enum class VerticalMode {
  Auto,         ///< from the CRS: its vertical datum, else the implied one, else ellipsoidal
  Ellipsoidal,  ///< z is a WGS 84 / ETRS89 ellipsoidal height: kept as is
  Orthometric,  ///< z is above the geoid: the CRS's (implied) datum, else EGM96
};

/// Parses "auto", "ellipsoidal", "orthometric". Throws GeoError naming the accepted words.
VerticalMode parse_vertical_mode(const std::string& word);
/// "auto" | "ellipsoidal" | "orthometric".
const char* to_string(VerticalMode m);

/// A vertical datum a horizontal CRS implies by national practice.
struct ImpliedVertical {
  int horizontal_epsg = 0;  ///< e.g. 28992 (RD New)
  int vertical_epsg = 0;    ///< e.g. 5709 (NAP height)
  std::string datum;        ///< e.g. "NAP"
  /// Only applied when PROJ has a complete (non-ballpark, grids installed)
  /// transformation of the compound CRS; RD New -> NAP always applies (AHN and
  /// every Dutch LiDAR is NAP), falling back to EGM96.
  bool needs_proj_path = true;
};

/// The table, conservative on purpose (a wrong guess moves a city by tens of metres):
///   28992 Amersfoort / RD New          -> 5709 NAP height (always)
///   2056  CH1903+ / LV95               -> 5728 LN02 height (if PROJ can: CH grids)
///   25832 ETRS89 / UTM 32N (Germany)   -> 7837 DHHN2016 height (if PROJ can: GCG2016)
///   25833 ETRS89 / UTM 33N (Germany)   -> 7837 DHHN2016 height (if PROJ can: GCG2016)
/// (UTM 32N/33N are used outside Germany too; without PROJ's German geoid their heights
/// stay ellipsoidal unless --vertical orthometric is given.)
const std::vector<ImpliedVertical>& implied_vertical_table();

/// The decision, ready for a Transformer: Transformer t(choice.crs, choice.options).
struct VerticalChoice {
  /// The CRS to transform with: the input CRS, or the compound "EPSG:h+v" when a
  /// vertical datum is implied.
  Crs crs;
  TransformOptions options;
  /// The height treatment that will actually run (after fallbacks): FromCrs (PROJ's
  /// vertical path), Egm96, or Ellipsoidal.
  HeightMode effective = HeightMode::Ellipsoidal;
  std::string datum;      ///< "NAP", "NAP height", "EGM96"; "" when heights are ellipsoidal
  int vertical_epsg = 0;  ///< vertical CRS code when known (5709), else 0
  bool implied = false;   ///< the datum comes from implied_vertical_table()
  /// One sentence for the run summary and run_report.json, e.g. "heights NAP (implied by
  /// EPSG:28992) -> ellipsoidal via EGM96 (nl_nsgi_nlgeo2018.tif not installed)".
  std::string assumption;
  std::vector<std::string> missing_grids;  ///< PROJ grids that would have been better
  std::vector<std::string> warnings;       ///< the Transformer's remarks
  /// The Transformer for `crs` + `options` that the choice set up to decide (null when it
  /// set up none): Georef::from_transformer_bbox adopts it, since setting up another asks
  /// PROJ's database again (RD New + NAP: ~30-75 ms).
  std::unique_ptr<Transformer> transformer;
};

/// Decides how z becomes an ellipsoidal height for `crs`. Throws GeoError when
/// the EGM96 grid is needed and missing (install proj-data).
VerticalChoice choose_vertical(const Crs& crs, VerticalMode mode = VerticalMode::Auto);

}  // namespace citylod::geo
