// Stage 3 — clean. Projected parts -> valid, oriented, clipped, simplified
// SceneFeatures, with every repair and drop in the manifest (ARCHITECTURE.md "3. clean",
// §4.4). Parallel per part with oneTBB; each worker owns a GEOS context; the
// results are gathered in input order, so the output does not depend on the
// thread count.
#include "prep/clean.hpp"

#include <geos_c.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <unordered_set>

#include "detail/certainly_valid.hpp"
#include "detail/clip_many_holes.hpp"
#include "detail/repair_by_parts.hpp"
#include "geos_handle.hpp"
#include "prep/error.hpp"
#include "prep/feature_failure.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace prep {
namespace {

// ------------------------------------------------------------ GEOS context --

// A worker thread's GEOS context, and the part it is cleaning for the
// progress watchdog (prep/progress.hpp; null when progress is off).
struct WorkerContext : detail::GeosContext {
  ProgressWatch* watch = nullptr;
  void step(const char* operation) {
    if (watch) watch->operation(operation);
  }
};

using Geom = detail::GeosGeom;

// ------------------------------------------------------------- ring helpers --

// Removes consecutive duplicate vertices (zero-length segments); for rings
// also the wrap-around duplicate. Returns how many were removed.
size_t remove_duplicates(Ring& r, bool ring) {
  if (r.empty()) return 0;
  size_t w = 1;
  for (size_t i = 1; i < r.size(); ++i) {
    if (r[i].x != r[w - 1].x || r[i].y != r[w - 1].y) r[w++] = r[i];
  }
  size_t removed = r.size() - w;
  r.resize(w);
  if (ring) {
    while (r.size() > 1 && r.front().x == r.back().x && r.front().y == r.back().y) {
      r.pop_back();
      ++removed;
    }
  }
  return removed;
}

double signed_area(const Ring& r) {
  // Shoelace, relative to the first vertex for precision.
  double a = 0;
  if (r.size() < 3) return 0;
  const double x0 = r[0].x, y0 = r[0].y;
  for (size_t i = 1; i + 1 < r.size(); ++i) {
    a += (r[i].x - x0) * (r[i + 1].y - y0) - (r[i + 1].x - x0) * (r[i].y - y0);
  }
  return 0.5 * a;
}

GEOSGeometry* make_ring(GEOSContextHandle_t h, const Ring& r) {
  std::vector<double> xy;
  xy.reserve(2 * (r.size() + 1));
  for (const Point2& p : r) {
    xy.push_back(p.x);
    xy.push_back(p.y);
  }
  xy.push_back(r[0].x);
  xy.push_back(r[0].y);
  GEOSCoordSequence* cs = GEOSCoordSeq_copyFromBuffer_r(h, xy.data(), r.size() + 1, 0, 0);
  return GEOSGeom_createLinearRing_r(h, cs);
}

GEOSGeometry* make_line(GEOSContextHandle_t h, const Ring& r) {
  std::vector<double> xy;
  xy.reserve(2 * r.size());
  for (const Point2& p : r) {
    xy.push_back(p.x);
    xy.push_back(p.y);
  }
  GEOSCoordSequence* cs = GEOSCoordSeq_copyFromBuffer_r(h, xy.data(), r.size(), 0, 0);
  return GEOSGeom_createLineString_r(h, cs);
}

GEOSGeometry* make_polygon(GEOSContextHandle_t h, const std::vector<Ring>& rings) {
  GEOSGeometry* shell = make_ring(h, rings[0]);
  std::vector<GEOSGeometry*> holes;
  for (size_t i = 1; i < rings.size(); ++i) holes.push_back(make_ring(h, rings[i]));
  return GEOSGeom_createPolygon_r(h, shell, holes.data(), static_cast<unsigned>(holes.size()));
}

// Reads a GEOS line string / ring into a Ring; drops the closing point when
// `drop_closing`.
Ring read_coords(GEOSContextHandle_t h, const GEOSGeometry* g, bool drop_closing) {
  const GEOSCoordSequence* cs = GEOSGeom_getCoordSeq_r(h, g);
  unsigned n = 0;
  GEOSCoordSeq_getSize_r(h, cs, &n);
  std::vector<double> xy(2 * size_t(n));
  if (n > 0) GEOSCoordSeq_copyToBuffer_r(h, cs, xy.data(), 0, 0);
  Ring r(n);
  for (unsigned i = 0; i < n; ++i) r[i] = {xy[2 * i], xy[2 * i + 1]};
  if (drop_closing && n > 1 && r.front().x == r.back().x && r.front().y == r.back().y) r.pop_back();
  return r;
}

// The rings of a GEOS polygon, oriented as ARCHITECTURE.md "3. clean" says:
// shell counter-clockwise, holes clockwise.
void read_oriented_rings(GEOSContextHandle_t h, const GEOSGeometry* poly, Ring& shell,
                         std::vector<Ring>& holes) {
  shell = read_coords(h, GEOSGetExteriorRing_r(h, poly), true);
  if (signed_area(shell) < 0) std::reverse(shell.begin(), shell.end());
  const int nh = GEOSGetNumInteriorRings_r(h, poly);
  holes.clear();
  for (int i = 0; i < nh; ++i) {
    Ring hole = read_coords(h, GEOSGetInteriorRingN_r(h, poly, i), true);
    if (signed_area(hole) > 0) std::reverse(hole.begin(), hole.end());
    holes.push_back(std::move(hole));
  }
}

// GEOS's isValid of a geometry, with a polygon decided by the sweep of
// detail/certainly_valid.hpp where it can (near-linear time; GEOS places
// each hole by a walk over the whole shell) and by GEOS where the sweep is
// unsure or a ring is too short for it: the same answer either way
// (tests/clean/test_validity_touching.cpp).
bool geos_valid(GEOSContextHandle_t h, const GEOSGeometry* g) {
  if (GEOSGeomTypeId_r(h, g) == GEOS_POLYGON && GEOSisEmpty_r(h, g) == 0) {
    std::vector<Ring> rings;
    const int nh = GEOSGetNumInteriorRings_r(h, g);
    rings.reserve(1 + size_t(std::max(nh, 0)));
    rings.push_back(read_coords(h, GEOSGetExteriorRing_r(h, g), true));
    for (int i = 0; i < nh; ++i)
      rings.push_back(read_coords(h, GEOSGetInteriorRingN_r(h, g, i), true));
    const bool sweepable =
        std::all_of(rings.begin(), rings.end(), [](const Ring& r) { return r.size() >= 3; });
    if (sweepable) {
      switch (detail::polygon_validity(rings)) {
        case detail::Validity::valid: return true;
        case detail::Validity::invalid: return false;
        case detail::Validity::unsure: break;
      }
    }
  }
  return GEOSisValid_r(h, g) == 1;
}

// Collects the polygons (or line strings) of any geometry, recursively.
void collect(GEOSContextHandle_t h, const GEOSGeometry* g, int want_type,
             std::vector<const GEOSGeometry*>& out, bool& had_other) {
  int type = GEOSGeomTypeId_r(h, g);
  if (type == GEOS_MULTIPOLYGON || type == GEOS_MULTILINESTRING ||
      type == GEOS_GEOMETRYCOLLECTION) {
    int n = GEOSGetNumGeometries_r(h, g);
    for (int i = 0; i < n; ++i) collect(h, GEOSGetGeometryN_r(h, g, i), want_type, out, had_other);
    return;
  }
  if (type == GEOS_LINEARRING) type = GEOS_LINESTRING;
  if (type == want_type) {
    if (!GEOSisEmpty_r(h, g)) out.push_back(g);
  } else if (!GEOSisEmpty_r(h, g)) {
    had_other = true;
  }
}

size_t vertex_count(GEOSContextHandle_t h, const GEOSGeometry* g) {
  int n = GEOSGetNumCoordinates_r(h, g);
  return n > 0 ? size_t(n) : 0;
}

// ------------------------------------------------- validity fast path --
//
// Parts that detail/certainly_valid.hpp proves valid, inside the extent and
// with nothing to simplify skip the GEOS round trip; these reproduce what
// GEOS would report for them.

// GEOS's shoelace (Area::ofRingSigned) over the closed ring, so the fast
// path reports the very area GEOS would.
double geos_ring_area(const Ring& r) {
  const size_t n = r.size() + 1;  // closed
  if (n < 3) return 0.0;
  auto at = [&](size_t i) -> const Point2& { return r[i % r.size()]; };
  const double x0 = at(0).x;
  double p1x = at(0).x, p1y = at(0).y;
  double p2x = at(1).x - x0, p2y = at(1).y;
  double sum = 0.0;
  for (size_t i = 1; i < n - 1; ++i) {
    const double p0y = p1y;
    p1x = p2x;
    p1y = p2y;
    p2x = at(i + 1).x - x0;
    p2y = at(i + 1).y;
    sum += p1x * (p0y - p2y);
  }
  return std::fabs(sum / 2.0);
}

// GEOS's Length::ofLine.
double geos_line_length(const Ring& pts) {
  double len = 0.0;
  for (size_t i = 1; i < pts.size(); ++i) {
    const double dx = pts[i].x - pts[i - 1].x, dy = pts[i].y - pts[i - 1].y;
    len += std::sqrt(dx * dx + dy * dy);
  }
  return len;
}

// ----------------------------------------------------------- part outcome --

enum class Outcome { kept, clipped_away, dropped };

struct PartResult {
  Outcome outcome = Outcome::kept;
  std::string repairs;  // "; "-joined; empty: untouched
  std::string drop_reason;
  std::optional<FailureStage> failed_in;  // set: drop_reason is a per-feature failure
  double area_before = std::numeric_limits<double>::quiet_NaN();
  double area_after = std::numeric_limits<double>::quiet_NaN();
  uint64_t vertices_in = 0, vertices_out = 0;
  std::vector<ScenePolygon> polygons;
  std::vector<SceneLine> lines;
};

void add_repair(PartResult& r, const std::string& what) {
  if (!r.repairs.empty()) r.repairs += "; ";
  r.repairs += what;
}

struct Cleaner {
  const std::optional<Extent>& clip;
  double resolution;
  RepairMethod repair = RepairMethod::linework;
  // CleanOptions::test_geos_failure_fid (tests only; prep/clean.hpp).
  std::optional<int64_t> geos_fail_fid;

