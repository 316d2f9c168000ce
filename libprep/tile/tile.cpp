// Stage 3b, tile: which tiles each part reaches, and one tile's scene, cut so
// that the cut never shows inside the tile's square (prep/tile.hpp).
#include "prep/tile.hpp"

#include <geos_c.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <string>

#include "geos_handle.hpp"
#include "prep/clean.hpp"
#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace {

Extent grown(const Extent& e, double by) {
  return {e.xmin - by, e.ymin - by, e.xmax + by, e.ymax + by};
}

bool boxes_meet(const Extent& a, const Extent& b) {
  return a.xmin <= b.xmax && b.xmin <= a.xmax && a.ymin <= b.ymax && b.ymin <= a.ymax;
}

Extent box_of(const Ring& r) {
  Extent b = no_points();
  extend(b, r);
  return b;
}

Extent segment_box(const Point2& a, const Point2& b) {
  return {std::min(a.x, b.x), std::min(a.y, b.y), std::max(a.x, b.x), std::max(a.y, b.y)};
}

bool inside(const Extent& e, const Extent& box) {
  return box.xmin >= e.xmin && box.xmax <= e.xmax && box.ymin >= e.ymin && box.ymax <= e.ymax;
}

double signed_area(const Ring& r) {
  double a = 0;
  for (size_t i = 0, n = r.size(); i < n; ++i) {
    const Point2& p = r[i];
    const Point2& q = r[(i + 1) % n];
    a += p.x * q.y - q.x * p.y;
  }
  return 0.5 * a;
}

// ------------------------------------------------------------ GEOS clips --

// Rectangle clips of polygons, on one GEOS context.
class PolygonClipper {
 public:
  // Polygon (shell, holes) clipped to `box`: the polygons of the result,
  // each as rings (shell first). Rings come back unclosed.
  std::vector<std::vector<Ring>> clip(const Ring& shell, const std::vector<Ring>& holes,
                                      const Extent& box, const std::string& what) {
    detail::GeosGeom s = ring(shell, what);
    std::vector<detail::GeosGeom> hs;
    hs.reserve(holes.size());
    for (const Ring& h : holes) hs.push_back(ring(h, what));
    detail::GeosGeom poly(h_, detail::polygon_of(h_, std::move(s), hs));
    if (!poly) failed(what, "cannot make the polygon");
    detail::GeosGeom cut(h_,
                         GEOSClipByRect_r(h_, poly.get(), box.xmin, box.ymin, box.xmax, box.ymax));
    if (!cut) failed(what, "rectangle clip failed");
    std::vector<std::vector<Ring>> out;
    collect(cut.get(), out);
    return out;
  }

 private:
  [[noreturn]] void failed(const std::string& what, const std::string& step) {
    fail<error>(kTileStage, what + ": " + step + " (GEOS: " + geos_.last_error() + ")");
  }

