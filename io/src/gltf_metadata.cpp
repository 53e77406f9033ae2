// glb writer, EXT_structural_metadata: the schema (class "building": our
// properties and the source attributes, typed once per tileset) and the
// property table, one column of bufferViews per property.
#include <algorithm>
#include <cctype>
#include <limits>
#include <map>
#include <set>

#include "citylod/io/error.hpp"
#include "citylod/io/gltf.hpp"
#include "gltf_internal.hpp"

namespace citylod::io {

namespace detail {

namespace {

/// A STRING attribute's text: strings as they are, other JSON values as JSON
/// text, a missing one (nullptr) as the noData string NUL (see schema_json).
std::string attribute_text(const nlohmann::json* v) {
  return !v ? std::string(1, '\0') : v->is_string() ? v->get<std::string>() : v->dump();
}

/// The columns of a property table, each one bufferView (STRING: two) of `w`.
struct Columns {
  BinWriter& w;
  Value::Object props;

  void column(const char* name, const void* p, std::size_t bytes) {
    props[name] = obj({{"values", Value(w.view(p, bytes, 0))}});
  }
  /// STRING: offsets as UINT16 when the characters allow it (UINT32 otherwise)
  void string_column(const char* name, std::string chars, const std::vector<std::uint32_t>& offs) {
    Value::Object o;
    const bool small = offs.back() <= 0xFFFF;
    if (chars.empty()) chars.push_back('\0');  // a bufferView needs byteLength >= 1
    o["values"] = Value(w.view(chars.data(), chars.size(), 0));
    if (small) {
      const std::vector<std::uint16_t> o16(offs.begin(), offs.end());
      o["stringOffsets"] = Value(w.view(o16.data(), o16.size() * 2, 0));
      o["stringOffsetType"] = str("UINT16");
    } else {
      o["stringOffsets"] = Value(w.view(offs.data(), offs.size() * 4, 0));  // default UINT32
    }
    props[name] = obj(std::move(o));
  }
};

/// The column of a source attribute (GlbOptions::attributes), typed.
void attribute_column(Columns& columns, const GlbAttribute& a,
                      const std::vector<GlbFeature>& features) {
  const std::size_t n = features.size();
  auto value_of = [&](const GlbFeature& f) -> const nlohmann::json* {
    if (!f.attributes.is_object()) return nullptr;
    const auto it = f.attributes.find(a.name);
    return it == f.attributes.end() || it->is_null() ? nullptr : &*it;
  };
  switch (a.type) {
    case GlbAttribute::Type::int64: {
      std::vector<std::int64_t> v;
      for (const auto& f : features) {
        const nlohmann::json* j = value_of(f);
        v.push_back(j && j->is_number_integer() ? j->get<std::int64_t>() : 0);
      }
      columns.column(a.property.c_str(), v.data(), n * 8);
      break;
    }
    case GlbAttribute::Type::float64: {
      const double none = std::numeric_limits<double>::lowest();
      std::vector<double> v;
      for (const auto& f : features) {
        const nlohmann::json* j = value_of(f);
        v.push_back(j && j->is_number() ? j->get<double>() : none);
      }
      columns.column(a.property.c_str(), v.data(), n * 8);
      break;
    }
    case GlbAttribute::Type::boolean: {
      std::vector<std::uint8_t> bits((n + 7) / 8, 0);
      for (std::size_t i = 0; i < n; ++i) {
        const nlohmann::json* j = value_of(features[i]);
        if (j && j->is_boolean() && j->get<bool>()) bits[i / 8] |= std::uint8_t(1u << (i % 8));
      }
      columns.column(a.property.c_str(), bits.data(), bits.size());
      break;
    }
    case GlbAttribute::Type::string: {
      if (!a.enum_values.empty()) {  // ENUM (UINT8): the index of the value
        std::vector<std::uint8_t> v;
        for (const auto& f : features) {
          const std::string text = attribute_text(value_of(f));
          const auto it = std::lower_bound(a.enum_values.begin(), a.enum_values.end(), text);
          if (it == a.enum_values.end() || *it != text)
            throw IoError(kWhere, "attribute '" + a.name + "': value '" + text +
                                      "' is not one of the schema's");
          v.push_back(std::uint8_t(it - a.enum_values.begin()));
        }
        columns.column(a.property.c_str(), v.data(), n);
        break;
      }
      std::string chars;
      std::vector<std::uint32_t> offs{0};
      for (const auto& f : features) {
        chars += attribute_text(value_of(f));
        offs.push_back(std::uint32_t(chars.size()));
      }
      columns.string_column(a.property.c_str(), chars, offs);
      break;
    }
  }
}

}  // namespace

nlohmann::json schema_json(const std::vector<GlbAttribute>& attributes) {
  using J = nlohmann::json;
  auto prop = [](const char* type, const char* component, const char* description) {
    J o{{"type", type}, {"description", description}};
    if (component) o["componentType"] = component;
    return o;
  };
  J props{
      {"building_id", prop("STRING", nullptr, "building (chunk) id of the work directory")},
      {"lod_kind",
       {{"type", "ENUM"},
        {"enumType", "LodKind"},
        {"description", "anchor or interpolation model of the LOD-Tree, or the fallback outline"}}},
      {"level", prop("SCALAR", "INT32", "LOD-Tree level set of the model")},
      {"step", prop("SCALAR", "INT32", "traversal step that produced the model")},
      {"model_index", prop("SCALAR", "INT32", "index in the building's kept models, 0 = coarsest")},
      {"model_count", prop("SCALAR", "INT32", "number of kept models of the building")},
      {"height", prop("SCALAR", "FLOAT32", "vertical extent of the model, metres")},
      {"footprint_area",
       prop("SCALAR", "FLOAT32", "footprint area of the building, square metres")},
      {"geometric_error", prop("SCALAR", "FLOAT32", "distance to the finest model, metres")},
      {"rmse",
       {{"type", "SCALAR"},
        {"componentType", "FLOAT32"},
        {"noData", -1.0},
        {"description",
         "RMSE of the building's input points to the model, metres (-1: not measured)"}}},
      {"valid", prop("BOOLEAN", nullptr,
                     "the model is a valid solid: closed, oriented, no pinched vertex, one outer "
                     "shell, no self-intersection")},
  };
  J values = J::array();
  for (lod::ModelKind k :
       {lod::ModelKind::anchor, lod::ModelKind::interpolation, lod::ModelKind::fallback})
    values.push_back(J{{"name", lod::to_string(k)}, {"value", int(k)}});
  J enums{{"LodKind", {{"valueType", "UINT8"}, {"values", values}}}};
  for (const GlbAttribute& a : attributes) {
    J def{{"name", a.name}, {"description", "footprint attribute"}};
    switch (a.type) {
      case GlbAttribute::Type::int64:
        def["type"] = "SCALAR";
        def["componentType"] = "INT64";
        break;
      case GlbAttribute::Type::float64:
        def["type"] = "SCALAR";
        def["componentType"] = "FLOAT64";
        if (a.no_data) def["noData"] = std::numeric_limits<double>::lowest();
        break;
      case GlbAttribute::Type::boolean:
        def["type"] = "BOOLEAN";
        break;
      case GlbAttribute::Type::string:
        if (!a.enum_values.empty()) {
          def["type"] = "ENUM";
          def["enumType"] = a.property;
          J vs = J::array();
          for (std::size_t i = 0; i < a.enum_values.size(); ++i)
            vs.push_back({{"name", a.enum_values[i]}, {"value", i}});
          enums[a.property] = {{"valueType", "UINT8"}, {"values", vs}};
          if (a.no_data) def["noData"] = std::string(1, '\0');
          break;
        }
        def["type"] = "STRING";
        // A missing value is the one-character string NUL, never a source value
        // (GDAL strings are C strings); "" would leave a column of missing
        // values without characters, which a bufferView cannot hold.
        if (a.no_data) def["noData"] = std::string(1, '\0');
        break;
    }
    props[a.property] = std::move(def);
  }
  return {{"id", "citylod"},
          {"classes", {{"building", {{"name", "Building LOD model"}, {"properties", props}}}}},
          {"enums", enums}};
}

void put_schema(nlohmann::ordered_json& j, const nlohmann::json& schema,
                const std::string& schema_uri) {
  auto& meta = j["extensions"]["EXT_structural_metadata"];
  nlohmann::ordered_json m;
  if (schema_uri.empty())
    m["schema"] = nlohmann::ordered_json::parse(schema.dump());
  else
    m["schemaUri"] = schema_uri;
  for (auto& [k, v] : meta.items()) m[k] = v;
  meta = std::move(m);
}

Value::Object property_table(BinWriter& w, const std::vector<GlbFeature>& features,
                             const std::vector<GlbAttribute>& attributes) {
  const std::size_t n = features.size();
  std::string ids;
  std::vector<std::uint32_t> offsets{0};
  std::vector<std::uint8_t> kind;
  std::vector<std::int32_t> level, step, index, count;
  std::vector<float> height, area, error, rmse;
  std::vector<std::uint8_t> valid((n + 7) / 8, 0);  // BOOLEAN: a bitstream, LSB first
  for (std::size_t i = 0; i < n; ++i) {
    const GlbFeature& f = features[i];
    if (f.valid) valid[i / 8] |= std::uint8_t(1u << (i % 8));
    rmse.push_back(f.rmse_m >= 0 ? float(f.rmse_m) : -1.0f);
    ids += f.building_id;
    offsets.push_back(std::uint32_t(ids.size()));
    kind.push_back(std::uint8_t(f.kind));
    level.push_back(f.level);
    step.push_back(f.step);
    index.push_back(f.model_index);
    count.push_back(f.model_count);
    height.push_back(float(f.height_m));
    area.push_back(float(f.footprint_area_m2));
    error.push_back(float(f.error_m));
  }
  Columns columns{w, {}};
  columns.string_column("building_id", ids, offsets);
  columns.column("lod_kind", kind.data(), n);
  columns.column("level", level.data(), n * 4);
  columns.column("step", step.data(), n * 4);
  columns.column("model_index", index.data(), n * 4);
  columns.column("model_count", count.data(), n * 4);
  columns.column("height", height.data(), n * 4);
  columns.column("footprint_area", area.data(), n * 4);
  columns.column("geometric_error", error.data(), n * 4);
  for (const GlbAttribute& a : attributes) attribute_column(columns, a, features);
  columns.column("rmse", rmse.data(), n * 4);
  if (valid.empty()) valid.push_back(0);
  columns.column("valid", valid.data(), valid.size());
  return {{"class", str("building")}, {"count", Value(int(n))}, {"properties", obj(columns.props)}};
}

}  // namespace detail

std::vector<GlbAttribute> glb_attribute_schema(const std::vector<const nlohmann::json*>& objects) {
  struct Seen {
    std::size_t null = 0, boolean = 0, integer = 0, real = 0, other = 0;
    bool big = false;  // an integer beyond 2^53 (not exact as a double)
  };
  std::map<std::string, Seen> seen;
  for (const nlohmann::json* o : objects)
    if (o && o->is_object())
      for (const auto& [k, v] : o->items()) seen[k];
  for (auto& [name, s] : seen)
    for (const nlohmann::json* o : objects) {
      const nlohmann::json* v = nullptr;
      if (o && o->is_object()) {
        const auto it = o->find(name);
        if (it != o->end()) v = &*it;
      }
      if (!v || v->is_null())
        ++s.null;
      else if (v->is_boolean())
        ++s.boolean;
      else if (v->is_number_integer()) {
        ++s.integer;
        const std::int64_t lim = std::int64_t(1) << 53;
        if (v->is_number_unsigned())
          s.big = s.big || v->get<std::uint64_t>() > std::uint64_t(lim);
        else
          s.big = s.big || v->get<std::int64_t>() > lim || v->get<std::int64_t>() < -lim;
      } else if (v->is_number())
        ++s.real;
      else
        ++s.other;
    }
  std::vector<GlbAttribute> out;
  std::set<std::string> ids;
  for (const auto& [name, s] : seen) {
    GlbAttribute a;
    a.name = name;
    const std::size_t numbers = s.integer + s.real;
    if (s.other == 0 && s.boolean == 0 && numbers > 0) {
      if (s.real == 0 && s.null == 0)
        a.type = GlbAttribute::Type::int64;
      else
        a.type = s.big ? GlbAttribute::Type::string : GlbAttribute::Type::float64;
    } else if (s.other == 0 && numbers == 0 && s.boolean > 0 && s.null == 0) {
      a.type = GlbAttribute::Type::boolean;
    }
    a.no_data = s.null > 0;
    if (a.type == GlbAttribute::Type::string) {
      std::set<std::string> distinct;  // a missing value: the noData string NUL
      for (const nlohmann::json* o : objects) {
        const nlohmann::json* v = nullptr;
        if (o && o->is_object()) {
          const auto it = o->find(name);
          if (it != o->end() && !it->is_null()) v = &*it;
        }
        distinct.insert(detail::attribute_text(v));
        if (distinct.size() > 255) break;
      }
      if (distinct.size() <= 255 &&
          (distinct.size() == 1 || distinct.size() * 4 <= objects.size() * 3))
        a.enum_values.assign(distinct.begin(), distinct.end());
    }
    std::string id = "fp_";
    for (char c : name) id += (std::isalnum(static_cast<unsigned char>(c)) || c == '_') ? c : '_';
    std::string unique = id;
    for (int k = 2; !ids.insert(unique).second; ++k) unique = id + "_" + std::to_string(k);
    a.property = unique;
    out.push_back(std::move(a));
  }
  return out;
}

std::string glb_schema(const GlbOptions& options) {
  return detail::schema_json(options.attributes).dump();
}

}  // namespace citylod::io
