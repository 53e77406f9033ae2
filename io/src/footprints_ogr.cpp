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

  OGRLayer* layer = nullptr;
  const std::vector<std::string> names = layer_names(*ds);
  if (!opt.layer.empty()) {
    layer = ds->GetLayerByName(opt.layer.c_str());
    if (!layer)
      throw IoError(out.source, "has no layer '" + opt.layer + "' (layers: " +
                                    (names.empty() ? std::string("none") : join(names)) + ")");
  } else {
    if (names.empty()) throw IoError(out.source, "has no layers");
    if (names.size() > 1)
      throw IoError(out.source, "has " + std::to_string(names.size()) +
                                    " layers; choose one (--footprints-layer): " + join(names));
    layer = ds->GetLayer(0);
  }
  out.layer = layer->GetName();

  OGRFeatureDefn* defn = layer->GetLayerDefn();
  int id_field = -1;
  bool id_is_fid = opt.id_attribute.empty();
  if (!opt.id_attribute.empty()) {
    id_field = defn->GetFieldIndex(opt.id_attribute.c_str());
    if (id_field < 0) {
      const std::string fidcol = layer->GetFIDColumn() ? layer->GetFIDColumn() : "";
      if (!fidcol.empty() && EQUAL(fidcol.c_str(), opt.id_attribute.c_str())) {
        id_is_fid = true;
      } else {
        std::vector<std::string> fields;
        for (int i = 0; i < defn->GetFieldCount(); ++i)
          fields.emplace_back(defn->GetFieldDefn(i)->GetNameRef());
        throw IoError(out.source, "layer '" + out.layer + "' has no attribute '" +
                                      opt.id_attribute + "' for the footprint ids (attributes: " +
                                      (fields.empty() ? std::string("none") : join(fields, 40)) +
                                      ")");
      }
    }
  }

  // CRS of the source, and the reprojection
  const OGRSpatialReference* src_srs = layer->GetSpatialRef();
  std::unique_ptr<OGRCoordinateTransformation> ct;
  OGRSpatialReference target;
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

  const bool can_repair = opt.repair && footprint_repair_available();
  QuietGdal quiet;
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
    const std::int64_t fid = f->GetFID();
    std::string sid;
    if (id_is_fid) {
      sid = std::to_string(fid);
    } else if (!f->IsFieldSetAndNotNull(id_field)) {
      sid = std::to_string(fid);
      out.problems.push_back("feature " + std::to_string(fid) + ": attribute '" + opt.id_attribute +
                             "' is NULL; its FID is the id");
    } else {
      sid = f->GetFieldAsString(id_field);
    }
    const std::string who = "feature " + std::to_string(fid) + (id_is_fid ? "" : " (" + sid + ")");
    auto skip = [&](const std::string& why) {
      ++out.skipped;
      out.problems.push_back(who + ": " + why + "; skipped");
    };

    const OGRGeometry* g0 = f->GetGeometryRef();
    if (!g0 || g0->IsEmpty()) {
      skip("no geometry");
      continue;
    }
    std::unique_ptr<OGRGeometry> g(g0->hasCurveGeometry() ? g0->getLinearGeometry() : g0->clone());
    if (!g) {
      skip("geometry not convertible to polygons");
      continue;
    }
    g->flattenTo2D();
    if (ct && g->transform(ct.get()) != OGRERR_NONE) {
      skip("cannot be reprojected to " + opt.target_crs);
      continue;
    }
    std::vector<const OGRPolygon*> polys;
    std::string other;
    collect_polygons(g.get(), polys, other);
    if (polys.empty()) {
      skip("not a polygon (" + (other.empty() ? std::string("empty") : other) + ")");
      continue;
    }

    // clean every polygon; test and repair the ones GEOS calls invalid
    std::vector<std::vector<Ring>> parts;
    int dropped_holes = 0, degenerate = 0;
    bool repaired = false, unrepairable = false;
    std::string repair_note;
    for (const OGRPolygon* p : polys) {
      const bool geos = footprint_repair_available();
      std::vector<Ring> rings = polygon_rings(*p, &dropped_holes, !geos);
      if (rings.empty()) {
        ++degenerate;
        continue;
      }
      if (!geos) {
        parts.push_back(std::move(rings));
        continue;
      }
      std::unique_ptr<OGRPolygon> clean = to_ogr(rings);
      const std::size_t mark = quiet.messages.size();
      if (clean->IsValid() && has_area(rings[0])) {
        parts.push_back(std::move(rings));
        continue;
      }
      std::string reason = quiet.take_last(mark);
      if (reason.empty()) reason = "invalid polygon";
      if (!can_repair) {
        repair_note = reason;
        ++degenerate;
        continue;
      }
      std::unique_ptr<OGRGeometry> fixed(clean->MakeValid());
      quiet.take_last(mark);
      std::vector<const OGRPolygon*> fixed_polys;
      std::string ignored;
      if (fixed) collect_polygons(fixed.get(), fixed_polys, ignored);
      std::size_t got = 0;
      for (const OGRPolygon* fp : fixed_polys) {
        std::vector<Ring> r = polygon_rings(*fp, &dropped_holes);
        if (!r.empty()) {
          parts.push_back(std::move(r));
          ++got;
        }
      }
      if (got == 0) {
        repair_note = reason;
        unrepairable = true;
        ++degenerate;
        continue;
      }
      repaired = true;
      repair_note = "invalid polygon (" + reason + "), repaired into " + std::to_string(got) +
                    (got == 1 ? " polygon" : " polygons");
    }
    if (parts.empty()) {
      std::string why = "zero area";
      if (!repair_note.empty()) {
        why = "invalid polygon (" + repair_note + ")";
        if (unrepairable) why += ", not repairable";
        if (!can_repair) why += opt.repair ? ", and GEOS is not available" : ", repair off";
      }
      skip(why);
      continue;
    }
    if (repaired) {
      ++out.repaired;
      out.problems.push_back(who + ": " + repair_note);
    }
    if (degenerate > 0 && !repaired)
      out.problems.push_back(who + ": " + std::to_string(degenerate) +
                             " zero-area or invalid polygon part(s) dropped");
    if (dropped_holes > 0)
      out.problems.push_back(who + ": " + std::to_string(dropped_holes) +
                             " zero-area hole(s) dropped");

    const nlohmann::json attrs = attributes_of(*f);
    for (std::size_t k = 0; k < parts.size(); ++k) {
      FootprintFeature ff;
      ff.source_id = sid;
      ff.part = static_cast<int>(k);
      ff.id = k == 0 ? sid : sid + "-" + std::to_string(k);
      ff.fid = fid;
      ff.rings = std::move(parts[k]);
      ff.attributes = attrs;
      ff.repaired = repaired;
      out.features.push_back(std::move(ff));
    }
  }
  return out;
}

}  // namespace citylod::io