  detail::GeosGeom ring(const Ring& r, const std::string& what) {
    GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h_, static_cast<unsigned>(r.size() + 1), 2);
    for (size_t i = 0; i <= r.size(); ++i) {
      const Point2& p = r[i % r.size()];
      GEOSCoordSeq_setXY_r(h_, cs, static_cast<unsigned>(i), p.x, p.y);
    }
    detail::GeosGeom g(h_, GEOSGeom_createLinearRing_r(h_, cs));
    if (!g) failed(what, "cannot make a ring");
    return g;
  }

  Ring points(const GEOSGeometry* ring) {
    const GEOSCoordSequence* cs = GEOSGeom_getCoordSeq_r(h_, ring);
    unsigned n = 0;
    GEOSCoordSeq_getSize_r(h_, cs, &n);
    Ring r;
    r.reserve(n);
    for (unsigned i = 0; i + 1 < n; ++i) {  // the closing point is dropped
      Point2 p;
      GEOSCoordSeq_getXY_r(h_, cs, i, &p.x, &p.y);
      r.push_back(p);
    }
    return r;
  }

  void collect(const GEOSGeometry* g, std::vector<std::vector<Ring>>& out) {
    const int type = GEOSGeomTypeId_r(h_, g);
    if (type == GEOS_POLYGON) {
      if (GEOSisEmpty_r(h_, g)) return;
      std::vector<Ring> rings{points(GEOSGetExteriorRing_r(h_, g))};
      const int nh = GEOSGetNumInteriorRings_r(h_, g);
      for (int i = 0; i < nh; ++i) rings.push_back(points(GEOSGetInteriorRingN_r(h_, g, i)));
      out.push_back(std::move(rings));
    } else if (type == GEOS_MULTIPOLYGON || type == GEOS_GEOMETRYCOLLECTION) {
      const int n = GEOSGetNumGeometries_r(h_, g);
      for (int i = 0; i < n; ++i) collect(GEOSGetGeometryN_r(h_, g, i), out);
    }
    // Points and lines (a polygon touching the box along an edge) cover no area.
  }

  detail::GeosContext geos_;
  const GEOSContextHandle_t h_ = geos_.handle();
};

// A ring with the orientation `ccw` (true: counter-clockwise).
Ring oriented(Ring r, bool ccw) {
  if ((signed_area(r) > 0) != ccw) std::reverse(r.begin(), r.end());
  return r;
}

// A segment clipped to `box` (Liang-Barsky); false when it misses the box.
// Used only for the rare segment longer than a tile's reach, so that every
// stored vertex stays within int32 millimetres of the tile's origin; the
// clipped segment is the same line, its new ends far outside the square.
bool clip_segment(Point2& a, Point2& b, const Extent& box) {
  double t0 = 0, t1 = 1;
  const double dx = b.x - a.x, dy = b.y - a.y;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {a.x - box.xmin, box.xmax - a.x, a.y - box.ymin, box.ymax - a.y};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0)
      t0 = std::max(t0, t);
    else
      t1 = std::min(t1, t);
  }
  if (t0 > t1) return false;
  const Point2 a0 = a;
  if (t0 > 0) a = {a0.x + t0 * dx, a0.y + t0 * dy};
  if (t1 < 1) b = {a0.x + t1 * dx, a0.y + t1 * dy};
  return true;
}

