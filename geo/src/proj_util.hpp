// Internal PROJ helpers of citylod::geo (RAII for contexts and objects, error capture).
#pragma once

#include "citylod/geo/crs.hpp"

#include <proj.h>

#include <memory>
#include <string>

namespace citylod::geo::detail {

struct PjDeleter {
  void operator()(PJ* p) const { proj_destroy(p); }
};
using PjPtr = std::unique_ptr<PJ, PjDeleter>;

/// One PROJ context whose log goes into `last_error` instead of stderr.
class Context {
 public:
  Context();
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  PJ_CONTEXT* get() const { return ctx_; }
  /// Last PROJ error message, or the errno string, or "unknown PROJ error"; then clears it.
  std::string take_error(const PJ* p = nullptr);
  void clear() { last_error_.clear(); }

 private:
  static void log(void* self, int level, const char* msg);
  PJ_CONTEXT* ctx_ = nullptr;
  std::string last_error_;
};

/// Parses a CRS definition (as in Crs::definition()) in `ctx`; throws GeoError.
PjPtr create_crs(Context& ctx, const std::string& definition, const std::string& spec_for_errors);

/// Horizontal (first) component of a compound CRS, or a clone of `crs` otherwise.
PjPtr horizontal_part(Context& ctx, const PJ* crs);

/// `crs` with its x/y read in `unit` (the Crs is rebuilt through PROJ).
Crs with_horizontal_unit(const Crs& crs, const Unit& unit);

/// Compact "%.*g" for messages, locale-independent.
std::string fmt(double v, int digits = 10);

}  // namespace citylod::geo::detail
