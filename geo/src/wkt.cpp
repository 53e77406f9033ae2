// summarize_wkt() (wkt.hpp): a structural reading of WKT 1 / 2 — the
// keywords, names, AUTHORITY/ID and UNIT nodes — that also summarises the
// incomplete WKT found in LAS files (PROJ refuses e.g. a PROJCS without its
// PROJECTION/CONVERSION, see tests/io/test_las.cpp). CRSes used for
// computation are parsed by PROJ (Crs::parse).
#include "citylod/geo/wkt.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string_view>
#include <system_error>
#include <vector>

namespace citylod::geo {
namespace {

/// A whole number token ("+" allowed), locale-independent.
template <class T>
bool parse_number(std::string_view s, T& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return !s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size();
}

struct Node {
  std::string keyword;
  std::vector<std::string> values;  // quoted strings and numbers, in order
  std::vector<std::unique_ptr<Node>> children;
};

class Parser {
 public:
  explicit Parser(const std::string& s) : s_(s) {}
  std::unique_ptr<Node> parse(int depth = 0) {
    if (depth > 32) return nullptr;
    skip();
    auto n = std::make_unique<Node>();
    while (i_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[i_])) || s_[i_] == '_'))
      n->keyword += s_[i_++];
    skip();
    if (n->keyword.empty() || i_ >= s_.size() || (s_[i_] != '[' && s_[i_] != '(')) return nullptr;
    const char close = s_[i_] == '[' ? ']' : ')';
    ++i_;
    for (;;) {
      skip();
      if (i_ >= s_.size()) return nullptr;
      char c = s_[i_];
      if (c == close) {
        ++i_;
        return n;
      }
      if (c == ',') {
        ++i_;
        continue;
      }
      if (c == '"') {
        std::string v;
        ++i_;
        while (i_ < s_.size()) {
          if (s_[i_] == '"') {
            if (i_ + 1 < s_.size() && s_[i_ + 1] == '"') {
              v += '"';
              i_ += 2;
              continue;
            }
            break;
          }
          v += s_[i_++];
        }
        ++i_;
        n->values.push_back(v);
      } else if (std::isalpha(static_cast<unsigned char>(c))) {
        std::size_t save = i_;
        auto child = parse(depth + 1);
        if (child) {
          n->children.push_back(std::move(child));
        } else {
          // Bare enumerations like "north" in AXIS["X",EAST]
          i_ = save;
          std::string v;
          while (i_ < s_.size() && s_[i_] != ',' && s_[i_] != close) v += s_[i_++];
          n->values.push_back(v);
        }
      } else {
        std::string v;
        while (i_ < s_.size() && s_[i_] != ',' && s_[i_] != close) v += s_[i_++];
        n->values.push_back(v);
      }
    }
  }

 private:
  void skip() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  const std::string& s_;
  std::size_t i_ = 0;
};

bool is(const Node& n, std::initializer_list<const char*> kws) {
  for (const char* k : kws)
    if (n.keyword == k) return true;
  return false;
}

const Node* child(const Node& n, std::initializer_list<const char*> kws) {
  for (const auto& c : n.children)
    if (is(*c, kws)) return c.get();
  return nullptr;
}

int epsg_of(const Node& n) {
  const Node* a = child(n, {"AUTHORITY", "ID"});
  if (a && a->values.size() >= 2 && a->values[0] == "EPSG") {
    std::int64_t v = 0;
    if (parse_number(a->values[1], v) && v > 0 && v < 1000000) return static_cast<int>(v);
  }
  return 0;
}

void unit_of(const Node& crs, WktSummary& out) {
  const Node* u = child(crs, {"UNIT", "LENGTHUNIT"});
  if (!u) {
    if (const Node* cs = child(crs, {"CS"})) u = child(*cs, {"UNIT", "LENGTHUNIT"});
  }
  if (!u) {
    for (const auto& c : crs.children)
      if (c->keyword == "AXIS")
        if ((u = child(*c, {"LENGTHUNIT", "UNIT"}))) break;
  }
  if (!u || u->values.size() < 2) return;
  double f = 0;
  if (!parse_number(u->values[1], f)) return;
  out.unit_m = f;
  if (std::abs(f - 1.0) < 1e-12)
    out.unit = "metre";
  else if (std::abs(f - 0.3048) < 1e-12)
    out.unit = "foot";
  else if (std::abs(f - 1200.0 / 3937.0) < 1e-12)
    out.unit = "US survey foot";
  else
    out.unit = u->values[0];
}

}  // namespace

WktSummary summarize_wkt(const std::string& wkt) {
  WktSummary out;
  if (wkt.empty()) return out;
  Parser p(wkt);
  std::unique_ptr<Node> root = p.parse();
  if (!root) return out;
  const Node* horiz = root.get();
  if (is(*root, {"COMPD_CS", "COMPOUNDCRS"})) {
    horiz = nullptr;
    for (const auto& c : root->children) {
      if (!horiz &&
          is(*c, {"PROJCS", "GEOGCS", "PROJCRS", "GEOGCRS", "GEODCRS", "PROJECTEDCRS", "GEOCCS"}))
        horiz = c.get();
      if (is(*c, {"VERT_CS", "VERTCRS", "VERTICALCRS"})) out.vertical_epsg = epsg_of(*c);
    }
    if (!horiz) horiz = root.get();
  }
  if (!horiz->values.empty()) out.name = horiz->values[0];
  out.epsg = epsg_of(*horiz);
  if (!is(*horiz, {"GEOGCS", "GEOGCRS"})) unit_of(*horiz, out);
  return out;
}

}  // namespace citylod::geo
