// One owning handle for a GEOS geometry of one context (destroyed unless
// released), for the clean stage's files.
#pragma once

#include <geos_c.h>

#include <utility>

namespace prep::detail {

class GeosGeom {
 public:
  GeosGeom() = default;
  GeosGeom(GEOSContextHandle_t h, GEOSGeometry* g) : h_(h), g_(g) {}
  GeosGeom(GeosGeom&& o) noexcept : h_(o.h_), g_(o.g_) { o.g_ = nullptr; }
  GeosGeom& operator=(GeosGeom&& o) noexcept {
    std::swap(h_, o.h_);
    std::swap(g_, o.g_);
    return *this;
  }
  GeosGeom(const GeosGeom&) = delete;
  GeosGeom& operator=(const GeosGeom&) = delete;
  ~GeosGeom() {
    if (g_) GEOSGeom_destroy_r(h_, g_);
  }
  GEOSGeometry* get() const { return g_; }
  GEOSGeometry* release() { return std::exchange(g_, nullptr); }
  explicit operator bool() const { return g_ != nullptr; }

 private:
  GEOSContextHandle_t h_ = nullptr;
  GEOSGeometry* g_ = nullptr;
};

}  // namespace prep::detail
