// geos_handle.hpp — the GEOS context and geometry handles that clean and
// tile share: one owning context per thread (GEOS _r API) that keeps the
// last error message GEOS reported, one owning handle for a GEOS geometry of
// a context (destroyed unless released), and the small GEOS helpers the
// clean stage's files share (prepared geometries, STR trees, envelopes,
// building and taking apart collections). Internal to the stages that link
// prep_geos: no public stage header includes it, so GEOS stays out of them.
#pragma once

#include <geos_c.h>

#include <string>
#include <utility>
#include <vector>

namespace prep::detail {

// One GEOS context (GEOS_init_r .. GEOS_finish_r) for the thread that owns
// it. GEOS reports an error through the context's error handler before the
// failing call returns null or an error code: last_error() is that message
// (empty before the first), for the caller's own error. Notices are
// dropped. Neither copied nor moved: the handlers point at the object.
class GeosContext {
 public:
  GeosContext() : h_(GEOS_init_r()) {
    GEOSContext_setErrorMessageHandler_r(h_, &GeosContext::on_error, this);
    GEOSContext_setNoticeMessageHandler_r(h_, &GeosContext::on_notice, this);
  }
  ~GeosContext() { GEOS_finish_r(h_); }
  GeosContext(const GeosContext&) = delete;
  GeosContext& operator=(const GeosContext&) = delete;

  GEOSContextHandle_t handle() const { return h_; }
  const std::string& last_error() const { return last_error_; }

 private:
  static void on_error(const char* msg, void* self) {
    static_cast<GeosContext*>(self)->last_error_ = msg ? msg : "";
  }
  static void on_notice(const char* /*msg*/, void* /*self*/) {}

  GEOSContextHandle_t h_;
  std::string last_error_;
};

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

class Prepared {
 public:
  Prepared(GEOSContextHandle_t h, const GEOSGeometry* g) : h_(h), p_(GEOSPrepare_r(h, g)) {}
  ~Prepared() {
    if (p_) GEOSPreparedGeom_destroy_r(h_, p_);
  }
  Prepared(const Prepared&) = delete;
  Prepared& operator=(const Prepared&) = delete;
  const GEOSPreparedGeometry* get() const { return p_; }

 private:
  GEOSContextHandle_t h_;
  const GEOSPreparedGeometry* p_;
};

class Tree {
 public:
  explicit Tree(GEOSContextHandle_t h) : h_(h), t_(GEOSSTRtree_create_r(h, 10)) {}
  ~Tree() {
    if (t_) GEOSSTRtree_destroy_r(h_, t_);
  }
  Tree(const Tree&) = delete;
  Tree& operator=(const Tree&) = delete;
  GEOSSTRtree* get() const { return t_; }

 private:
  GEOSContextHandle_t h_;
  GEOSSTRtree* t_;
};

struct Envelope {
  double x0, y0, x1, y1;
};

inline bool envelope_of(GEOSContextHandle_t h, const GEOSGeometry* g, Envelope& e) {
  return GEOSGeom_getXMin_r(h, g, &e.x0) == 1 && GEOSGeom_getYMin_r(h, g, &e.y0) == 1 &&
         GEOSGeom_getXMax_r(h, g, &e.x1) == 1 && GEOSGeom_getYMax_r(h, g, &e.y1) == 1;
}

// Every polygon (`polys`) and every other non-empty piece (`other`) of `g`.
inline void flatten(GEOSContextHandle_t h, const GEOSGeometry* g,
                    std::vector<const GEOSGeometry*>& polys,
                    std::vector<const GEOSGeometry*>& other) {
  const int type = GEOSGeomTypeId_r(h, g);
  if (type == GEOS_MULTIPOLYGON || type == GEOS_MULTILINESTRING || type == GEOS_MULTIPOINT ||
      type == GEOS_GEOMETRYCOLLECTION) {
    const int n = GEOSGetNumGeometries_r(h, g);
    for (int i = 0; i < n; ++i) flatten(h, GEOSGetGeometryN_r(h, g, i), polys, other);
    return;
  }
  if (GEOSisEmpty_r(h, g)) return;
  (type == GEOS_POLYGON ? polys : other).push_back(g);
}

// A polygon from owned rings (taken); null when GEOS refuses.
inline GEOSGeometry* polygon_of(GEOSContextHandle_t h, GeosGeom shell,
                                std::vector<GeosGeom>& holes) {
  std::vector<GEOSGeometry*> raw;
  raw.reserve(holes.size());
  for (GeosGeom& r : holes) raw.push_back(r.release());
  holes.clear();
  return GEOSGeom_createPolygon_r(h, shell.release(), raw.data(),
                                  static_cast<unsigned>(raw.size()));
}

// A collection of `type` taking over `parts` (left empty).
inline GeosGeom collection(GEOSContextHandle_t h, int type, std::vector<GeosGeom>& parts) {
  std::vector<GEOSGeometry*> raw;
  raw.reserve(parts.size());
  for (GeosGeom& p : parts) raw.push_back(p.release());
  parts.clear();
  return GeosGeom(
      h, GEOSGeom_createCollection_r(h, type, raw.data(), static_cast<unsigned>(raw.size())));
}

}  // namespace prep::detail