  // The feature whose simplification is made to fail (tolerance -1, which
  // GEOS rejects: "Tolerance must be non-negative").
  bool fails_on_purpose(const SourceFeature& f) const {
    return geos_fail_fid && f.fid == *geos_fail_fid;
  }

  // GEOS MakeValid with the scene's method (prep/spec.hpp RepairMethod).
  GEOSGeometry* make_valid(GEOSContextHandle_t h, const GEOSGeometry* g) const {
    if (repair == RepairMethod::linework) return GEOSMakeValid_r(h, g);
    GEOSMakeValidParams* params = GEOSMakeValidParams_create_r(h);
    if (!params) return nullptr;
    GEOSMakeValidParams_setMethod_r(h, params, GEOS_MAKE_VALID_STRUCTURE);
    // Collapsed (zero-area) pieces are not kept: only polygons are used.
    GEOSMakeValidParams_setKeepCollapsed_r(h, params, 0);
    GEOSGeometry* fixed = GEOSMakeValidWithParams_r(h, g, params);
    GEOSMakeValidParams_destroy_r(h, params);
    return fixed;
  }

  double tolerance_for(const SourceFeature& f) const {
    return fails_on_purpose(f) ? -1.0 : resolution;
  }

  // Topology-preserving simplification of one part to the scene resolution:
  // `out` stays empty when there is nothing to simplify. False (and the
  // feature recorded as failed) when GEOS reports an error.
  bool simplify(WorkerContext& ctx, const SourceFeature& f, const GEOSGeometry* part, Geom& out,
                PartResult& r) const {
    if (!(resolution > 0) && !fails_on_purpose(f)) return true;
    ctx.step("GEOS TopologyPreserveSimplify");
    out = Geom(ctx.handle(), GEOSTopologyPreserveSimplify_r(ctx.handle(), part, tolerance_for(f)));
    if (!out) fail(r, "GEOS simplification failed: " + ctx.last_error());
    return bool(out);
  }

  // A per-feature failure (feature_failure.hpp): recorded here, turned into
  // an error or a drop in input order by LayerGather.
  static void fail(PartResult& r, const std::string& what) {
    r.outcome = Outcome::dropped;
    r.drop_reason = what;
    r.failed_in = FailureStage::clean;
    r.polygons.clear();
    r.lines.clear();
  }

  // Clip rectangle as a GEOS polygon, built per context on demand.
  GEOSGeometry* clip_rect(GEOSContextHandle_t h) const {
    const Extent& e = *clip;
    return GEOSGeom_createRectangle_r(h, e.xmin, e.ymin, e.xmax, e.ymax);
  }

  // -1 fully outside, 1 fully inside (or no clip), 0 crosses the border.
  int clip_relation(const std::vector<Ring>& rings) const {
    if (!clip) return 1;
    Extent b = no_points();
    for (const Ring& r : rings) extend(b, r);
    const Extent& c = *clip;
    if (b.xmin >= c.xmin && b.xmax <= c.xmax && b.ymin >= c.ymin && b.ymax <= c.ymax) return 1;
    if (b.xmax < c.xmin || b.xmin > c.xmax || b.ymax < c.ymin || b.ymin > c.ymax) return -1;
    return 0;
  }

  // ------------------------------------------------------------ polygons --

