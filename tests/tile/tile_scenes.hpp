// Synthetic scenes for the tile stage's unit tests (prep/tile.hpp), and the
// plane geometry the tests compute their expected values with: shoelace
// areas and polyline lengths, by hand, never through GEOS or the code under
// test.
#pragma once

#include <cmath>
#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

#include "prep/features.hpp"
#include "prep/tile.hpp"

namespace prep {
// GoogleTest prints a failing key as (x, y).
inline void PrintTo(const TileKey& k, std::ostream* os) {
  *os << "(" << k.x << ", " << k.y << ")";
}
}  // namespace prep

namespace tile_test {

// Layer indices of scene().
constexpr uint32_t kPolys = 0, kRoads = 1, kOutlines = 2, kDynamic = 3, kDashed = 4;

// An empty scene with one layer of each kind the tile stage treats apart:
// polygons, static lines, inset outlines (clipped as their ring), dynamic
// lines and dashed static lines. Frame origin (ox, oy).
inline prep::SceneFeatures scene(double ox = 0, double oy = 0) {
  prep::SceneFeatures s;
  s.frame.origin_x = ox;
  s.frame.origin_y = oy;
  s.frame.description = "tile test frame";
  auto layer = [&](const char* name, prep::DecalKind kind) {
    prep::LayerSpec l;
    l.name = name;
    l.kind = kind;
    s.layers.push_back(l);
    return &s.layers.back();
  };
  layer("polys", prep::DecalKind::polygon);
  layer("roads", prep::DecalKind::line);
  layer("outlines", prep::DecalKind::outline)->style.outline = decal::OutlineMode::inset;
  layer("dynamic", prep::DecalKind::line)->dynamic = true;
  layer("dashed", prep::DecalKind::line)->dash = {10.0, 10.0};
  return s;
}

// A counter-clockwise axis-aligned rectangle.
inline prep::Ring rect(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

inline double signed_area(const prep::Ring& r) {
  double a = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    const prep::Point2& p = r[i];
    const prep::Point2& q = r[(i + 1) % r.size()];
    a += p.x * q.y - q.x * p.y;
  }
  return 0.5 * a;
}

// Shell minus holes.
inline double area(const prep::ScenePolygon& p) {
  double a = std::fabs(signed_area(p.shell));
  for (const prep::Ring& h : p.holes) a -= std::fabs(signed_area(h));
  return a;
}

inline double length(const prep::SceneLine& l) {
  double s = 0;
  const size_t n = l.points.size();
  const size_t segs = l.closed ? n : n - 1;
  for (size_t i = 0; i < segs && n >= 2; ++i) {
    const prep::Point2& a = l.points[i];
    const prep::Point2& b = l.points[(i + 1) % n];
    s += std::hypot(b.x - a.x, b.y - a.y);
  }
  return s;
}

inline prep::ScenePolygon polygon(int64_t fid, prep::Ring shell,
                                  std::vector<prep::Ring> holes = {}) {
  prep::ScenePolygon p;
  p.fid = fid;
  p.layer = kPolys;
  p.shell = std::move(shell);
  p.holes = std::move(holes);
  p.area = area(p);
  return p;
}

inline prep::SceneLine line(int64_t fid, uint32_t layer, prep::Ring points, double width,
                            bool closed = false) {
  prep::SceneLine l;
  l.fid = fid;
  l.layer = layer;
  l.points = std::move(points);
  l.width = width;
  l.closed = closed;
  l.length = length(l);
  return l;
}

// A horizontal polyline at height y with a vertex every `step` metres from
// x0 to x1.
inline prep::Ring row(double x0, double x1, double step, double y) {
  prep::Ring r;
  const int n = int(std::lround((x1 - x0) / step));
  for (int i = 0; i <= n; ++i) r.push_back({x0 + i * step, y});
  return r;
}

}  // namespace tile_test
