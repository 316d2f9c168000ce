// The clip of hole-heavy polygons to the extent: detail/clip_many_holes.hpp.
#include "detail/clip_many_holes.hpp"

#include <algorithm>
#include <cstdint>
#include <memory>
#include <numeric>
#include <vector>

#include "geos_handle.hpp"

namespace prep::detail {
namespace {

struct Found {
  std::vector<uint32_t> ids;
};

void on_found(void* item, void* user) {
  static_cast<Found*>(user)->ids.push_back(*static_cast<const uint32_t*>(item));
}

}  // namespace

GEOSGeometry* clip_many_holes(GEOSContextHandle_t h, const GEOSGeometry* valid, double x0,
                              double y0, double x1, double y1) {
  const int type = GEOSGeomTypeId_r(h, valid);
  if (type != GEOS_POLYGON && type != GEOS_MULTIPOLYGON && type != GEOS_GEOMETRYCOLLECTION)
    return nullptr;
  std::vector<const GEOSGeometry*> inputs, lower;  // polygons; lines and points
  flatten(h, valid, inputs, lower);
  size_t total_holes = 0;
  for (const GEOSGeometry* p : inputs)
    total_holes += static_cast<size_t>(std::max(GEOSGetNumInteriorRings_r(h, p), 0));
  if (total_holes < kClipByHolesMinHoles) return nullptr;

  std::vector<GeosGeom> no_holes;
  GeosGeom rect(h, GEOSGeom_createRectangle_r(h, x0, y0, x1, y1));  // as clean's clip_rect
  if (!rect) return nullptr;

  std::vector<GeosGeom> polys, other;    // the result's pieces
  for (const GEOSGeometry* g : lower) {  // collapsed pieces of a repair, clipped as they are
    GeosGeom cut(h, GEOSIntersection_r(h, g, rect.get()));
    if (!cut) return nullptr;
    std::vector<const GEOSGeometry*> none, rest;
    flatten(h, cut.get(), none, rest);
    for (const GEOSGeometry* o : rest) other.emplace_back(h, GEOSGeom_clone_r(h, o));
  }
  for (const GEOSGeometry* p : inputs) {
    const int nh = GEOSGetNumInteriorRings_r(h, p);
    if (nh < 0) return nullptr;
    std::vector<GeosGeom> crossing;
    std::vector<const GEOSGeometry*> inside;
    for (int i = 0; i < nh; ++i) {
      const GEOSGeometry* ring = GEOSGetInteriorRingN_r(h, p, i);
      Envelope e{};
      if (!envelope_of(h, ring, e)) return nullptr;
      if (e.x1 < x0 || e.x0 > x1 || e.y1 < y0 || e.y0 > y1) continue;  // misses the rectangle
      if (e.x0 > x0 && e.x1 < x1 && e.y0 > y0 && e.y1 < y1)
        inside.push_back(ring);
      else
        crossing.emplace_back(h, GEOSGeom_clone_r(h, ring));
    }
    GeosGeom reduced(
        h, polygon_of(h, GeosGeom(h, GEOSGeom_clone_r(h, GEOSGetExteriorRing_r(h, p))), crossing));
    if (!reduced) return nullptr;
    GeosGeom cut(h, GEOSIntersection_r(h, reduced.get(), rect.get()));
    if (!cut) return nullptr;
    std::vector<const GEOSGeometry*> pieces, rest;
    flatten(h, cut.get(), pieces, rest);
    for (const GEOSGeometry* o : rest) other.emplace_back(h, GEOSGeom_clone_r(h, o));

    // Each set-aside hole goes into the piece whose shell covers it (the
    // smallest such shell: an island piece inside another piece's hole).
    std::vector<std::vector<GeosGeom>> added(pieces.size());
    if (!inside.empty()) {
      if (pieces.empty()) return nullptr;
      std::vector<GeosGeom> shells;
      std::vector<double> shell_area(pieces.size(), 0.0);
      Tree tree(h);
      if (!tree.get()) return nullptr;
      std::vector<uint32_t> ids(pieces.size());
      std::iota(ids.begin(), ids.end(), 0u);
      for (size_t k = 0; k < pieces.size(); ++k) {
        shells.emplace_back(
            h, polygon_of(h, GeosGeom(h, GEOSGeom_clone_r(h, GEOSGetExteriorRing_r(h, pieces[k]))),
                          no_holes));
        if (!shells.back() || GEOSArea_r(h, shells.back().get(), &shell_area[k]) != 1)
          return nullptr;
        GEOSSTRtree_insert_r(h, tree.get(), shells.back().get(), &ids[k]);
      }
      std::vector<std::unique_ptr<Prepared>> prepared(pieces.size());
      Found found;
      for (const GEOSGeometry* ring : inside) {
        found.ids.clear();
        GEOSSTRtree_query_r(h, tree.get(), ring, &on_found, &found);
        std::sort(found.ids.begin(), found.ids.end());
        int64_t home = -1;
        for (const uint32_t k : found.ids) {
          if (home >= 0 && shell_area[k] >= shell_area[size_t(home)]) continue;
          if (!prepared[k]) prepared[k] = std::make_unique<Prepared>(h, shells[k].get());
          if (!prepared[k]->get()) return nullptr;
          const char c = GEOSPreparedCovers_r(h, prepared[k]->get(), ring);
          if (c == 2) return nullptr;
          if (c == 1) home = k;
        }
        if (home < 0) return nullptr;
        added[size_t(home)].emplace_back(h, GEOSGeom_clone_r(h, ring));
      }
    }
    for (size_t k = 0; k < pieces.size(); ++k) {
      if (added[k].empty()) {
        polys.emplace_back(h, GEOSGeom_clone_r(h, pieces[k]));
        continue;
      }
      std::vector<GeosGeom> hs;
      const int own = GEOSGetNumInteriorRings_r(h, pieces[k]);
      for (int j = 0; j < own; ++j)
        hs.emplace_back(h, GEOSGeom_clone_r(h, GEOSGetInteriorRingN_r(h, pieces[k], j)));
      for (GeosGeom& r : added[k]) hs.push_back(std::move(r));
      polys.emplace_back(
          h,
          polygon_of(h, GeosGeom(h, GEOSGeom_clone_r(h, GEOSGetExteriorRing_r(h, pieces[k]))), hs));
      if (!polys.back()) return nullptr;
    }
  }

  // Assembled as GEOS Intersection returns it: the area alone (a Polygon or
  // MultiPolygon; empty when nothing is left), or first in a
  // GeometryCollection with the lower-dimensional pieces.
  GeosGeom area = polys.size() == 1 ? std::move(polys[0]) : collection(h, GEOS_MULTIPOLYGON, polys);
  if (!area) return nullptr;
  if (other.empty()) return area.release();
  other.insert(other.begin(), std::move(area));
  return collection(h, GEOS_GEOMETRYCOLLECTION, other).release();
}

}  // namespace prep::detail
