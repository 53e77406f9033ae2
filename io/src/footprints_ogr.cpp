// Footprints from OGR sources through GDAL's C++ API (see footprints.hpp).
#include "citylod/io/footprints.hpp"

#include <gdal.h>
#include <gdal_priv.h>
#include <ogr_api.h>
#include <ogr_geometry.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <mutex>

#include "citylod/io/error.hpp"

namespace citylod::io {
namespace {

using Ring = std::vector<std::array<double, 2>>;

void register_gdal() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// GDAL messages are collected instead of printed while a source is read.
thread_local std::vector<std::string>* g_messages = nullptr;

void CPL_STDCALL collect_messages(CPLErr, CPLErrorNum, const char* msg) {
  if (g_messages && msg && g_messages->size() < 64) g_messages->push_back(msg);
}

class QuietGdal {
 public:
  QuietGdal() {
    prev_ = g_messages;
    g_messages = &messages;
    CPLPushErrorHandler(collect_messages);
    CPLErrorReset();
  }
  ~QuietGdal() {
    CPLPopErrorHandler();
    g_messages = prev_;
  }
  QuietGdal(const QuietGdal&) = delete;
  QuietGdal& operator=(const QuietGdal&) = delete;

  /// The last message since `from` ("" when none), and forgets them.
  std::string take_last(std::size_t from = 0) {
    std::string m = messages.size() > from ? messages.back() : std::string();
    messages.resize(std::min(messages.size(), from));
    return m;
  }
  std::vector<std::string> messages;