  // §1.3 for one polygon part: dedupe, validity, clip, simplify, orient.
  // Takes the part's rings (f.rings is left empty).
  void polygon(WorkerContext& ctx, SourceFeature& f, PartResult& r) const {
    GEOSContextHandle_t h = ctx.handle();
    std::vector<Ring> rings = std::move(f.rings);
    if (!remove_degenerate(rings, r)) return;
    int rel = clip_relation(rings);
    if (rel < 0) {
      r.outcome = Outcome::clipped_away;
      return;
    }
    // Proven valid, inside the extent, nothing to simplify: GEOS would hand
    // the rings back unchanged (emit_rings reproduces what it reports).
    ctx.step("the validity sweep");
    const bool proven = detail::certainly_valid(rings);
    if (proven && rel == 1 && !(resolution > 0) && !fails_on_purpose(f)) {
      emit_rings(f, std::move(rings), r);
      return;
    }
    Geom g(h, make_polygon(h, rings));
    if (!g) return fail(r, "GEOS cannot build the polygon: " + ctx.last_error());
    ctx.step("GEOS isValid");
    if (!proven && !make_valid_if_invalid(ctx, g, rings, rel == 0 ? &*clip : nullptr, r)) return;
    if (rel == 0) {
      // Many holes: the holes outside or inside the extent stay out of the
      // overlay (detail/clip_many_holes.hpp: the same area).
      ctx.step("GEOS Intersection with the extent by holes");
      const Extent& c = *clip;
      Geom cut(h, detail::clip_many_holes(h, g.get(), c.xmin, c.ymin, c.xmax, c.ymax));
      if (!cut) {
        ctx.step("GEOS Intersection with the extent");
        Geom rect(h, clip_rect(h));
        cut = Geom(h, GEOSIntersection_r(h, g.get(), rect.get()));
      }
      if (!cut)
        return fail(r, "GEOS intersection with the clip extent failed: " + ctx.last_error());
      g = std::move(cut);
    }
    std::vector<const GEOSGeometry*> parts;
    bool other = false;
    collect(h, g.get(), GEOS_POLYGON, parts, other);
    if (other && rel != 0) add_repair(r, "discarded collapsed (non-areal) pieces");
    if (parts.empty()) {
      if (rel == 0) {
        r.outcome = Outcome::clipped_away;
      } else {
        r.outcome = Outcome::dropped;
        r.drop_reason = "zero area" + (r.repairs.empty() ? std::string() : " after: " + r.repairs);
      }
      return;
    }
    simplify_and_emit_polygons(ctx, f, parts, r);
  }

  // Removes duplicate vertices and holes with fewer than 3 distinct
  // vertices, recording both. False: the shell itself is degenerate (the
  // part is dropped).
  static bool remove_degenerate(std::vector<Ring>& rings, PartResult& r) {
    size_t dups = 0;
    for (Ring& ring : rings) dups += remove_duplicates(ring, true);
    if (dups > 0) add_repair(r, "removed " + std::to_string(dups) + " duplicate vertices");
    if (rings[0].size() < 3) {
      r.outcome = Outcome::dropped;
      r.drop_reason =
          "zero area: shell has " + std::to_string(rings[0].size()) + " distinct vertices";
      return false;
    }
    for (size_t i = 1; i < rings.size();) {
      if (rings[i].size() < 3) {
        add_repair(r, "removed degenerate hole " + std::to_string(i));
        rings.erase(rings.begin() + static_cast<std::ptrdiff_t>(i));
      } else {
        ++i;
      }
    }
    return true;
  }

  // What GEOS isValidReason answers for a valid geometry (its C API).
  static constexpr const char* kGeosValid = "Valid Geometry";

  // GEOS isValid, and GEOS MakeValid when it says invalid: `g` (built from
  // `rings`) becomes the repair, recorded with the area before and after
  // when they differ. False: the feature failed (GEOS error, or a repair
  // that is still invalid). A polygon with many holes is repaired by parts
  // (detail/repair_by_parts.hpp: the same result as MakeValid of the whole,
  // without its time quadratic in the holes); when that does not apply or
  // its result is not valid, the whole polygon is repaired. `window`: the
  // extent the part is clipped to next (null: none); the repair by parts
  // is then the whole repair inside it only.
  bool make_valid_if_invalid(WorkerContext& ctx, Geom& g, const std::vector<Ring>& rings,
                             const Extent* window, PartResult& r) const {
    GEOSContextHandle_t h = ctx.handle();
    // One validation, not isValid and then isValidReason: both run GEOS
    // IsValidOp, which on a large polygon nodes every ring (half a second
    // for the 1.8e6 vertices of bench/clean_real.py's world ocean).
    char* why = GEOSisValidReason_r(h, g.get());
    std::string reason = why ? why : "invalid";
    GEOSFree_r(h, why);
    if (reason == kGeosValid) return true;
    const double before = GEOSArea_r(h, g.get(), &r.area_before) ? r.area_before : NAN;
    Geom fixed;
    detail::LeftOut left_out;
    if (rings.size() > detail::kRepairByPartsMinHoles) {
      // The part is clipped to `window` next (when given): hole groups
      // whose envelope misses it are left out of the repair.
      detail::Envelope w{};
      if (window) w = {window->xmin, window->ymin, window->xmax, window->ymax};
      ctx.step(repair == RepairMethod::structure ? "GEOS MakeValid by parts (structure)"
                                                 : "GEOS MakeValid by parts");
      // Valid when not null (checked piece by piece: GEOS isValid of the
      // whole repair costs holes x shell vertices).
      fixed = Geom(h, detail::make_valid_by_parts(
                          h, g.get(), rings,
                          [&](GEOSContextHandle_t th, const GEOSGeometry* part) {
                            return make_valid(th, part);
                          },
                          window ? &w : nullptr, &left_out));
    }
    if (!fixed) {
      left_out = detail::LeftOut{};
      ctx.step(repair == RepairMethod::structure ? "GEOS MakeValid (structure)" : "GEOS MakeValid");
      fixed = Geom(h, make_valid(h, g.get()));
      if (!fixed) {
        fail(r, "invalid (" + reason + ") and GEOS MakeValid failed: " + ctx.last_error());
        return false;
      }
      // A repair that is still invalid would break point-in-polygon later.
      ctx.step("GEOS isValid of the repair");
      if (GEOSisValid_r(h, fixed.get()) != 1) {
        char* still = GEOSisValidReason_r(h, fixed.get());
        const std::string after_reason = still ? still : "invalid";
        GEOSFree_r(h, still);
        fail(r, "invalid (" + reason + ") and still invalid after GEOS MakeValid (" + after_reason +
                    ")");
        return false;
      }
    }
    double after = 0;
    GEOSArea_r(h, fixed.get(), &after);
    after -= left_out.lone_hole_area;  // the whole repair's area
    // Hole groups that needed a repair of their own left out (outside the
    // extent): the area of the whole repair is not known, only the part
    // inside the extent was repaired to the end.
    const bool measured = left_out.groups == 0;
    add_repair(r, "made valid (" + reason + ")" +
                      (repair == RepairMethod::structure ? " by the structure method" : "") +
                      (measured ? "" : " inside the scene extent"));
    if (!measured) {
      r.area_before = before;
      r.area_after = NAN;
    } else if (!(std::fabs(after - before) <= 1e-6 * std::fabs(before))) {
      r.area_before = before;
      r.area_after = after;
    } else {
      r.area_before = r.area_after = NAN;
    }
    g = std::move(fixed);
    return true;
  }

  // Simplifies each clipped piece (counting its vertices in) and hands
  // emit() the pieces of `type` (GEOS_POLYGON or GEOS_LINESTRING) of the
  // result; false when a simplification failed (recorded in r).
  template <class Emit>
  bool simplify_pieces(WorkerContext& ctx, const SourceFeature& f,
                       const std::vector<const GEOSGeometry*>& parts, int type, PartResult& r,
                       Emit&& emit) const {
    GEOSContextHandle_t h = ctx.handle();
    for (const GEOSGeometry* p : parts) {
      r.vertices_in += vertex_count(h, p);
      Geom simple;
      if (!simplify(ctx, f, p, simple, r)) return false;
      if (type == GEOS_POLYGON) {
        // Simplification is topology-preserving; keep the unsimplified part
        // if GEOS ever disagrees.
        ctx.step("validity of the simplified part");
        if (simple && !geos_valid(h, simple.get())) simple = Geom();
      }
      std::vector<const GEOSGeometry*> pieces;
      bool ignored = false;
      collect(h, simple ? simple.get() : p, type, pieces, ignored);
      for (const GEOSGeometry* piece : pieces) emit(piece);
    }
    return true;
  }

