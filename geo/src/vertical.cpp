#include "citylod/geo/vertical.hpp"

#include "citylod/geo/types.hpp"

#include <algorithm>
#include <cctype>

namespace citylod::geo {

namespace {

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// "-> ellipsoidal via ..." for a Transformer set up in FromCrs or Egm96 mode.
std::string via(const Transformer& t) {
  if (t.effective_height_mode() == HeightMode::FromCrs)
    return "-> ellipsoidal via PROJ (" + t.description() + ")";
  std::string s = "-> ellipsoidal via EGM96";
  if (!t.missing_grids().empty()) s += " (" + join(t.missing_grids()) + " not installed)";
  return s;
}

/// `c` with the outcome of `t`, which was set up for c.crs + c.options (kept for the Georef).
VerticalChoice finish(VerticalChoice c, std::unique_ptr<Transformer> t) {
  c.effective = t->effective_height_mode();
  c.missing_grids = t->missing_grids();
  c.warnings = t->warnings();
  c.transformer = std::move(t);
  return c;
}

const ImpliedVertical* implied_for(const Crs& crs) {
  if (!crs.epsg() || crs.has_vertical_datum()) return nullptr;
  for (const ImpliedVertical& v : implied_vertical_table())
    if (v.horizontal_epsg == *crs.epsg()) return &v;
  return nullptr;
}

}  // namespace

VerticalMode parse_vertical_mode(const std::string& word) {
  std::string w = word;
  std::transform(w.begin(), w.end(), w.begin(), [](unsigned char ch) { return std::tolower(ch); });
  if (w == "auto") return VerticalMode::Auto;
  if (w == "ellipsoidal") return VerticalMode::Ellipsoidal;
  if (w == "orthometric") return VerticalMode::Orthometric;
  throw GeoError("unknown vertical mode '" + word + "' (auto, ellipsoidal or orthometric)");
}

const char* to_string(VerticalMode m) {
  switch (m) {
    case VerticalMode::Auto:
      return "auto";
    case VerticalMode::Ellipsoidal:
      return "ellipsoidal";
    case VerticalMode::Orthometric:
      return "orthometric";
  }
  return "auto";
}

const std::vector<ImpliedVertical>& implied_vertical_table() {
  static const std::vector<ImpliedVertical> table = {
      {28992, 5709, "NAP", false},
      {2056, 5728, "LN02", true},
      {25832, 7837, "DHHN2016", true},
      {25833, 7837, "DHHN2016", true},
  };
  return table;
}

VerticalChoice choose_vertical(const Crs& crs, VerticalMode mode) {
  VerticalChoice c;
  c.crs = crs;
  const std::string label = crs.label();

  if (mode == VerticalMode::Ellipsoidal) {
    c.options.height = HeightMode::Ellipsoidal;
    c.effective = HeightMode::Ellipsoidal;
    c.assumption =
        "heights taken as ellipsoidal (--vertical ellipsoidal)" +
        std::string(crs.has_vertical_datum() ? "; the vertical datum of " + label + " (" +
                                                   crs.vertical_name() + ") is ignored"
                                             : "");
    return c;
  }

  // a compound CRS: its own vertical datum
  if (crs.has_vertical_datum()) {
    c.options.height = HeightMode::FromCrs;
    c.datum = crs.vertical_name();
    auto t = std::make_unique<Transformer>(c.crs, c.options);
    c.assumption = "heights " + c.datum + " (from " + label + ") " + via(*t);
    return finish(std::move(c), std::move(t));
  }

  // a horizontal CRS whose national practice implies a vertical datum
  // (not when z was given another unit than the datum's: a vertical CRS fixes its unit)
  const ImpliedVertical* v = implied_for(crs);
  std::optional<Crs> compound;
  if (v) {
    compound = Crs::parse("EPSG:" + std::to_string(v->horizontal_epsg) + "+" +
                          std::to_string(v->vertical_epsg));
    if (compound->vertical_unit().to_si != crs.vertical_unit().to_si) v = nullptr;
  }
  if (v) {
    TransformOptions o;
    o.height = HeightMode::FromCrs;
    auto t = std::make_unique<Transformer>(*compound, o);
    if (!v->needs_proj_path || t->effective_height_mode() == HeightMode::FromCrs) {
      c.crs = *compound;
      c.options = o;
      c.datum = v->datum;
      c.vertical_epsg = v->vertical_epsg;
      c.implied = true;
      c.assumption = "heights " + v->datum + " (implied by " + label + ") " + via(*t);
      return finish(std::move(c), std::move(t));
    }
    if (mode == VerticalMode::Auto) {
      c.options.height = HeightMode::Ellipsoidal;
      c.effective = HeightMode::Ellipsoidal;
      c.missing_grids = t->missing_grids();
      c.assumption = "heights taken as ellipsoidal: " + label + " heights are often " + v->datum +
                     ", but PROJ cannot convert " + v->datum + " here (" +
                     join(t->missing_grids()) +
                     " not installed); --vertical orthometric for heights above the EGM96 geoid";
      return c;
    }
    // Orthometric: fall through to EGM96
  }

  if (mode == VerticalMode::Auto) {
    c.options.height = HeightMode::Ellipsoidal;
    c.effective = HeightMode::Ellipsoidal;
    c.assumption = "heights taken as ellipsoidal: " + label +
                   " has no vertical datum and none is implied (--vertical orthometric for "
                   "heights above the EGM96 geoid)";
    return c;
  }

  // Orthometric, no datum known: EGM96
  c.options.height = HeightMode::Egm96;
  c.datum = "EGM96";
  auto t = std::make_unique<Transformer>(c.crs, c.options);
  c.assumption = "heights orthometric (--vertical orthometric) -> ellipsoidal via EGM96";
  return finish(std::move(c), std::move(t));
}

}  // namespace citylod::geo