// The runs of whole segments of `line` that reach `reach`, each grown by
// one neighbour segment at both ends (prep/tile.hpp). A closed line every
// segment of which is kept stays closed. Vertices beyond `safe` are pulled
// onto it along their segment.
std::vector<SceneLine> line_runs(const SceneLine& line, const Extent& reach, const Extent& safe,
                                 bool dashed = false) {
  const Ring& p = line.points;
  const size_t n = p.size();
  if (n < 2) return {};
  const size_t nseg = line.closed ? n : n - 1;
  std::vector<char> hit(nseg, 0);
  bool any = false;
  for (size_t s = 0; s < nseg; ++s) {
    if (boxes_meet(segment_box(p[s], p[(s + 1) % n]), reach)) hit[s] = 1, any = true;
  }
  if (!any) return {};
  // Grow by one segment on each side.
  std::vector<char> keep(hit);
  for (size_t s = 0; s < nseg; ++s) {
    if (!hit[s]) continue;
    if (s > 0 || line.closed) keep[(s + nseg - 1) % nseg] = 1;
    if (s + 1 < nseg || line.closed) keep[(s + 1) % nseg] = 1;
  }
  auto fits = [&](const Point2& q) {
    return q.x >= safe.xmin && q.x <= safe.xmax && q.y >= safe.ymin && q.y <= safe.ymax;
  };
  // Runs of kept segments: [first, first + count) in segment indices (mod nseg).
  std::vector<std::pair<size_t, size_t>> runs;
  if (std::all_of(keep.begin(), keep.end(), [](char k) { return k != 0; })) {
    if (line.closed && std::all_of(p.begin(), p.end(), fits)) {
      return {line};
    }
    if (!line.closed) {
      runs.push_back({0, nseg});
    } else {
      runs.push_back({0, nseg});  // the whole ring, opened at vertex 0
    }
  } else {
    // Start where a run begins, so a closed line's run across vertex 0 is one run.
    size_t start = 0;
    if (line.closed) {
      while (!(keep[start] && !keep[(start + nseg - 1) % nseg])) ++start;
    }
    size_t s = 0;
    while (s < nseg) {
      const size_t k = (start + s) % nseg;
      if (!keep[k]) {
        ++s;
        continue;
      }
      size_t count = 0;
      while (s + count < nseg && keep[(start + s + count) % nseg]) ++count;
      runs.push_back({k, count});
      s += count;
    }
  }
  // A dashed line's length from its start to each vertex, over the
  // positions a package quantises (llround of millimetres, as
  // libprep/model/grid.cpp quantise; a tile's origin is a whole number of
  // them from the scene's), so that a cut keeps the whole line's phase.
  std::vector<double> dist;
  if (dashed) {
    dist.assign(n, 0.0);
    auto qv = [&](size_t i) {
      return std::array<int64_t, 2>{std::llround(p[i].x / decal::kQuantumMetres),
                                    std::llround(p[i].y / decal::kQuantumMetres)};
    };
    for (size_t i = 1; i < n; ++i) {
      const auto a = qv(i - 1), b = qv(i);
      dist[i] = dist[i - 1] + std::hypot(double(b[0] - a[0]) * decal::kQuantumMetres,
                                         double(b[1] - a[1]) * decal::kQuantumMetres);
    }
  }
  std::vector<SceneLine> out;
  for (const auto& [first, count] : runs) {
    SceneLine piece = line;
    piece.closed = false;
    piece.points.clear();
    for (size_t i = 0; i < count; ++i) {
      Point2 a = p[(first + i) % n], b = p[(first + i + 1) % n];
      if (!(fits(a) && fits(b)) && !clip_segment(a, b, safe)) continue;
      if (dashed && piece.points.empty()) {  // a pulled-in start: its distance along
        const Point2& v = p[(first + i) % n];
        piece.dash_start =
            line.dash_start + dist[(first + i) % n] + std::hypot(a.x - v.x, a.y - v.y);
      }
      if (piece.points.empty() || piece.points.back().x != a.x || piece.points.back().y != a.y)
        piece.points.push_back(a);
      piece.points.push_back(b);
    }
    if (piece.points.size() >= 2) out.push_back(std::move(piece));
  }
  return out;
}

// "layer 'roads' fid 7" for messages.
std::string where_of(const SceneFeatures& scene, uint32_t layer, int64_t fid) {
  const std::string name = layer < scene.layers.size() ? scene.layers[layer].name : "?";
  return "layer '" + name + "' fid " + std::to_string(fid);
}

void shift(Ring& r, double dx, double dy) {
  for (Point2& q : r) q = {q.x + dx, q.y + dy};
}

}  // namespace

std::string tile_name(const TileKey& key) {
  return "x" + std::to_string(key.x) + "_y" + std::to_string(key.y);
}

Extent TilePlan::square(const TileKey& key) const {
  return {double(key.x) * size, double(key.y) * size, double(key.x + 1) * size,
          double(key.y + 1) * size};
}

std::pair<double, double> TilePlan::origin(const TileKey& key) const {
  return {(double(key.x) + 0.5) * size, (double(key.y) + 0.5) * size};
}

double stroke_half_width(const SceneFeatures& scene) {
  double hw = 0;
  for (const SceneLine& l : scene.lines) {
    const LayerSpec& spec = scene.layers.at(l.layer);
    const bool banded = spec.style.outline != decal::OutlineMode::normal;
    if (std::isfinite(l.width)) hw = std::max(hw, l.width * 0.5 * (banded ? 2.0 : 1.0));
  }
  return hw;
}