  // Simplifies each valid, clipped polygon piece and emits what is left.
  void simplify_and_emit_polygons(WorkerContext& ctx, const SourceFeature& f,
                                  const std::vector<const GEOSGeometry*>& parts,
                                  PartResult& r) const {
    if (!simplify_pieces(ctx, f, parts, GEOS_POLYGON, r,
                         [&](const GEOSGeometry* poly) { emit_polygon(ctx.handle(), f, poly, r); }))
      return;
    if (r.polygons.empty()) {
      r.outcome = Outcome::dropped;
      r.drop_reason = "collapsed to zero area under simplification";
    }
  }
  // emit_polygon for a part proven valid, without the GEOS round trip: the
  // same rings, counts and (GEOS's) area.
  static void emit_rings(const SourceFeature& f, std::vector<Ring> rings, PartResult& r) {
    ScenePolygon out;
    static_cast<FeatureKeys&>(out) = f;
    double area = geos_ring_area(rings[0]);
    for (size_t i = 1; i < rings.size(); ++i) area -= geos_ring_area(rings[i]);
    out.area = area;
    for (const Ring& ring : rings) r.vertices_in += ring.size() + 1;
    out.shell = std::move(rings[0]);
    // Orientation (ARCHITECTURE.md "3. clean"): shell counter-clockwise, holes clockwise.
    if (signed_area(out.shell) < 0) std::reverse(out.shell.begin(), out.shell.end());
    for (size_t i = 1; i < rings.size(); ++i) {
      Ring hole = std::move(rings[i]);
      if (signed_area(hole) > 0) std::reverse(hole.begin(), hole.end());
      out.holes.push_back(std::move(hole));
    }
    r.vertices_out += out.shell.size() + 1;
    for (const Ring& hole : out.holes) r.vertices_out += hole.size() + 1;
    r.polygons.push_back(std::move(out));
  }

  void emit_polygon(GEOSContextHandle_t h, const SourceFeature& f, const GEOSGeometry* poly,
                    PartResult& r) const {
    ScenePolygon out;
    static_cast<FeatureKeys&>(out) = f;
    read_oriented_rings(h, poly, out.shell, out.holes);
    GEOSArea_r(h, poly, &out.area);
    r.vertices_out += out.shell.size() + 1;
    for (const Ring& hole : out.holes) r.vertices_out += hole.size() + 1;
    r.polygons.push_back(std::move(out));
  }

  // --------------------------------------------------------------- lines --

  // A point layer's part: outside the extent it is clipped away; inside,
  // a line from the point kPointStep along +x, which every renderer draws
  // as a round dot of the line's width (formats/SPEC.md "Points").
  void point(const SourceFeature& f, PartResult& r) const {
    const Point2 p = f.rings[0][0];
    r.vertices_in = r.vertices_out = 1;
    if (clip &&
        !(p.x >= clip->xmin && p.x <= clip->xmax && p.y >= clip->ymin && p.y <= clip->ymax)) {
      r.outcome = Outcome::clipped_away;
      return;
    }
    SceneLine out;
    out.points = {p, {p.x + kPointStep, p.y}};
    static_cast<FeatureKeys&>(out) = f;
    r.lines.push_back(std::move(out));
  }

  // Takes the part's points (f.rings[0] is left empty).
  void line(WorkerContext& ctx, SourceFeature& f, PartResult& r) const {
    GEOSContextHandle_t h = ctx.handle();
    Ring pts = std::move(f.rings[0]);
    const bool was_closed =
        pts.size() >= 3 && pts.front().x == pts.back().x && pts.front().y == pts.back().y;
    size_t dups = remove_duplicates(pts, false);
    if (dups > 0) add_repair(r, "removed " + std::to_string(dups) + " duplicate vertices");
    if (pts.size() < 2) {
      r.outcome = Outcome::dropped;
      r.drop_reason = "zero length: " + std::to_string(pts.size()) + " distinct vertices";
      return;
    }
    int rel = clip_relation({pts});
    if (rel < 0) {
      r.outcome = Outcome::clipped_away;
      return;
    }
    if (rel == 1 && !(resolution > 0) && !fails_on_purpose(f)) {
      emit_points(f, std::move(pts), was_closed, r);
      return;
    }
    Geom g(h, make_line(h, pts));
    if (!g) return fail(r, "GEOS cannot build the line: " + ctx.last_error());
    if (rel == 0) {
      ctx.step("GEOS Intersection with the extent");
      Geom rect(h, clip_rect(h));
      Geom cut(h, GEOSIntersection_r(h, g.get(), rect.get()));
      if (!cut)
        return fail(r, "GEOS intersection with the clip extent failed: " + ctx.last_error());
      // Pieces that meet at a vertex are joined again.
      Geom merged(h, GEOSLineMerge_r(h, cut.get()));
      g = merged ? std::move(merged) : std::move(cut);
    }
    std::vector<const GEOSGeometry*> parts;
    bool other = false;
    collect(h, g.get(), GEOS_LINESTRING, parts, other);
    if (parts.empty()) {
      r.outcome = Outcome::clipped_away;
      return;
    }
    // Only an unclipped closed line can stay closed.
    simplify_and_emit_lines(ctx, f, parts, was_closed && rel == 1, r);
  }

  // A line inside the extent with nothing to simplify: GEOS would hand the
  // points back unchanged; the same counts and (GEOS's) length without it.
  static void emit_points(const SourceFeature& f, Ring pts, bool was_closed, PartResult& r) {
    SceneLine out;
    r.vertices_in += pts.size();
    r.vertices_out += pts.size();
    out.length = geos_line_length(pts);
    out.points = std::move(pts);
    close_if_ends_meet(out, was_closed);
    static_cast<FeatureKeys&>(out) = f;
    r.lines.push_back(std::move(out));
  }

  // A line whose first and last points are equal (and that may close) is
  // a closed line of the points without the repeated last one.
  static void close_if_ends_meet(SceneLine& out, bool may_close) {
    out.closed = may_close && out.points.size() >= 4 &&
                 out.points.front().x == out.points.back().x &&
                 out.points.front().y == out.points.back().y;
    if (out.closed) out.points.pop_back();
  }

