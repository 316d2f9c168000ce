// geos_oracle.hpp — GEOS, used directly as the independent oracle of the
// clean, evaluate and model tests: one context, one owning geometry handle,
// geometries built from prep::Ring / ScenePolygon / SceneLine, and areas
// independent of GEOS. Header-only and GEOS's: include it only where
// GEOS::geos_c and prep are linked.
#pragma once

#include <geos_c.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "prep/features.hpp"

namespace prep::test {

// Rings scaled by `scale`, turned by `angle` radians about (0, 0) when
// `rotate`, then moved by (ox, oy): where the validity tests place a sample.
inline std::vector<Ring> placed(std::vector<Ring> rings, double scale, double ox, double oy,
                                double angle, bool rotate) {
  const double ca = std::cos(angle), sa = std::sin(angle);
  for (Ring& r : rings)
    for (Point2& p : r) {
      const double x = p.x * scale, y = p.y * scale;
      p = rotate ? Point2{ox + ca * x - sa * y, oy + sa * x + ca * y} : Point2{ox + x, oy + y};
    }
  return rings;
}

// Rings as text for a failure message: "(x y, x y, ...) (...) ", every
// coordinate with 17 digits so that it reads back exactly.
inline std::string describe(const std::vector<Ring>& rings) {
  std::string s;
  char buf[64];
  for (const Ring& r : rings) {
    s += "(";
    for (const Point2& p : r) {
      std::snprintf(buf, sizeof buf, "%.17g %.17g, ", p.x, p.y);
      s += buf;
    }
    s += ") ";
  }
  return s;
}

// ------------------------------------------------------------- context --
inline void geos_notice(const char*, void*) {}

// A GEOS context whose notices and errors are silenced (the tests check
// results, not messages).
struct Geos {
  GEOSContextHandle_t h;
  Geos() : h(GEOS_init_r()) {
    GEOSContext_setNoticeMessageHandler_r(h, geos_notice, nullptr);
    GEOSContext_setErrorMessageHandler_r(h, geos_notice, nullptr);
  }
  ~Geos() { GEOS_finish_r(h); }
  Geos(const Geos&) = delete;
  Geos& operator=(const Geos&) = delete;
};

// Owning geometry pointer; GEOS returning null throws.
struct G {
  GEOSContextHandle_t h = nullptr;
  GEOSGeometry* g = nullptr;
  G() = default;
  G(GEOSContextHandle_t hh, GEOSGeometry* gg) : h(hh), g(gg) {
    if (!g) throw std::runtime_error("GEOS returned null");
  }
  G(G&& o) noexcept : h(o.h), g(o.g) { o.g = nullptr; }
  G& operator=(G&& o) noexcept {
    std::swap(h, o.h);
    std::swap(g, o.g);
    return *this;
  }
  ~G() {
    if (g) GEOSGeom_destroy_r(h, g);
  }
  GEOSGeometry* release() {
    auto* r = g;
    g = nullptr;
    return r;
  }
};

// -------------------------------------------------------- constructors --
// The points of `r`, with the first repeated at the end when `close`.
inline GEOSCoordSequence* seq(GEOSContextHandle_t h, const Ring& r, bool close) {
  const size_t n = r.size() + (close ? 1 : 0);
  GEOSCoordSequence* s = GEOSCoordSeq_create_r(h, unsigned(n), 2);
  for (size_t i = 0; i < n; ++i) {
    const Point2& p = r[i % r.size()];
    GEOSCoordSeq_setXY_r(h, s, unsigned(i), p.x, p.y);
  }
  return s;
}
inline G linestring(GEOSContextHandle_t h, const Ring& r, bool close = false) {
  return G(h, GEOSGeom_createLineString_r(h, seq(h, r, close)));
}
// A scene line as GEOS sees it: closed lines repeat their first point.
inline G line(GEOSContextHandle_t h, const SceneLine& l) {
  return linestring(h, l.points, l.closed);
}
inline G polygon(GEOSContextHandle_t h, const Ring& shell, const std::vector<Ring>& holes = {}) {
  GEOSGeometry* s = GEOSGeom_createLinearRing_r(h, seq(h, shell, true));
  std::vector<GEOSGeometry*> hs;
  for (const auto& r : holes) hs.push_back(GEOSGeom_createLinearRing_r(h, seq(h, r, true)));
  return G(h, GEOSGeom_createPolygon_r(h, s, hs.data(), unsigned(hs.size())));
}
inline G polygon(GEOSContextHandle_t h, const ScenePolygon& p) {
  return polygon(h, p.shell, p.holes);
}
inline G box(GEOSContextHandle_t h, double x0, double y0, double x1, double y1) {
  return polygon(h, Ring{{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}});
}
inline G point(GEOSContextHandle_t h, double x, double y) {
  return G(h, GEOSGeom_createPointFromXY_r(h, x, y));
}
// A collection of `type` taking over `parts` (left empty handles).
inline G collection(GEOSContextHandle_t h, int type, std::vector<G>& parts) {
  std::vector<GEOSGeometry*> raw;
  for (auto& p : parts) raw.push_back(p.release());
  return G(h, GEOSGeom_createCollection_r(h, type, raw.data(), unsigned(raw.size())));
}
inline G from_wkt(GEOSContextHandle_t h, const std::string& wkt) {
  GEOSWKTReader* r = GEOSWKTReader_create_r(h);
  GEOSGeometry* g = GEOSWKTReader_read_r(h, r, wkt.c_str());
  GEOSWKTReader_destroy_r(h, r);
  return G(h, g);
}

// ------------------------------------------------------------- queries --
inline bool is_valid(GEOSContextHandle_t h, const ScenePolygon& p) {
  return GEOSisValid_r(h, polygon(h, p).g) == 1;
}

inline double area(const G& g) {
  double a = 0;
  GEOSArea_r(g.h, g.g, &a);
  return a;
}
inline double length(const G& g) {
  double l = 0;
  GEOSLength_r(g.h, g.g, &l);
  return l;
}

// Area of GEOS MakeValid of `wkt`: the default (linework) method, or with
// `structure` GEOS_MAKE_VALID_STRUCTURE without collapsed pieces (0 when
// nothing areal is left).
inline double make_valid_area(GEOSContextHandle_t h, const std::string& wkt,
                              bool structure = false) {
  const G g = from_wkt(h, wkt);
  GEOSGeometry* v = nullptr;
  if (!structure) {
    v = GEOSMakeValid_r(h, g.g);
  } else {
    GEOSMakeValidParams* p = GEOSMakeValidParams_create_r(h);
    GEOSMakeValidParams_setMethod_r(h, p, GEOS_MAKE_VALID_STRUCTURE);
    GEOSMakeValidParams_setKeepCollapsed_r(h, p, 0);
    v = GEOSMakeValidWithParams_r(h, g.g, p);
    GEOSMakeValidParams_destroy_r(h, p);
  }
  const G valid(h, v);
  double a = 0;
  GEOSArea_r(h, valid.g, &a);
  return a;
}

// ------------------------------------------------- areas without GEOS --
// Shoelace area (positive for counter-clockwise), independent of GEOS.
inline double ring_area(const Ring& r) {
  double a = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    const Point2& p = r[i];
    const Point2& q = r[(i + 1) % r.size()];
    a += p.x * q.y - q.x * p.y;
  }
  return 0.5 * a;
}

inline double polygon_area(const ScenePolygon& p) {
  double a = ring_area(p.shell);
  for (const Ring& h : p.holes) a += ring_area(h);  // holes are clockwise: negative
  return a;
}

}  // namespace prep::test