double stroke_margin_of(double hw, const ModelOptions& options) {
  const double limit = std::clamp(options.miter_limit_deg, 1.0, 180.0);
  return std::max(1.0, 1.01 * hw / std::sin(limit * M_PI / 360.0));
}

double stroke_margin(const SceneFeatures& scene, const ModelOptions& options) {
  return stroke_margin_of(stroke_half_width(scene), options);
}

Extent ring_box(const Ring& ring) {
  return box_of(ring);
}

TileRange tile_range(const Extent& local, double by, double ox, double oy, double tile_size) {
  const Extent b{local.xmin + ox - by, local.ymin + oy - by, local.xmax + ox + by,
                 local.ymax + oy + by};
  return {{int64_t(std::floor(b.xmin / tile_size)), int64_t(std::floor(b.ymin / tile_size))},
          {int64_t(std::floor(b.xmax / tile_size)), int64_t(std::floor(b.ymax / tile_size))}};
}

void check_tile_size(double tile_size) {
  if (!(tile_size >= kMinTileSize && tile_size <= kMaxTileSize)) {
    fail<usage_error>(kTileStage, "--tile-size " + std::to_string(tile_size) +
                                      " m is outside [1, 4000000] m (a tile's half must fit "
                                      "int32 millimetres around its centre)");
  }
}

TilePlan tile_plan(const SceneFeatures& scene, const ModelOptions& options, double tile_size) {
  check_tile_size(tile_size);
  TilePlan plan;
  plan.size = tile_size;
  plan.frame = scene.frame;
  plan.margin = stroke_margin(scene, options);
  plan.dynamic_margin = tile_size * 0.5;
  const double ox = scene.frame.origin_x, oy = scene.frame.origin_y;
  // Tiles whose square grown by `by` meets the part's box (absolute).
  auto each_tile = [&](const Extent& local, double by, auto&& visit) {
    const TileRange r = tile_range(local, by, ox, oy, tile_size);
    for (int64_t y = r.lo.y; y <= r.hi.y; ++y)
      for (int64_t x = r.lo.x; x <= r.hi.x; ++x) visit(TileKey{x, y});
  };
  for (uint32_t i = 0; i < scene.polygons.size(); ++i)
    each_tile(box_of(scene.polygons[i].shell), plan.margin,
              [&](TileKey k) { plan.tiles[k].polygons.push_back(i); });
  for (uint32_t i = 0; i < scene.lines.size(); ++i)
    each_tile(box_of(scene.lines[i].points), plan.margin,
              [&](TileKey k) { plan.tiles[k].lines.push_back(i); });
  for (uint32_t i = 0; i < scene.dynamic_lines.size(); ++i)
    each_tile(box_of(scene.dynamic_lines[i].points), plan.dynamic_margin,
              [&](TileKey k) { plan.tiles[k].dynamic_lines.push_back(i); });
  return plan;
}