  // Simplifies each (clipped) line piece and emits what is left; a piece
  // stays a closed line when `may_close` and its ends meet.
  void simplify_and_emit_lines(WorkerContext& ctx, const SourceFeature& f,
                               const std::vector<const GEOSGeometry*>& parts, bool may_close,
                               PartResult& r) const {
    GEOSContextHandle_t h = ctx.handle();
    if (!simplify_pieces(ctx, f, parts, GEOS_LINESTRING, r, [&](const GEOSGeometry* l) {
          SceneLine out;
          out.points = read_coords(h, l, false);
          r.vertices_out += out.points.size();
          close_if_ends_meet(out, may_close);
          if (out.points.size() < 2) return;
          static_cast<FeatureKeys&>(out) = f;
          double len = 0;
          GEOSLength_r(h, l, &len);
          out.length = len;
          r.lines.push_back(std::move(out));
        }))
      return;
    if (r.lines.empty()) {
      r.outcome = Outcome::dropped;
      r.drop_reason = "collapsed under simplification";
    }
  }
};

// ------------------------------------------------------- one part, a layer --

// Why GEOS must not see this part (empty: it may). Read rejects NaN/Inf,
// but a transform can still yield them; GEOS must never see one (its
// quad-tree index loops forever on a NaN envelope inside
// TopologyPreserveSimplify: found by fuzz_model). Nor a coordinate near
// DBL_MAX (the quad-tree's 2^level overflows to inf, the same endless loop;
// found by fuzz_model with a frame equal to the source CRS). Nothing on
// Earth lies kMaxCoordinate from the origin of any frame, so such a vertex
// is a failure of the feature.
std::string unsafe_vertex(const SourceFeature& f) {
  constexpr double kMaxCoordinate = 1e9;  // metres
  for (size_t ri = 0; ri < f.rings.size(); ++ri)
    for (size_t v = 0; v < f.rings[ri].size(); ++v) {
      const Point2& q = f.rings[ri][v];
      if (!std::isfinite(q.x) || !std::isfinite(q.y))
        return "ring " + std::to_string(ri) + " vertex " + std::to_string(v) +
               " has a non-finite coordinate";
      if (std::fabs(q.x) > kMaxCoordinate || std::fabs(q.y) > kMaxCoordinate) {
        char text[160];
        std::snprintf(text, sizeof text,
                      "ring %zu vertex %zu at (%.17g, %.17g) is more than 1e9 m from the "
                      "scene origin",
                      ri, v, q.x, q.y);
        return text;
      }
    }
  return {};
}

// Cleans one part into `r` (taking its coordinates): parts read or project
// already dropped stay dropped with their reason; an unsafe vertex or an
// exception fails the feature. The progress watchdog names the part while
// it is here (in GEOS) too long.
void clean_part(const Cleaner& cleaner, WorkerContext& ctx, ProgressStage& stage,
                const std::string& layer, SourceFeature& f, PartResult& r) {
  if (!f.drop_reason.empty() || f.rings.empty() || f.rings[0].empty()) {
    r.outcome = Outcome::dropped;
    r.drop_reason = f.drop_reason.empty() ? "no coordinates" : f.drop_reason;
    r.failed_in = f.failed_in;
    return;
  }
  const std::string bad = unsafe_vertex(f);
  if (!bad.empty()) return Cleaner::fail(r, bad);
  if (!f.repairs.empty()) add_repair(r, f.repairs);
  uint64_t vertices = 0;
  for (const Ring& ring : f.rings) vertices += ring.size();
  ProgressWatch watch = stage.watch(layer, f.fid, vertices, "clean");
  ctx.watch = &watch;
  try {
    if (f.is_point)
      cleaner.point(f, r);
    else if (f.is_polygon)
      cleaner.polygon(ctx, f, r);
    else
      cleaner.line(ctx, f, r);
  } catch (const std::bad_alloc&) {
    ctx.watch = nullptr;
    throw;  // not this feature's fault: the build is out of memory
  } catch (const std::exception& e) {
    Cleaner::fail(r, e.what());
  }
  ctx.watch = nullptr;
}

// Cleans every part of `layer` in parallel (one GEOS context per worker
// thread); the results are in input order.
std::vector<PartResult> clean_parts(const Cleaner& cleaner,
                                    tbb::enumerable_thread_specific<WorkerContext>& contexts,
                                    ProgressStage& stage, SourceLayer& layer) {
  std::vector<PartResult> results(layer.features.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, layer.features.size(), 16),
                    [&](const tbb::blocked_range<size_t>& range) {
                      WorkerContext& ctx = contexts.local();
                      for (size_t i = range.begin(); i != range.end(); ++i) {
                        struct CountPart {  // one part done, whichever way it leaves
                          ProgressStage& stage;
                          ~CountPart() { stage.add(); }
                        } count_part{stage};
                        clean_part(cleaner, ctx, stage, layer.spec.name, layer.features[i],
                                   results[i]);
                      }
                    });
  return results;
}

// ------------------------------------------------------------- gathering --

// Gathers one layer's part results into the scene, feature by feature in
// input order (deterministic at any thread count), with the manifest
// entries and the layer's counts.
class LayerGather {
 public:
  LayerGather(const SceneSpec& scene, const LayerSpec& spec, uint32_t layer_index,
              const Manifest& read_manifest)
      : scene_(scene), spec_(spec), layer_index_(layer_index) {
    for (const LayerCounts& c : read_manifest.layers)
      if (c.layer == spec_.name) counts_ = c;
    counts_.layer = spec_.name;
    counts_.kept = counts_.repaired = counts_.clipped_away = counts_.dropped = 0;
    counts_.parts = counts_.vertices_in = counts_.vertices_out = 0;
  }

  // Every feature of `features` (whole features; a layer may come in
  // several calls, in input order) into `out`.
  void gather(SceneFeatures& out, const std::vector<SourceFeature>& features,
              const std::vector<double>& scale, std::vector<PartResult>& results) {
    out_ = &out;
    features_ = &features;
    scale_ = &scale;
    gather(results);
  }

  // Every feature (a run of parts with the same feature index).
  void gather(std::vector<PartResult>& results) {
    const std::vector<SourceFeature>& features = *features_;
    size_t i = 0;
    while (i < features.size()) {
      size_t j = i;
      while (j < features.size() && features[j].feature == features[i].feature) ++j;
      add_feature(i, j, results);
      i = j;
    }
  }

  // The layer's counts; read == kept + clipped_away + dropped, or an error.
  const LayerCounts& counts() const {
    const LayerCounts& c = counts_;
    if (c.kept + c.clipped_away + c.dropped != c.read) {
      fail<error>(kCleanStage, "layer '" + spec_.name + "': accounting mismatch: read " +
                                   std::to_string(c.read) + " != kept " + std::to_string(c.kept) +
                                   " + clipped " + std::to_string(c.clipped_away) + " + dropped " +
                                   std::to_string(c.dropped));
    }
    return c;
  }

 private:
  // Parts [first, end) of one feature.
  void add_feature(size_t first, size_t end, std::vector<PartResult>& results) {
    // A failing part fails its whole feature (ogr2ogr -skipfailures drops
    // features, not parts); without skip_failures it stops the build.
    const std::vector<SourceFeature>& features = *features_;
    const std::vector<double>& scale = *scale_;
    for (size_t p = first; p < end; ++p)
      if (results[p].outcome == Outcome::dropped && results[p].failed_in)
        return add_failure(features[first], results[p]);
    bool any_kept = false, any_dropped = false, any_repaired = false;
    std::string first_drop;
    for (size_t p = first; p < end; ++p) {
      if (results[p].outcome == Outcome::kept) any_kept = true;
      if (results[p].outcome == Outcome::dropped) {
        any_dropped = true;
        if (first_drop.empty()) first_drop = results[p].drop_reason;
      }
    }
    for (size_t p = first; p < end; ++p)
      add_part(results[p], features[p], scale[p], any_kept, any_repaired);
    const int64_t fid = features[first].fid;
    if (any_kept) {
      ++counts_.kept;
      if (any_repaired) ++counts_.repaired;
    } else if (any_dropped) {
      ++counts_.dropped;
      out_->manifest.entries.push_back({spec_.name, fid, -1, ManifestAction::dropped, first_drop});
    } else {
      ++counts_.clipped_away;
      out_->manifest.entries.push_back(
          {spec_.name, fid, -1, ManifestAction::clipped_away, "outside the scene extent"});
    }
  }

