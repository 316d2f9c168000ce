// tests/evaluate/synthetic.hpp — synthetic SceneFeatures for the static decal
// tests (built directly, the way clean hands them to build) and the GEOS
// regions a static line covers, on the shared GEOS oracle
// (tests/support/geos_oracle.hpp).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "geos_oracle.hpp"
#include "prep/features.hpp"

namespace synth {

// The GEOS oracle (tests/support/geos_oracle.hpp: Geos, G, polygon, ...)
// under synth:: as well.
using namespace prep::test;

// ----------------------------------------------------------- generators --

// Star-shaped simple ring around (cx, cy), radii in [r0, r1], `n` vertices,
// counter-clockwise unless `cw`.
inline prep::Ring star(std::mt19937_64& rng, double cx, double cy, double r0, double r1, int n,
                       bool cw) {
  std::uniform_real_distribution<double> rad(r0, r1), jitter(-0.3, 0.3);
  prep::Ring r;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * (i + 0.5 + jitter(rng)) / n;
    const double rr = rad(rng);
    r.push_back({cx + rr * std::cos(a), cy + rr * std::sin(a)});
  }
  if (cw) std::reverse(r.begin(), r.end());
  return r;
}

inline prep::LayerSpec layer(const std::string& name, prep::DecalKind kind, uint32_t rgba,
                             decal::CornerStyle corner = decal::CornerStyle::round,
                             decal::OutlineMode outline = decal::OutlineMode::normal,
                             double width = 2.0) {
  prep::LayerSpec l;
  l.name = name;
  l.kind = kind;
  l.style.color.rgba = rgba;
  l.style.corner = corner;
  l.style.outline = outline;
  l.style.width = width;
  return l;
}

// A tiled polygon set: in tile (i, j) of size `tile` one star shell with a
// star hole, and a star island inside the hole. Every `complex_every`-th
// shell has many vertices (deep quad-trees). Coordinates + (ox, oy).
struct PolygonSet {
  prep::SceneFeatures scene;
  int tiles = 0;
  double tile = 0, ox = 0, oy = 0;
};
inline PolygonSet polygon_set(uint64_t seed, int tiles, double tile, double ox, double oy,
                              int complex_every = 7, int complex_vertices = 1500) {
  std::mt19937_64 rng(seed);
  PolygonSet s;
  s.tiles = tiles;
  s.tile = tile;
  s.ox = ox;
  s.oy = oy;
  s.scene.layers.push_back(layer("parcels", prep::DecalKind::polygon, 0xff3366ccu));
  std::uniform_int_distribution<int> nv(5, 40);
  int64_t fid = 0;
  for (int j = 0; j < tiles; ++j)
    for (int i = 0; i < tiles; ++i) {
      const double cx = ox + (i + 0.5) * tile, cy = oy + (j + 0.5) * tile;
      const bool complex = (i + j * tiles) % complex_every == 0;
      prep::ScenePolygon p;
      p.shell =
          star(rng, cx, cy, 0.28 * tile, 0.48 * tile, complex ? complex_vertices : nv(rng), false);
      p.holes.push_back(star(rng, cx, cy, 0.10 * tile, 0.18 * tile, nv(rng), true));
      p.fid = fid++;
      p.area = double(fid);  // any distinct order
      s.scene.polygons.push_back(p);
      prep::ScenePolygon island;
      island.shell = star(rng, cx, cy, 0.03 * tile, 0.07 * tile, nv(rng), false);
      island.fid = fid++;
      island.area = double(fid);
      s.scene.polygons.push_back(island);
    }
  s.scene.extent = {ox, oy, ox + tiles * tile, oy + tiles * tile};
  return s;
}