 private:
  std::vector<std::string>* prev_;
};

// A "PG:" connection string without its password, for messages.
// A hand parser: a std::regex match recurses per character (a long string overflowed the stack).
std::string mask_source(const std::string& s) {
  auto space = [&](std::size_t k) { return std::isspace(static_cast<unsigned char>(s[k])) != 0; };
  std::string out;
  std::size_t i = 0;
  const std::string key = "password";
  while (i < s.size()) {
    bool match = s.size() - i >= key.size();
    for (std::size_t k = 0; match && k < key.size(); ++k)
      match = std::tolower(static_cast<unsigned char>(s[i + k])) == key[k];
    if (!match) {
      out += s[i++];
      continue;
    }
    std::size_t j = i + key.size();
    while (j < s.size() && space(j)) ++j;
    if (j >= s.size() || s[j] != '=') {
      out += s[i++];
      continue;
    }
    ++j;
    while (j < s.size() && space(j)) ++j;
    std::size_t e = j;
    if (e < s.size() && s[e] == '\'') {
      const std::size_t close = s.find('\'', e + 1);
      e = close == std::string::npos ? e : close + 1;
    }
    if (e == j)
      while (e < s.size() && !space(e)) ++e;
    if (e == j) {  // nothing after '='
      out += s.substr(i, j - i);
      i = j;
      continue;
    }
    out += s.substr(i, j - i) + "***";
    i = e;
  }
  return out;
}

bool is_pg(const std::string& s) {
  return s.size() >= 3 && (s.compare(0, 3, "PG:") == 0 || s.compare(0, 3, "pg:") == 0);
}

struct DatasetCloser {
  void operator()(GDALDataset* d) const { GDALClose(d); }
};
using DatasetPtr = std::unique_ptr<GDALDataset, DatasetCloser>;

DatasetPtr open_source(const std::string& source, const std::string& shown) {
  register_gdal();
  std::string path = source;
  // libpq waits for an unreachable server for ever by default: a read never hangs
  if (is_pg(path) && path.find("connect_timeout") == std::string::npos)
    path += " connect_timeout=10";
  QuietGdal quiet;
  // GeoJSON turns date-like strings into OGR dates ("2014-07-09" -> "2014/07/09"): keep
  // them as written, so that a GeoJSON and the GeoPackage it came from agree.
  const char* geojson_options[] = {"DATE_AS_STRING=YES", nullptr};
  GDALDriverH drv = GDALIdentifyDriverEx(path.c_str(), GDAL_OF_VECTOR, nullptr, nullptr);
  const bool geojson = drv && std::string(GDALGetDriverShortName(drv)) == "GeoJSON";
  GDALDataset* ds =
      static_cast<GDALDataset*>(GDALOpenEx(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY, nullptr,
                                           geojson ? geojson_options : nullptr, nullptr));
  if (!ds) {
    std::string why = quiet.take_last();
    // libpq's messages span lines; keep the report on one line
    for (char& c : why)
      if (c == '\n' || c == '\r') c = ' ';
    while (!why.empty() && why.back() == ' ') why.pop_back();
    if (why.empty()) why = "no GDAL vector driver recognises it, or it does not exist";
    throw IoError(shown, "cannot open as a footprint (vector) source: " + why);
  }
  return DatasetPtr(ds);
}

std::vector<std::string> layer_names(GDALDataset& ds) {
  std::vector<std::string> names;
  for (int i = 0; i < ds.GetLayerCount(); ++i)
    if (OGRLayer* l = ds.GetLayer(i)) names.emplace_back(l->GetName());
  return names;
}

std::string join(const std::vector<std::string>& v, std::size_t max = 20) {
  std::string s;
  for (std::size_t i = 0; i < v.size() && i < max; ++i) s += (i ? ", " : "") + v[i];
  if (v.size() > max) s += ", ... (" + std::to_string(v.size()) + " in all)";
  return s;
}

double ring_area(const Ring& r) {
  double a = 0;
  for (std::size_t i = 0, j = r.size() - 1; i < r.size(); j = i++)
    a += (r[j][0] - r[0][0]) * (r[i][1] - r[0][1]) - (r[i][0] - r[0][0]) * (r[j][1] - r[0][1]);
  return 0.5 * a;
}

// The vertices of a ring, without repeated consecutive vertices or the closing copy.
Ring clean_ring(const OGRLinearRing& lr) {
  Ring r;
  r.reserve(static_cast<std::size_t>(lr.getNumPoints()));
  for (int i = 0; i < lr.getNumPoints(); ++i) {
    const std::array<double, 2> p{lr.getX(i), lr.getY(i)};
    if (!std::isfinite(p[0]) || !std::isfinite(p[1])) return {};
    if (r.empty() || r.back() != p) r.push_back(p);
  }
  while (r.size() > 1 && r.front() == r.back()) r.pop_back();
  return r;
}

// A ring has area when it spans more than rounding noise of its coordinates.
bool has_area(const Ring& r) {
  if (r.size() < 3) return false;
  double x0 = r[0][0], x1 = x0, y0 = r[0][1], y1 = y0;
  for (const auto& p : r) {
    x0 = std::min(x0, p[0]);
    x1 = std::max(x1, p[0]);
    y0 = std::min(y0, p[1]);
    y1 = std::max(y1, p[1]);
  }
  const double extent = std::max({x1 - x0, y1 - y0, 1e-300});
  return std::abs(ring_area(r)) > 1e-12 * extent * extent;
}

void collect_polygons(const OGRGeometry* g, std::vector<const OGRPolygon*>& out,
                      std::string& other) {
  if (!g || g->IsEmpty()) return;
  switch (wkbFlatten(g->getGeometryType())) {
    case wkbPolygon:
      out.push_back(g->toPolygon());
      break;
    case wkbMultiPolygon:
    case wkbGeometryCollection:
      for (const OGRGeometry* part : *g->toGeometryCollection()) collect_polygons(part, out, other);
      break;
    default:
      if (other.empty()) other = g->getGeometryName();
      break;
  }
}

// Polygon rings in our convention: exterior CCW first, holes CW. Empty when
// the exterior has fewer than 3 vertices, or no area when `need_area` (a
// bowtie has a signed area of 0 but is a polygon GEOS repairs); degenerate
// holes are dropped (counted).
std::vector<Ring> polygon_rings(const OGRPolygon& p, int* dropped_holes, bool need_area = true) {
  std::vector<Ring> rings;
  const OGRLinearRing* ext = p.getExteriorRing();
  if (!ext) return rings;
  Ring outer = clean_ring(*ext);
  if (outer.size() < 3 || (need_area && !has_area(outer))) return rings;
  if (ring_area(outer) < 0) std::reverse(outer.begin(), outer.end());
  rings.push_back(std::move(outer));
  for (int i = 0; i < p.getNumInteriorRings(); ++i) {
    Ring h = clean_ring(*p.getInteriorRing(i));
    if (!has_area(h)) {
      ++*dropped_holes;
      continue;
    }
    if (ring_area(h) > 0) std::reverse(h.begin(), h.end());
    rings.push_back(std::move(h));
  }
  return rings;
}

// An OGR polygon rebuilt from cleaned rings (closed), for the validity test.
std::unique_ptr<OGRPolygon> to_ogr(const std::vector<Ring>& rings) {
  auto p = std::make_unique<OGRPolygon>();
  for (const Ring& r : rings) {
    auto lr = std::make_unique<OGRLinearRing>();
    for (const auto& v : r) lr->addPoint(v[0], v[1]);
    lr->addPoint(r[0][0], r[0][1]);
    p->addRingDirectly(lr.release());
  }
  return p;
}

nlohmann::json attributes_of(OGRFeature& f) {
  nlohmann::json a = nlohmann::json::object();
  OGRFeatureDefn* d = f.GetDefnRef();
  for (int i = 0; i < d->GetFieldCount(); ++i) {
    const OGRFieldDefn* fd = d->GetFieldDefn(i);
    if (!f.IsFieldSet(i)) continue;
    const std::string name = fd->GetNameRef();
    if (f.IsFieldNull(i)) {
      a[name] = nullptr;
      continue;
    }
    switch (fd->GetType()) {
      case OFTInteger:
        if (fd->GetSubType() == OFSTBoolean)
          a[name] = f.GetFieldAsInteger(i) != 0;
        else
          a[name] = f.GetFieldAsInteger(i);
        break;
      case OFTInteger64:
        a[name] = static_cast<std::int64_t>(f.GetFieldAsInteger64(i));
        break;
      case OFTReal:
        a[name] = f.GetFieldAsDouble(i);
        break;
      default:
        a[name] = std::string(f.GetFieldAsString(i));
        break;
    }
  }
  return a;
}

std::string crs_code(const OGRSpatialReference& srs, int* epsg) {
  *epsg = 0;
  OGRSpatialReference s(srs);
  const char* auth = s.GetAuthorityName(nullptr);
  const char* code = s.GetAuthorityCode(nullptr);
  if (!(auth && code)) {
    if (s.AutoIdentifyEPSG() == OGRERR_NONE) {
      auth = s.GetAuthorityName(nullptr);
      code = s.GetAuthorityCode(nullptr);
    }
  }
  if (!(auth && code)) {
    // e.g. an ESRI .prj: ask PROJ for a single confident match
    int n = 0;
    int* conf = nullptr;
    OGRSpatialReferenceH* m = s.FindMatches(nullptr, &n, &conf);
    if (m && n >= 1 && conf[0] >= 90) {
      OGRSpatialReference* best = OGRSpatialReference::FromHandle(m[0]);
      const char* a2 = best->GetAuthorityName(nullptr);
      const char* c2 = best->GetAuthorityCode(nullptr);
      std::string r;
      if (a2 && c2 && std::string(a2) == "EPSG") {
        *epsg = std::atoi(c2);
        r = std::string("EPSG:") + c2;
      }
      OSRFreeSRSArray(m);
      CPLFree(conf);
      return r;
    }
    if (m) OSRFreeSRSArray(m);
    CPLFree(conf);
    return "";
  }
  if (std::string(auth) == "EPSG") *epsg = std::atoi(code);
  return std::string(auth) + ":" + code;
}

std::string wkt_of(const OGRSpatialReference& srs) {
  const char* opts[] = {"FORMAT=WKT2_2018", nullptr};
  char* w = nullptr;
  std::string s;
  if (srs.exportToWkt(&w, opts) == OGRERR_NONE && w) s = w;
  CPLFree(w);
  return s;
}

/// The layer to read: opt.layer, else the source's only one (an error naming the
/// layers when it has none or several).
OGRLayer* choose_layer(GDALDataset& ds, const FootprintReadOptions& opt,
                       const FootprintLayer& out) {
  OGRLayer* layer = nullptr;
  const std::vector<std::string> names = layer_names(ds);
  if (!opt.layer.empty()) {
    layer = ds.GetLayerByName(opt.layer.c_str());
    if (!layer)
      throw IoError(out.source, "has no layer '" + opt.layer + "' (layers: " +
                                    (names.empty() ? std::string("none") : join(names)) + ")");
  } else {
    if (names.empty()) throw IoError(out.source, "has no layers");
    if (names.size() > 1)
      throw IoError(out.source, "has " + std::to_string(names.size()) +
                                    " layers; choose one (--footprints-layer): " + join(names));
    layer = ds.GetLayer(0);
  }
  return layer;
}

/// Where a feature's id comes from: an attribute, or the OGR FID.
struct IdField {
  int field = -1;
  bool is_fid = true;
};

/// opt.id_attribute in the layer (its FID column too); an error listing the
/// attributes when it has none of that name.
IdField id_field_of(OGRLayer& layer, const FootprintReadOptions& opt, const FootprintLayer& out) {
  OGRFeatureDefn* defn = layer.GetLayerDefn();
  IdField id;
  id.is_fid = opt.id_attribute.empty();
  if (opt.id_attribute.empty()) return id;
  id.field = defn->GetFieldIndex(opt.id_attribute.c_str());
  if (id.field >= 0) return id;
  const std::string fidcol = layer.GetFIDColumn() ? layer.GetFIDColumn() : "";
  if (!fidcol.empty() && EQUAL(fidcol.c_str(), opt.id_attribute.c_str())) {
    id.is_fid = true;
    return id;
  }
  std::vector<std::string> fields;
  for (int i = 0; i < defn->GetFieldCount(); ++i)
    fields.emplace_back(defn->GetFieldDefn(i)->GetNameRef());
  throw IoError(out.source, "layer '" + out.layer + "' has no attribute '" + opt.id_attribute +
                                "' for the footprint ids (attributes: " +
                                (fields.empty() ? std::string("none") : join(fields, 40)) + ")");
}

/// The CRS of the source (out.crs, crs_wkt, crs_epsg), and the reprojection into
/// opt.target_crs (null when none is asked for); `target` holds the target CRS.
std::unique_ptr<OGRCoordinateTransformation> reprojection(OGRLayer& layer,
                                                          const FootprintReadOptions& opt,
                                                          OGRSpatialReference& target,
                                                          FootprintLayer& out) {
  const OGRSpatialReference* src_srs = layer.GetSpatialRef();
  std::unique_ptr<OGRCoordinateTransformation> ct;
  if (!opt.target_crs.empty()) {
    if (!src_srs)
      throw IoError(out.source, "layer '" + out.layer + "' has no CRS; cannot reproject it to " +
                                    opt.target_crs);
    QuietGdal quiet;
    if (target.SetFromUserInput(opt.target_crs.c_str()) != OGRERR_NONE)
      throw IoError(out.source, "unknown target CRS '" + opt.target_crs + "'");
    target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    OGRSpatialReference s(*src_srs);
    s.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    ct.reset(OGRCreateCoordinateTransformation(&s, &target));
    if (!ct)
      throw IoError(out.source, "no transformation from the layer's CRS to " + opt.target_crs +
                                    ": " + quiet.take_last());
    out.crs = crs_code(target, &out.crs_epsg);
    out.crs_wkt = wkt_of(target);
  } else if (src_srs) {
    out.crs = crs_code(*src_srs, &out.crs_epsg);
    out.crs_wkt = wkt_of(*src_srs);
  }
  if (out.crs.empty()) out.crs = out.crs_wkt;
  return ct;
}

/// A feature's id: its id attribute, or its FID (when the attribute is NULL: with a
/// problem line).
std::string feature_id(OGRFeature& f, const IdField& id, const FootprintReadOptions& opt,
                       FootprintLayer& out) {
  const std::int64_t fid = f.GetFID();
  if (id.is_fid) return std::to_string(fid);
  if (!f.IsFieldSetAndNotNull(id.field)) {
    out.problems.push_back("feature " + std::to_string(fid) + ": attribute '" + opt.id_attribute +
                           "' is NULL; its FID is the id");
    return std::to_string(fid);
  }
  return f.GetFieldAsString(id.field);
}

/// A feature's geometry as linear 2D polygons in the target CRS; null, with `why`,
/// when it has none.
std::unique_ptr<OGRGeometry> feature_geometry(OGRFeature& f, OGRCoordinateTransformation* ct,
                                              const FootprintReadOptions& opt, std::string& why) {
  const OGRGeometry* g0 = f.GetGeometryRef();
  if (!g0 || g0->IsEmpty()) {
    why = "no geometry";
    return nullptr;
  }
  std::unique_ptr<OGRGeometry> g(g0->hasCurveGeometry() ? g0->getLinearGeometry() : g0->clone());
  if (!g) {
    why = "geometry not convertible to polygons";
    return nullptr;
  }
  g->flattenTo2D();
  if (ct && g->transform(ct) != OGRERR_NONE) {
    why = "cannot be reprojected to " + opt.target_crs;
    return nullptr;
  }
  return g;
}

/// A feature's polygons cleaned; the ones GEOS calls invalid tested and repaired.
struct CleanParts {
  std::vector<std::vector<Ring>> parts;
  int dropped_holes = 0, degenerate = 0;
  bool repaired = false, unrepairable = false;
  std::string repair_note;
};

CleanParts clean_polygons(const std::vector<const OGRPolygon*>& polys, bool can_repair,
                          QuietGdal& quiet) {
  CleanParts c;
  for (const OGRPolygon* p : polys) {
    const bool geos = footprint_repair_available();
    std::vector<Ring> rings = polygon_rings(*p, &c.dropped_holes, !geos);
    if (rings.empty()) {
      ++c.degenerate;
      continue;
    }
    if (!geos) {
      c.parts.push_back(std::move(rings));
      continue;
    }
    std::unique_ptr<OGRPolygon> clean = to_ogr(rings);
    const std::size_t mark = quiet.messages.size();
    if (clean->IsValid() && has_area(rings[0])) {
      c.parts.push_back(std::move(rings));
      continue;
    }
    std::string reason = quiet.take_last(mark);
    if (reason.empty()) reason = "invalid polygon";
    if (!can_repair) {
      c.repair_note = reason;
      ++c.degenerate;
      continue;
    }
    std::unique_ptr<OGRGeometry> fixed(clean->MakeValid());
    quiet.take_last(mark);
    std::vector<const OGRPolygon*> fixed_polys;
    std::string ignored;
    if (fixed) collect_polygons(fixed.get(), fixed_polys, ignored);
    std::size_t got = 0;
    for (const OGRPolygon* fp : fixed_polys) {
      std::vector<Ring> r = polygon_rings(*fp, &c.dropped_holes);
      if (!r.empty()) {
        c.parts.push_back(std::move(r));
        ++got;
      }
    }
    if (got == 0) {
      c.repair_note = reason;
      c.unrepairable = true;
      ++c.degenerate;
      continue;
    }
    c.repaired = true;
    c.repair_note = "invalid polygon (" + reason + "), repaired into " + std::to_string(got) +
                    (got == 1 ? " polygon" : " polygons");
  }
  return c;
}

/// The layer's reading state: what every feature is read with.
struct FeatureReader {
  IdField id;
  OGRCoordinateTransformation* ct = nullptr;
  bool can_repair = false;
  const FootprintReadOptions* opt = nullptr;
  QuietGdal* quiet = nullptr;
};

/// One source feature: its parts into out.features, or a problem line saying why not.
void read_feature(OGRFeature& f, const FeatureReader& r, FootprintLayer& out) {
  const FootprintReadOptions& opt = *r.opt;
  const std::int64_t fid = f.GetFID();
  const std::string sid = feature_id(f, r.id, opt, out);
  const std::string who = "feature " + std::to_string(fid) + (r.id.is_fid ? "" : " (" + sid + ")");
  auto skip = [&](const std::string& why) {
    ++out.skipped;
    out.problems.push_back(who + ": " + why + "; skipped");
  };

  std::string why;
  const std::unique_ptr<OGRGeometry> g = feature_geometry(f, r.ct, opt, why);
  if (!g) return skip(why);
  std::vector<const OGRPolygon*> polys;
  std::string other;
  collect_polygons(g.get(), polys, other);
  if (polys.empty())
    return skip("not a polygon (" + (other.empty() ? std::string("empty") : other) + ")");

  CleanParts c = clean_polygons(polys, r.can_repair, *r.quiet);
  if (c.parts.empty()) {
    why = "zero area";
    if (!c.repair_note.empty()) {
      why = "invalid polygon (" + c.repair_note + ")";
      if (c.unrepairable) why += ", not repairable";
      if (!r.can_repair) why += opt.repair ? ", and GEOS is not available" : ", repair off";
    }
    return skip(why);
  }
  if (c.repaired) {
    ++out.repaired;
    out.problems.push_back(who + ": " + c.repair_note);
  }
  if (c.degenerate > 0 && !c.repaired)
    out.problems.push_back(who + ": " + std::to_string(c.degenerate) +
                           " zero-area or invalid polygon part(s) dropped");
  if (c.dropped_holes > 0)
    out.problems.push_back(who + ": " + std::to_string(c.dropped_holes) +
                           " zero-area hole(s) dropped");

  const nlohmann::json attrs = attributes_of(f);
  for (std::size_t k = 0; k < c.parts.size(); ++k) {
    FootprintFeature ff;
    ff.source_id = sid;
    ff.part = static_cast<int>(k);
    ff.id = k == 0 ? sid : sid + "-" + std::to_string(k);
    ff.fid = fid;
    ff.rings = std::move(c.parts[k]);
    ff.attributes = attrs;
    ff.repaired = c.repaired;
    out.features.push_back(std::move(ff));
  }
}

}  // namespace

bool footprint_repair_available() {
  return OGRGeometryFactory::haveGEOS();
}

std::string footprint_reader_version() {
  return std::string("GDAL ") + GDALVersionInfo("RELEASE_NAME") + ", GEOS " +
         (footprint_repair_available() ? "yes" : "no");
}

std::vector<std::string> footprint_layers(const std::string& source) {
  const std::string shown = mask_source(source);
  DatasetPtr ds = open_source(source, shown);
  return layer_names(*ds);
}

FootprintLayer read_footprints(const std::string& source, const FootprintReadOptions& opt) {
  FootprintLayer out;
  out.source = mask_source(source);
  DatasetPtr ds = open_source(source, out.source);
  out.driver = ds->GetDriver() ? ds->GetDriver()->GetDescription() : "";
  OGRLayer* layer = choose_layer(*ds, opt, out);
  out.layer = layer->GetName();
  FeatureReader r;
  r.id = id_field_of(*layer, opt, out);
  OGRSpatialReference target;
  const std::unique_ptr<OGRCoordinateTransformation> ct = reprojection(*layer, opt, target, out);
  r.ct = ct.get();
  r.can_repair = opt.repair && footprint_repair_available();
  r.opt = &opt;
  QuietGdal quiet;
  r.quiet = &quiet;
  layer->ResetReading();
  // A read error ends the layer like its last feature does: the error state
  // tells them apart (a damaged file read as a short one drops buildings
  // silently, issue 27).
  auto next_feature = [&]() {
    CPLErrorReset();
    OGRFeatureUniquePtr f(layer->GetNextFeature());
    if (!f && CPLGetLastErrorType() >= CE_Failure)
      throw IoError(out.source,
                    "reading stopped after feature " + std::to_string(out.source_features) +
                        " of layer '" + std::string(layer->GetName()) +
                        "': " + std::string(CPLGetLastErrorMsg()) + " (the file is damaged?)");
    return f;
  };
  for (OGRFeatureUniquePtr f = next_feature(); f; f = next_feature()) {
    ++out.source_features;
    read_feature(*f, r, out);
  }
  return out;
}

}  // namespace citylod::io
