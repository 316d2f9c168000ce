// GEOS, used directly as the oracle for clean tests: double-precision
// validity, MakeValid and areas on the original geometry.
#pragma once

#include <geos_c.h>

#include <string>
#include <vector>

#include "prep/scene.hpp"

namespace prep::test {

class Geos {
 public:
  Geos() : h_(GEOS_init_r()) {}
  ~Geos() { GEOS_finish_r(h_); }
  Geos(const Geos&) = delete;
  Geos& operator=(const Geos&) = delete;
  GEOSContextHandle_t h() const { return h_; }

  // Area GEOS MakeValid gives the WKT geometry (0 when nothing areal is left).
  // Area of GEOS MakeValid of `wkt`: the default (linework) method, or with
  // `structure` GEOS_MAKE_VALID_STRUCTURE without collapsed pieces.
  double make_valid_area(const std::string& wkt, bool structure = false) const {
    GEOSWKTReader* r = GEOSWKTReader_create_r(h_);
    GEOSGeometry* g = GEOSWKTReader_read_r(h_, r, wkt.c_str());
    GEOSWKTReader_destroy_r(h_, r);
    GEOSGeometry* v = nullptr;
    if (!structure) {
      v = GEOSMakeValid_r(h_, g);
    } else {
      GEOSMakeValidParams* p = GEOSMakeValidParams_create_r(h_);
      GEOSMakeValidParams_setMethod_r(h_, p, GEOS_MAKE_VALID_STRUCTURE);
      GEOSMakeValidParams_setKeepCollapsed_r(h_, p, 0);
      v = GEOSMakeValidWithParams_r(h_, g, p);
      GEOSMakeValidParams_destroy_r(h_, p);
    }
    double a = 0;
    GEOSArea_r(h_, v, &a);
    GEOSGeom_destroy_r(h_, v);
    GEOSGeom_destroy_r(h_, g);
    return a;
  }

  GEOSGeometry* ring(const Ring& r, bool linear_ring = true) const {
    GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h_, static_cast<unsigned>(r.size() + 1), 2);
    for (size_t i = 0; i <= r.size(); ++i) {
      const Point2& p = r[i % r.size()];
      GEOSCoordSeq_setXY_r(h_, cs, static_cast<unsigned>(i), p.x, p.y);
    }
    return linear_ring ? GEOSGeom_createLinearRing_r(h_, cs) : GEOSGeom_createLineString_r(h_, cs);
  }

  GEOSGeometry* polygon(const ScenePolygon& p) const {
    std::vector<GEOSGeometry*> holes;
    for (const Ring& h : p.holes) holes.push_back(ring(h));
    return GEOSGeom_createPolygon_r(h_, ring(p.shell), holes.data(),
                                    static_cast<unsigned>(holes.size()));
  }

  GEOSGeometry* line(const Ring& pts) const {
    GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h_, static_cast<unsigned>(pts.size()), 2);
    for (size_t i = 0; i < pts.size(); ++i)
      GEOSCoordSeq_setXY_r(h_, cs, static_cast<unsigned>(i), pts[i].x, pts[i].y);
    return GEOSGeom_createLineString_r(h_, cs);
  }

  bool is_valid(const ScenePolygon& p) const {
    GEOSGeometry* g = polygon(p);
    bool ok = GEOSisValid_r(h_, g) == 1;
    GEOSGeom_destroy_r(h_, g);
    return ok;
  }

 private:
  GEOSContextHandle_t h_;
};

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