// A city-like scene, denser towards (0, 0): layer 0 "parcels" holds
// `polygons` star shells around normally distributed centres (standard
// deviation sx, sy metres), every third with a star hole; layer 1 "roads"
// holds `lines` random walks from such centres. Ring vertex counts come
// from shell_vertices / hole_vertices (drawn from the scene's generator, if
// at all, just before the ring), so that a scene is the same for a seed.
struct ClusteredScene {
  uint64_t seed = 0;
  int polygons = 0, lines = 0;
  double sx = 0, sy = 0;
  std::function<int(std::mt19937_64&)> shell_vertices, hole_vertices;
  int walk_points = 0;        // points per line
  double step = 0, turn = 0;  // metres per step; turn ~ N(0, turn) radians
  decal::CornerStyle corner = decal::CornerStyle::round;
  double width = 0;                   // the roads' width, metres
  std::function<double(int)> length;  // line i's length
};
inline prep::SceneFeatures clustered_scene(const ClusteredScene& c) {
  std::mt19937_64 rng(c.seed);
  std::normal_distribution<double> N(0, 1);
  std::uniform_real_distribution<double> U(0, 1);
  prep::SceneFeatures s;
  s.layers.push_back(layer("parcels", prep::DecalKind::polygon, 0xc0406080u));
  s.layers.push_back(layer("roads", prep::DecalKind::line, 0xffffffffu, c.corner,
                           decal::OutlineMode::normal, c.width));
  for (int i = 0; i < c.polygons; ++i) {
    const double cx = c.sx * N(rng), cy = c.sy * N(rng), size = 6 + 20 * std::abs(N(rng));
    prep::ScenePolygon p;
    const int shell = c.shell_vertices(rng);
    p.shell = star(rng, cx, cy, 0.6 * size, size, shell, false);
    if (i % 3 == 0) {
      const int hole = c.hole_vertices(rng);
      p.holes.push_back(star(rng, cx, cy, 0.15 * size, 0.3 * size, hole, true));
    }
    p.fid = i;
    p.area = size * size;
    s.polygons.push_back(std::move(p));
  }
  for (int i = 0; i < c.lines; ++i) {
    prep::SceneLine l;
    double x = c.sx * N(rng), y = c.sy * N(rng), a = 2 * M_PI * U(rng);
    for (int k = 0; k < c.walk_points; ++k) {
      l.points.push_back({x, y});
      x += c.step * std::cos(a);
      y += c.step * std::sin(a);
      a += c.turn * N(rng);
    }
    l.layer = 1;
    l.width = c.width;
    l.length = c.length(i);
    l.fid = i;
    s.lines.push_back(std::move(l));
  }
  return s;
}

// ------------------------------------------------------- line oracle --
// GEOS region a static line covers, on its double-precision geometry (see
// tests/evaluate/test_line_accuracy.cpp for the definition per style).
constexpr double kLimitDeg = 40.0;

inline bool fallback(const prep::Point2& p, const prep::Point2& v, const prep::Point2& n) {
  double ax = v.x - p.x, ay = v.y - p.y, bx = n.x - v.x, by = n.y - v.y;
  const double la = std::hypot(ax, ay), lb = std::hypot(bx, by);
  ax /= la;
  ay /= la;
  bx /= lb;
  by /= lb;
  return -(ax * bx + ay * by) > std::cos(kLimitDeg * M_PI / 180.0);
}

inline G disc(GEOSContextHandle_t h, const prep::Point2& c, double r) {
  G p = synth::point(h, c.x, c.y);
  return G(h, GEOSBuffer_r(h, p.g, r, 64));
}

inline G unite(GEOSContextHandle_t h, std::vector<G>& parts) {
  G coll = synth::collection(h, GEOS_GEOMETRYCOLLECTION, parts);
  return G(h, GEOSUnaryUnion_r(h, coll.g));
}