  void add_failure(const SourceFeature& head, const PartResult& failure) {
    if (!scene_.skip_failures)
      fail_feature(*failure.failed_in, spec_.source, spec_.name, head.fid, failure.drop_reason);
    ++counts_.dropped;
    ManifestEntry e{spec_.name, head.fid, -1, ManifestAction::dropped, failure.drop_reason};
    e.failed_in = failure.failed_in;
    out_->manifest.entries.push_back(std::move(e));
  }

  // One part of a feature without failures; `kf` is the frame's point scale
  // factor there. Sets `any_repaired` when the part was repaired.
  void add_part(PartResult& r, const SourceFeature& f, double kf, bool any_kept,
                bool& any_repaired) {
    if (r.outcome == Outcome::kept) {
      counts_.vertices_in += r.vertices_in;
      counts_.vertices_out += r.vertices_out;
      if (!r.repairs.empty()) {
        any_repaired = true;
        out_->manifest.entries.push_back({spec_.name, f.fid, f.part, ManifestAction::repaired,
                                          r.repairs, r.area_before, r.area_after});
      }
      for (ScenePolygon& poly : r.polygons) add_polygon(poly, kf);
      for (SceneLine& l : r.lines) {
        // Widths are ground metres; the frame's metres are k times
        // longer or shorter (ARCHITECTURE.md "2. project").
        l.length /= kf;
        add_line(std::move(l), kf);
      }
    } else if (r.outcome == Outcome::dropped && any_kept) {
      out_->manifest.entries.push_back(
          {spec_.name, f.fid, f.part, ManifestAction::part_dropped, r.drop_reason});
    }
  }

  void add_polygon(ScenePolygon& poly, double kf) {
    poly.layer = layer_index_;
    if (spec_.kind != DecalKind::outline) {
      out_->polygons.push_back(std::move(poly));
      ++counts_.parts;
      return;
    }
    // Outline decals: the rings as closed lines, shell CCW and holes CW, so
    // "inset" (left side) is the polygon's interior.
    if (spec_.shared_edges_once) {
      add_outline_ring_once(poly, poly.shell, kf);
      for (const Ring& hole : poly.holes) add_outline_ring_once(poly, hole, kf);
      return;
    }
    add_outline_ring(poly, poly.shell, kf);
    for (const Ring& hole : poly.holes) add_outline_ring(poly, hole, kf);
  }

  // The length of a closed ring, its closing edge included.
  static double perimeter(const Ring& ring) {
    double len = 0;
    for (size_t q = 0; q < ring.size(); ++q) {
      const Point2& a = ring[q];
      const Point2& b = ring[(q + 1) % ring.size()];
      len += std::hypot(b.x - a.x, b.y - a.y);
    }
    return len;
  }

  // An edge with its ends in a fixed order, as the bits of its doubles.
  struct EdgeKey {
    uint64_t v[4];
    bool operator==(const EdgeKey& o) const { return std::memcmp(v, o.v, sizeof v) == 0; }
  };
  struct EdgeHash {
    size_t operator()(const EdgeKey& k) const {
      uint64_t h = 0x9e3779b97f4a7c15ull;
      for (uint64_t x : k.v) h = (h ^ x) * 0x100000001b3ull + (h >> 29);
      return size_t(h);
    }
  };
  static EdgeKey edge_key(const Point2& a, const Point2& b) {
    const bool ab = a.x < b.x || (a.x == b.x && a.y <= b.y);
    const Point2& p = ab ? a : b;
    const Point2& q = ab ? b : a;
    EdgeKey k;
    std::memcpy(&k.v[0], &p.x, 8);
    std::memcpy(&k.v[1], &p.y, 8);
    std::memcpy(&k.v[2], &q.x, 8);
    std::memcpy(&k.v[3], &q.y, 8);
    return k;
  }

  // shared_edges = "once": each edge of the layer's rings is drawn by the
  // first ring that has it (the same two vertices, either way round, in
  // scene order); a ring that lost edges to earlier rings is drawn as the
  // open runs of the edges it keeps, so each shared boundary is one line
  // with one dash phase. The drawing-order length stays the ring's.
  void add_outline_ring_once(const ScenePolygon& poly, const Ring& ring, double kf) {
    const size_t n = ring.size();
    std::vector<char> keep(n);
    size_t kept = 0;
    for (size_t q = 0; q < n; ++q) {
      keep[q] = seen_edges_.insert(edge_key(ring[q], ring[(q + 1) % n])).second;
      kept += keep[q];
    }
    if (kept == n) return add_outline_ring(poly, ring, kf);
    if (kept == 0) return;
    const double len = perimeter(ring);
    // Start at a kept edge after a dropped one; each run of kept edges is a line.
    size_t start = 0;
    while (!(keep[start] && !keep[(start + n - 1) % n])) ++start;
    SceneLine l;
    for (size_t k = 0; k <= n; ++k) {
      const size_t q = (start + k) % n;
      if (k < n && keep[q]) {
        if (l.points.empty()) l.points.push_back(ring[q]);
        l.points.push_back(ring[(q + 1) % n]);
        continue;
      }
      if (!l.points.empty()) {
        static_cast<FeatureKeys&>(l) = poly;
        l.closed = false;
        l.length = len / kf;
        add_line(std::move(l), kf);
        l = SceneLine{};
      }
    }
  }

  void add_outline_ring(const ScenePolygon& poly, const Ring& ring, double kf) {
    SceneLine l;
    l.points = ring;
    l.closed = true;
    static_cast<FeatureKeys&>(l) = poly;
    const double len = perimeter(ring);
    l.length = len / kf;
    add_line(std::move(l), kf);
  }

  // A line (length already in ground metres) into the static or dynamic lines.
  void add_line(SceneLine l, double kf) {
    l.layer = layer_index_;
    l.width = spec_.dynamic ? spec_.style.width : spec_.style.width * kf;
    (spec_.dynamic ? out_->dynamic_lines : out_->lines).push_back(std::move(l));
    ++counts_.parts;
  }

  SceneFeatures* out_ = nullptr;
  const SceneSpec& scene_;
  const LayerSpec spec_;
  const std::vector<SourceFeature>* features_ = nullptr;
  const uint32_t layer_index_;
  const std::vector<double>* scale_ = nullptr;
  LayerCounts counts_;
  // shared_edges = "once": the edges drawn so far (32 bytes and a hash
  // node an edge, for the layer's whole life, across chunks).
  std::unordered_set<EdgeKey, EdgeHash> seen_edges_;
};

}  // namespace

SceneFeatures clean(const ProjectedFeatures& input, const SceneSpec& scene,
                    const CleanOptions& options) {
  ProjectedFeatures copy = input;
  return clean(std::move(copy), scene, options);
}