SceneFeatures tile_scene(const SceneFeatures& scene, const TilePlan& plan, const TileKey& key) {
  const auto it = plan.tiles.find(key);
  SceneFeatures out;
  out.frame = scene.frame;
  const auto [tox, toy] = plan.origin(key);
  out.frame.origin_x = tox;
  out.frame.origin_y = toy;
  out.layers = scene.layers;
  out.manifest.notes = scene.manifest.notes;
  if (it == plan.tiles.end()) return out;
  const TilePlan::Members& members = it->second;

  // The square and its reaches in scene coordinates (relative to the scene origin).
  const Extent sq = plan.square(key);
  const double sx = scene.frame.origin_x, sy = scene.frame.origin_y;
  const Extent local{sq.xmin - sx, sq.ymin - sy, sq.xmax - sx, sq.ymax - sy};
  const Extent reach = grown(local, plan.margin);
  const Extent dyn_reach = grown(local, plan.dynamic_margin);
  // Beyond this, vertices are pulled in (a tile's positions must fit int32 mm).
  const Extent safe = grown(local, plan.size);
  // scene coordinates -> tile coordinates
  const double dx = sx - tox, dy = sy - toy;

  PolygonClipper clipper;
  for (uint32_t i : members.polygons) {
    const ScenePolygon& p = scene.polygons[i];
    if (inside(reach, box_of(p.shell))) {
      ScenePolygon q = p;
      shift(q.shell, dx, dy);
      for (Ring& h : q.holes) shift(h, dx, dy);
      out.polygons.push_back(std::move(q));
      continue;
    }
    for (std::vector<Ring>& rings :
         clipper.clip(p.shell, p.holes, reach, where_of(scene, p.layer, p.fid))) {
      if (rings.front().size() < 3) continue;
      ScenePolygon q = p;  // area and order keys: the whole feature's
      q.shell = oriented(std::move(rings.front()), true);
      q.holes.clear();
      for (size_t h = 1; h < rings.size(); ++h)
        if (rings[h].size() >= 3) q.holes.push_back(oriented(std::move(rings[h]), false));
      shift(q.shell, dx, dy);
      for (Ring& h : q.holes) shift(h, dx, dy);
      out.polygons.push_back(std::move(q));
    }
  }
  for (uint32_t i : members.lines) {
    const SceneLine& l = scene.lines[i];
    const bool own_ring =
        l.closed && scene.layers.at(l.layer).style.outline != decal::OutlineMode::normal;
    if (own_ring && !inside(reach, box_of(l.points))) {
      // Clipped as its ring's polygon: the even-odd side test is unchanged
      // inside the square; the new edges lie on the reach's border.
      const bool ccw = signed_area(l.points) > 0;
      for (std::vector<Ring>& rings :
           clipper.clip(l.points, {}, reach, where_of(scene, l.layer, l.fid))) {
        if (rings.front().size() < 3) continue;
        SceneLine q = l;
        q.points = oriented(std::move(rings.front()), ccw);
        shift(q.points, dx, dy);
        out.lines.push_back(std::move(q));
      }
      continue;
    }
    for (SceneLine& q : line_runs(l, reach, safe, !scene.layers.at(l.layer).dash.empty())) {
      shift(q.points, dx, dy);
      out.lines.push_back(std::move(q));
    }
  }
  for (uint32_t i : members.dynamic_lines) {
    for (SceneLine& q : line_runs(scene.dynamic_lines[i], dyn_reach, safe)) {
      shift(q.points, dx, dy);
      out.dynamic_lines.push_back(std::move(q));
    }
  }

  // This tile's counts: features (layer, fid) with a part here, parts, vertices.
  out.manifest.layers.resize(scene.layers.size());
  std::vector<std::set<int64_t>> fids(scene.layers.size());
  auto count = [&](uint32_t layer, int64_t fid, size_t vertices) {
    fids.at(layer).insert(fid);
    LayerCounts& c = out.manifest.layers[layer];
    ++c.parts;
    c.vertices_in += vertices;
    c.vertices_out += vertices;
  };
  for (const ScenePolygon& p : out.polygons) {
    size_t v = p.shell.size();
    for (const Ring& h : p.holes) v += h.size();
    count(p.layer, p.fid, v);
  }
  for (const SceneLine& l : out.lines) count(l.layer, l.fid, l.points.size());
  for (const SceneLine& l : out.dynamic_lines) count(l.layer, l.fid, l.points.size());
  for (size_t l = 0; l < scene.layers.size(); ++l) {
    LayerCounts& c = out.manifest.layers[l];
    c.layer = scene.layers[l].name;
    c.read = c.kept = fids[l].size();
  }
  out.extent = kept_extent(out);
  return out;
}

}  // namespace prep