inline G oracle(GEOSContextHandle_t h, const prep::SceneLine& l, const prep::LayerSpec& layer) {
  const double hw = l.width * 0.5 * (layer.style.outline == decal::OutlineMode::normal ? 1 : 2);
  const auto& pts = l.points;
  const size_t n = pts.size();
  G band;
  const double limit = 1.0 / std::sin(kLimitDeg * M_PI / 360.0) * (1 + 1e-9);
  switch (layer.style.corner) {
    case decal::CornerStyle::round: {
      G g = synth::linestring(h, pts, l.closed);
      band = G(h, GEOSBufferWithStyle_r(h, g.g, hw, 64, GEOSBUF_CAP_ROUND, GEOSBUF_JOIN_ROUND, 5));
      break;
    }
    case decal::CornerStyle::bevel: {
      G g = synth::linestring(h, pts, l.closed);
      band = G(h, GEOSBufferWithStyle_r(h, g.g, hw, 64, GEOSBUF_CAP_ROUND, GEOSBUF_JOIN_BEVEL, 5));
      break;
    }
    case decal::CornerStyle::miter: {
      std::vector<bool> fb(n, false);
      bool any = false;
      for (size_t i = 0; i < n; ++i) {
        if (!l.closed && (i == 0 || i + 1 == n)) continue;
        fb[i] = fallback(pts[(i + n - 1) % n], pts[i], pts[(i + 1) % n]);
        any = any || fb[i];
      }
      if (l.closed && !any) {
        G poly = synth::polygon(h, pts);
        G outer(h, GEOSBufferWithStyle_r(h, poly.g, hw, 8, GEOSBUF_CAP_FLAT, GEOSBUF_JOIN_MITRE,
                                         limit));
        G inner(h, GEOSBufferWithStyle_r(h, poly.g, -hw, 8, GEOSBUF_CAP_FLAT, GEOSBUF_JOIN_MITRE,
                                         limit));
        band = G(h, GEOSDifference_r(h, outer.g, inner.g));
        break;
      }
      // Walk the line from a break vertex (an end, or a fallback vertex of a
      // ring), cutting at every break vertex.
      std::vector<size_t> order;
      size_t start = 0;
      if (l.closed)
        while (!fb[start]) ++start;
      for (size_t k = 0; k < n; ++k) order.push_back((start + k) % n);
      if (l.closed) order.push_back(start);
      std::vector<G> parts;
      prep::Ring piece{pts[order[0]]};
      parts.push_back(disc(h, pts[order[0]], hw));
      for (size_t k = 1; k < order.size(); ++k) {
        const size_t i = order[k];
        piece.push_back(pts[i]);
        const bool brk = k + 1 == order.size() || fb[i];
        if (!brk) continue;
        // GEOS buffers a closed LineString as a ring (a join, no caps), so a
        // ring with a single fallback vertex is cut into two open pieces
        // sharing one segment; their union keeps every mitre join.
        std::vector<prep::Ring> pieces{piece};
        if (piece.size() >= 4 && piece.front().x == piece.back().x &&
            piece.front().y == piece.back().y)
          pieces = {prep::Ring(piece.begin(), piece.begin() + 3),
                    prep::Ring(piece.begin() + 1, piece.end())};
        for (const auto& pc : pieces) {
          G g = synth::linestring(h, pc);
          parts.push_back(G(h, GEOSBufferWithStyle_r(h, g.g, hw, 8, GEOSBUF_CAP_FLAT,
                                                     GEOSBUF_JOIN_MITRE, limit)));
        }
        parts.push_back(disc(h, pts[i], hw));
        piece = {pts[i]};
      }
      band = unite(h, parts);
      break;
    }
  }
  if (layer.style.outline == decal::OutlineMode::normal) return band;
  double area2 = 0;
  for (size_t i = 0; i < n; ++i)
    area2 += pts[i].x * pts[(i + 1) % n].y - pts[(i + 1) % n].x * pts[i].y;
  const bool ccw = area2 > 0;
  G poly = synth::polygon(h, pts);
  if ((layer.style.outline == decal::OutlineMode::inset) == ccw)
    return G(h, GEOSIntersection_r(h, band.g, poly.g));
  return G(h, GEOSDifference_r(h, band.g, poly.g));
}

}  // namespace synth