SceneFeatures clean(ProjectedFeatures&& input, const SceneSpec& scene,
                    const CleanOptions& options) {
  SceneFeatures out;
  out.frame = input.frame;
  out.manifest.notes = input.features.manifest.notes;
  const Manifest& read_manifest = input.features.manifest;

  // Also capped by the pipeline; kept so clean() alone honours it.
  std::unique_ptr<tbb::global_control> limit;
  if (options.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  options.threads);
  }
  tbb::enumerable_thread_specific<WorkerContext> contexts;
  const Cleaner cleaner{input.clip, scene.resolution, scene.repair, options.test_geos_failure_fid};
  uint64_t parts = 0;
  for (const SourceLayer& layer : input.features.layers) parts += layer.features.size();
  ProgressStage stage(options.progress, "clean", parts, "parts");

  for (size_t li = 0; li < input.features.layers.size(); ++li) {
    SourceLayer& layer = input.features.layers[li];
    out.layers.push_back(layer.spec);
    std::vector<PartResult> results = clean_parts(cleaner, contexts, stage, layer);
    LayerGather gather(scene, layer.spec, static_cast<uint32_t>(li), read_manifest);
    gather.gather(out, layer.features, input.scale[li], results);
    out.manifest.layers.push_back(gather.counts());
  }
  // Read-stage entries (parts of kept features the kind could not draw).
  for (const ManifestEntry& e : read_manifest.entries) out.manifest.entries.push_back(e);

  out.extent = kept_extent(out);
  stage.finish();
  return out;
}

struct ChunkCleaner::Impl {
  const SceneSpec& scene;
  std::optional<Extent> clip;
  Cleaner cleaner;
  std::unique_ptr<tbb::global_control> limit;
  tbb::enumerable_thread_specific<WorkerContext> contexts;
  ProgressStage silent;
  ProgressStage* stage;
  std::optional<LayerGather> layer;

  Impl(const SceneSpec& s, const std::optional<Extent>& c, const CleanOptions& options,
       ProgressStage* st)
      : scene(s),
        clip(c),
        cleaner{clip, s.resolution, s.repair, options.test_geos_failure_fid},
        stage(st ? st : &silent) {
    if (options.threads > 0) {
      limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    options.threads);
    }
  }
};

ChunkCleaner::ChunkCleaner(const SceneSpec& scene, const std::optional<Extent>& clip,
                           const CleanOptions& options, ProgressStage* stage)
    : impl_(std::make_unique<Impl>(scene, clip, options, stage)) {}

ChunkCleaner::~ChunkCleaner() = default;

void ChunkCleaner::begin_layer(uint32_t layer_index, const LayerSpec& spec,
                               const Manifest& read_manifest) {
  impl_->layer.emplace(impl_->scene, spec, layer_index, read_manifest);
}

void ChunkCleaner::clean_chunk(SourceLayer& chunk, const std::vector<double>& scale,
                               SceneFeatures& out) {
  std::vector<PartResult> results =
      clean_parts(impl_->cleaner, impl_->contexts, *impl_->stage, chunk);
  impl_->layer->gather(out, chunk.features, scale, results);
}

LayerCounts ChunkCleaner::end_layer() {
  LayerCounts c = impl_->layer->counts();
  impl_->layer.reset();
  return c;
}

Extent kept_extent(const SceneFeatures& s) {
  Extent b = no_points();
  for (const ScenePolygon& p : s.polygons) extend(b, p.shell);
  for (const SceneLine& l : s.lines) extend(b, l.points);
  for (const SceneLine& l : s.dynamic_lines) extend(b, l.points);
  return b.xmax >= b.xmin ? b : Extent{};
}

// ------------------------------------------------------- overview levels --

namespace {

// Squared distance from p to the segment a-b.
double segment_distance2(const Point2& p, const Point2& a, const Point2& b) {
  const double dx = b.x - a.x, dy = b.y - a.y, len2 = dx * dx + dy * dy;
  double t = len2 > 0 ? ((p.x - a.x) * dx + (p.y - a.y) * dy) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double ex = a.x + t * dx - p.x, ey = a.y + t * dy - p.y;
  return ex * ex + ey * ey;
}

// Douglas-Peucker of a closed ring (unclosed, as stored): which vertices it
// keeps. The ring is split at its first vertex and the vertex farthest from
// it; each section keeps its farthest vertex while that lies more than
// `tolerance` from the section's chord. Every vertex of the ring then lies
// within `tolerance` of the result, and every vertex of the result is one of
// the ring's.
std::vector<char> douglas_peucker_keep(const Ring& r, double tolerance) {
  const size_t n = r.size();
  std::vector<char> keep(n, n <= 3 ? 1 : 0);
  if (n <= 3) return keep;
  const double t2 = tolerance * tolerance;
  size_t far = 0;
  double far_d = -1;
  for (size_t i = 1; i < n; ++i) {
    const double dx = r[i].x - r[0].x, dy = r[i].y - r[0].y, d = dx * dx + dy * dy;
    if (d > far_d) far_d = d, far = i;
  }
  keep[0] = keep[far] = 1;
  // Sections [a, b] in ring order; b == n stands for vertex 0.
  std::vector<std::pair<size_t, size_t>> todo = {{0, far}, {far, n}};
  while (!todo.empty()) {
    const auto [a, b] = todo.back();
    todo.pop_back();
    if (b - a < 2) continue;
    const Point2 &pa = r[a], &pb = r[b == n ? 0 : b];
    size_t at = a;
    double worst = -1;
    for (size_t i = a + 1; i < b; ++i) {
      const double d = segment_distance2(r[i], pa, pb);
      if (d > worst) worst = d, at = i;
    }
    if (worst <= t2) continue;
    keep[at] = 1;
    todo.push_back({a, at});
    todo.push_back({at, b});
  }
  return keep;
}

Ring kept_vertices(const Ring& r, const std::vector<char>& keep) {
  Ring out;
  for (size_t i = 0; i < r.size(); ++i)
    if (keep[i]) out.push_back(r[i]);
  return out;
}

// Gives back ring r's vertices between each two kept ones (a section the
// simplifier replaced by its chord) where the section's box holds one of
// `at` (the points where the sweep found a problem: the region between a
// chord and its section lies in that box); how many came back.
uint64_t restore_sections(const Ring& r, std::vector<char>& keep, std::vector<Point2>& at) {
  const size_t n = r.size();
  std::sort(at.begin(), at.end(), [](const Point2& a, const Point2& b) { return a.x < b.x; });
  size_t first = 0;
  while (first < n && !keep[first]) ++first;
  if (first == n) return 0;
  uint64_t changed = 0;
  for (size_t a = first;;) {
    size_t b = a + 1;  // the next kept vertex (mod n)
    while (!keep[b % n]) ++b;
    if (b - a >= 2) {
      double xmin = INFINITY, ymin = INFINITY, xmax = -INFINITY, ymax = -INFINITY;
      for (size_t i = a; i <= b; ++i) {
        const Point2& p = r[i % n];
        xmin = std::min(xmin, p.x), xmax = std::max(xmax, p.x);
        ymin = std::min(ymin, p.y), ymax = std::max(ymax, p.y);
      }
      auto it = std::lower_bound(at.begin(), at.end(), xmin,
                                 [](const Point2& p, double x) { return p.x < x; });
      for (; it != at.end() && it->x <= xmax; ++it)
        if (it->y >= ymin && it->y <= ymax) {
          for (size_t i = a + 1; i < b; ++i) keep[i % n] = 1;
          ++changed;
          break;
        }
    }
    if (b % n == first) break;
    a = b % n;
  }
  return changed;
}

// The rings of a valid polygon (shell first) simplified ring by ring
// (Douglas-Peucker), then proved valid by the sweep of
// detail/certainly_valid.hpp: only the simplification can have made a
// problem, so where the sweep finds them, the sections of the rings in them
// whose boxes hold a problem's point get their vertices back (a ring whose
// sections are all back, or one that collapsed or turned over, is the
// ring as it was), and the sweep runs again. False, rings untouched, when
// the sweep is unsure, or a problem lies only among rings as they were, or
// after kMaxRounds rounds: GEOS's TopologyPreserveSimplify decides those.
bool simplified_rings(std::vector<Ring>& rings, double tolerance, uint64_t& sections_back) {
  constexpr int kMaxRounds = 16;
  const size_t count = rings.size();
  std::vector<std::vector<char>> keep(count);
  std::vector<Ring> out(count);
  for (size_t i = 0; i < count; ++i) {
    keep[i] = douglas_peucker_keep(rings[i], tolerance);
    out[i] = kept_vertices(rings[i], keep[i]);
    const double before = signed_area(rings[i]), after = signed_area(out[i]);
    if (out[i].size() < 3 || after == 0 || (after > 0) != (before > 0)) {
      std::fill(keep[i].begin(), keep[i].end(), 1);
      out[i] = rings[i];
    }
  }
  std::vector<detail::Culprit> culprits;
  std::vector<std::vector<Point2>> at(count);  // per ring, the problems' points this round
  std::vector<char> whole(count, 0);           // per ring, a problem of the whole ring
  for (int round = 0; round < kMaxRounds; ++round) {
    switch (detail::polygon_validity(out, &culprits)) {
      case detail::Validity::valid: rings = std::move(out); return true;
      case detail::Validity::unsure: return false;
      case detail::Validity::invalid: break;
    }
    std::vector<uint32_t> touched;
    for (const detail::Culprit& c : culprits) {
      if (c.ring >= count) return false;
      if (at[c.ring].empty() && !whole[c.ring]) touched.push_back(c.ring);
      if (c.whole)
        whole[c.ring] = 1;
      else
        at[c.ring].push_back(c.at);
    }
    // The sections at the problems' points; where that gives nothing back,
    // the rings in the problems whole.
    bool changed = false;
    for (int whole_rings = 0; whole_rings < 2 && !changed; ++whole_rings)
      for (uint32_t ri : touched) {
        bool back = false;
        if (whole_rings || whole[ri]) {
          back = std::find(keep[ri].begin(), keep[ri].end(), 0) != keep[ri].end();
          std::fill(keep[ri].begin(), keep[ri].end(), 1);
          sections_back += back;
        } else {
          const uint64_t sections = restore_sections(rings[ri], keep[ri], at[ri]);
          sections_back += sections;
          back = sections > 0;
        }
        if (back) out[ri] = kept_vertices(rings[ri], keep[ri]);
        changed |= back;
      }
    for (uint32_t ri : touched) at[ri].clear(), whole[ri] = 0;
    if (!changed) return false;
  }
  return false;
}

}  // namespace

struct PartSimplifier::Impl {
  detail::GeosContext ctx;
  double tolerance;
  Counts counts;
  explicit Impl(double t) : tolerance(t) {}
};

PartSimplifier::PartSimplifier(double tolerance) : impl_(std::make_unique<Impl>(tolerance)) {}
PartSimplifier::~PartSimplifier() = default;

bool PartSimplifier::polygon(ScenePolygon& p, const std::string& what) {
  if (p.shell.size() < 3) return false;
  std::vector<Ring> rings;
  rings.reserve(1 + p.holes.size());
  rings.push_back(p.shell);
  for (const Ring& r : p.holes)
    if (r.size() >= 3) rings.push_back(r);
  uint64_t sections_back = 0;
  Counts& counts = impl_->counts;
  if (simplified_rings(rings, impl_->tolerance, sections_back)) {
    ++counts.proved;
    counts.with_sections_back += sections_back > 0;
    counts.sections_back += sections_back;
    p.shell = std::move(rings[0]);
    p.holes.assign(std::make_move_iterator(rings.begin() + 1),
                   std::make_move_iterator(rings.end()));
    return true;
  }
  ++counts.geos;
  GEOSContextHandle_t h = impl_->ctx.handle();
  Geom g(h, make_polygon(h, rings));
  if (!g)
    fail<input_error>(kNoStage, "overview level: " + what +
                                    ": GEOS cannot build the polygon: " + impl_->ctx.last_error());
  Geom simple(h, GEOSTopologyPreserveSimplify_r(h, g.get(), impl_->tolerance));
  if (!simple)
    fail<input_error>(kNoStage, "overview level: " + what +
                                    ": GEOS simplification failed: " + impl_->ctx.last_error());
  // Topology-preserving; keep the part as it is if GEOS ever disagrees (as
  // clean() does), decided by the sweep where it can (geos_valid).
  if (!geos_valid(h, simple.get())) return true;
  std::vector<const GEOSGeometry*> polys;
  bool ignored = false;
  collect(h, simple.get(), GEOS_POLYGON, polys, ignored);
  if (polys.empty()) return false;
  // One polygon in, one polygon out (TopologyPreserveSimplify never splits one).
  Ring shell;
  std::vector<Ring> holes;
  read_oriented_rings(h, polys[0], shell, holes);
  if (shell.size() < 3 || signed_area(shell) == 0) return false;
  std::erase_if(holes, [](const Ring& hole) { return hole.size() < 3; });
  p.shell = std::move(shell);
  p.holes = std::move(holes);
  return true;
}

const PartSimplifier::Counts& PartSimplifier::counts() const {
  return impl_->counts;
}

bool PartSimplifier::line(SceneLine& l, const std::string& what) {
  return line(l, what, impl_->tolerance);
}

bool PartSimplifier::line(SceneLine& l, const std::string& what, double tolerance) {
  GEOSContextHandle_t h = impl_->ctx.handle();
  if (l.points.size() < 2) return false;
  Ring pts = l.points;
  if (l.closed) pts.push_back(pts.front());
  Geom g(h, make_line(h, pts));
  if (!g)
    fail<input_error>(kNoStage, "overview level: " + what +
                                    ": GEOS cannot build the line: " + impl_->ctx.last_error());
  Geom simple(h, GEOSTopologyPreserveSimplify_r(h, g.get(), tolerance));
  if (!simple)
    fail<input_error>(kNoStage, "overview level: " + what +
                                    ": GEOS simplification failed: " + impl_->ctx.last_error());
  std::vector<const GEOSGeometry*> lines;
  bool ignored = false;
  collect(h, simple.get(), GEOS_LINESTRING, lines, ignored);
  if (lines.empty()) return false;
  Ring out = read_coords(h, lines[0], false);
  if (l.closed) {
    // A closed line keeps its closing point in GEOS; three distinct corners at least.
    if (out.size() < 4) return false;
    out.pop_back();
  } else if (out.size() < 2) {
    return false;
  }
  l.points = std::move(out);
  return true;
}

double part_area(const ScenePolygon& p) {
  double a = geos_ring_area(p.shell);
  for (const Ring& h : p.holes) a -= geos_ring_area(h);
  return a;
}

double ring_area(const Ring& r) {
  return geos_ring_area(r);
}

double part_length(const SceneLine& l) {
  double len = geos_line_length(l.points);
  if (l.closed && l.points.size() >= 2) {
    const double dx = l.points.front().x - l.points.back().x;
    const double dy = l.points.front().y - l.points.back().y;
    len += std::sqrt(dx * dx + dy * dy);
  }
  return len;
}

}  // namespace prep
