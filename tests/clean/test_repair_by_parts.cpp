// The repair of hole-heavy polygons by parts (libprep/clean/detail/
// repair_by_parts.hpp) against GEOS MakeValid of the whole polygon, in
// double precision, with both repair methods: the same area (1e-9
// relative), a symmetric difference of (almost) zero area, and the same
// number of polygons and rings.
//
//  - A hostile 4,100-hole polygon at UTM-sized coordinates through clean()
//    itself: grid holes, and holes sharing an edge with the shell, touching
//    it at a point, crossing it, outside it, a strip across the whole shell
//    (it cuts the shell in two: the grid holes must go to the right half),
//    overlapping pairs, nested holes, identical holes, holes touching at a
//    point, a self-crossing (bow-tie) hole and a large hole around a block
//    of grid holes (islands in the repair).
//  - Random polygons: a non-convex shell with 100-300 holes of random shape
//    and size, many of them overlapping each other or the shell.
//  - The clip of such repairs to a rectangle by holes (libprep/clean/detail/
//    clip_many_holes.hpp) against GEOS Intersection of the whole repair, for
//    rectangles through the grid, along hole edges, around islands and
//    around everything.
//  - With DECALPREP_STRESS_CLEAN=1 (ctest -L stress): the 10^5-hole polygon
//    of tests/hostile/generate.py --big (poly_100k_holes_touching_shell),
//    against the whole MakeValid (minutes).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "../read/scene_fixtures.hpp"
#include "detail/clip_many_holes.hpp"
#include "detail/repair_by_parts.hpp"
#include "geos_oracle.hpp"
#include "prep/clean.hpp"
#include "test_support.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace clean_repair_by_parts {

namespace {

using prep::Point2;
using prep::Ring;
using prep::test::G;
using prep::test::Geos;
using Rings = std::vector<Ring>;

// UTM-sized offset: the coordinates carry metres at 10^6 magnitude.
constexpr double kX0 = 500000, kY0 = 4800000;

Ring rect(double x0, double y0, double x1, double y1) {
  return {{kX0 + x0, kY0 + y0}, {kX0 + x1, kY0 + y0}, {kX0 + x1, kY0 + y1}, {kX0 + x0, kY0 + y1}};
}
Ring square(double cx, double cy, double r) {
  return rect(cx - r, cy - r, cx + r, cy + r);
}
Ring ring(std::initializer_list<std::pair<double, double>> pts) {
  Ring r;
  for (const auto& [x, y] : pts) r.push_back({kX0 + x, kY0 + y});
  return r;
}

// The hostile polygon: a 2 km square shell, 64 x 64 grid holes of 10 m
// (centres 30 m apart) and the special holes of the file comment.
Rings hostile_polygon() {
  Rings rings{rect(0, 0, 2000, 2000)};
  auto centre = [](int i) { return 30.0 * (i + 1); };
  for (int j = 0; j < 64; ++j)
    for (int i = 0; i < 64; ++i) {
      const double cx = centre(i), cy = centre(j);
      if (i == 0 && j % 7 == 3) {  // shares an edge with the shell (x = 0)
        rings.push_back(rect(0, cy - 5, cx + 5, cy + 5));
      } else if (j == 0 && i % 9 == 4) {  // touches the shell at a point (y = 0)
        rings.push_back(ring({{cx - 5, 20}, {cx, 0}, {cx + 5, 20}}));
      } else if (j == 63 && i % 11 == 5) {  // crosses the shell (y = 2000)
        rings.push_back(rect(cx - 5, 1990, cx + 5, 2010));
      } else if (i == 20 && j % 5 == 1) {  // an overlapping pair
        rings.push_back(square(cx, cy, 5));
        rings.push_back(square(cx + 4, cy + 4, 5));
      } else if (i == 21 && j % 6 == 2) {  // nested: a hole in a hole in a hole
        rings.push_back(square(cx, cy, 5));
        rings.push_back(square(cx, cy, 3));
        rings.push_back(square(cx, cy, 1));
      } else if (i == 22 && j % 8 == 3) {  // the same hole twice
        rings.push_back(square(cx, cy, 5));
        rings.push_back(square(cx, cy, 5));
      } else if (i == 23 && j % 4 == 0) {  // two triangles touching at a vertex
        rings.push_back(ring({{cx - 5, cy - 5}, {cx, cy}, {cx - 5, cy + 5}}));
        rings.push_back(ring({{cx + 5, cy - 5}, {cx + 5, cy + 5}, {cx, cy}}));
      } else if (i == 25 && j % 10 == 5) {  // collinear: collapses to a line
        rings.push_back(ring({{cx - 5, cy}, {cx + 5, cy}, {cx, cy}}));
      } else if (i == 24 && j % 9 == 4) {  // bow-tie
        rings.push_back(
            ring({{cx - 5, cy - 5}, {cx + 5, cy + 5}, {cx + 5, cy - 5}, {cx - 5, cy + 5}}));
      } else {
        rings.push_back(square(cx, cy, 5));
      }
    }
  // A strip across the shell between two rows of holes (rows at 990 and
  // 1020: the strip's envelope meets none of them).
  rings.push_back(rect(-10, 1003, 2010, 1007));
  // A hole outside the shell.
  rings.push_back(square(2100, 2100, 20));
  // A large hole around a block of 6 x 6 grid holes (x, y in 1380..1560):
  // the grid holes inside become islands.
  rings.push_back(rect(1372, 1372, 1568, 1568));
  // A U-shaped hole with a grid hole in its bay (envelopes meet, rings not).
  rings.push_back(ring({{1672, 1672},
                        {1718, 1672},
                        {1718, 1718},
                        {1712, 1718},
                        {1712, 1678},
                        {1678, 1678},
                        {1678, 1718},
                        {1672, 1718}}));
  return rings;
}

G make_valid(GEOSContextHandle_t h, const GEOSGeometry* g, bool structure) {
  if (!structure) return G(h, GEOSMakeValid_r(h, g));
  GEOSMakeValidParams* p = GEOSMakeValidParams_create_r(h);
  GEOSMakeValidParams_setMethod_r(h, p, GEOS_MAKE_VALID_STRUCTURE);
  GEOSMakeValidParams_setKeepCollapsed_r(h, p, 0);
  G v(h, GEOSMakeValidWithParams_r(h, g, p));
  GEOSMakeValidParams_destroy_r(h, p);
  return v;
}

G polygon_of(GEOSContextHandle_t h, const Rings& rings) {
  return prep::test::polygon(h, rings[0], Rings(rings.begin() + 1, rings.end()));
}

// The polygons of `g` (any nesting of collections), as a MultiPolygon.
void polygons_of(GEOSContextHandle_t h, const GEOSGeometry* g, std::vector<G>& out) {
  const int type = GEOSGeomTypeId_r(h, g);
  if (type == GEOS_POLYGON) {
    if (!GEOSisEmpty_r(h, g)) out.emplace_back(h, GEOSGeom_clone_r(h, g));
    return;
  }
  if (type == GEOS_MULTIPOLYGON || type == GEOS_GEOMETRYCOLLECTION)
    for (int i = 0; i < GEOSGetNumGeometries_r(h, g); ++i)
      polygons_of(h, GEOSGetGeometryN_r(h, g, i), out);
}
G multipolygon(GEOSContextHandle_t h, std::vector<G> parts) {
  return prep::test::collection(h, GEOS_MULTIPOLYGON, parts);
}
G polygonal(GEOSContextHandle_t h, const GEOSGeometry* g) {
  std::vector<G> parts;
  polygons_of(h, g, parts);
  return multipolygon(h, std::move(parts));
}

// Whether `g` holds a non-empty piece that is not a polygon.
bool has_non_polygon(GEOSContextHandle_t h, const GEOSGeometry* g) {
  const int type = GEOSGeomTypeId_r(h, g);
  if (type == GEOS_MULTIPOLYGON || type == GEOS_GEOMETRYCOLLECTION) {
    for (int i = 0; i < GEOSGetNumGeometries_r(h, g); ++i)
      if (has_non_polygon(h, GEOSGetGeometryN_r(h, g, i))) return true;
    return false;
  }
  return type != GEOS_POLYGON && !GEOSisEmpty_r(h, g);
}

struct Shape {
  size_t polygons = 0, rings = 0;
};
Shape shape_of(GEOSContextHandle_t h, const GEOSGeometry* multi) {
  Shape s;
  for (int i = 0; i < GEOSGetNumGeometries_r(h, multi); ++i) {
    ++s.polygons;
    s.rings += 1 + size_t(GEOSGetNumInteriorRings_r(h, GEOSGetGeometryN_r(h, multi, i)));
  }
  return s;
}

// `got` (polygonal) against the oracle `want` (polygonal): valid, the same
// area to 1e-9 relative, a symmetric difference below 1e-9 of the area, the
// same polygons and rings.
void expect_same(GEOSContextHandle_t h, const G& got, const G& want, const std::string& what) {
  EXPECT_EQ(GEOSisValid_r(h, got.g), 1) << what;
  const double a_got = prep::test::area(got), a_want = prep::test::area(want);
  ASSERT_GT(a_want, 0) << what;
  EXPECT_NEAR(a_got, a_want, 1e-9 * a_want) << what;
  const G diff(h, GEOSSymDifference_r(h, got.g, want.g));
  EXPECT_LE(prep::test::area(diff), 1e-9 * a_want) << what << ": symmetric difference";
  const Shape s_got = shape_of(h, got.g), s_want = shape_of(h, want.g);
  std::printf(
      "%s: area %.17g vs %.17g (relative %.2g), symmetric difference %.3g m2, "
      "%zu/%zu polygons, %zu/%zu rings\n",
      what.c_str(), a_got, a_want, std::fabs(a_got - a_want) / a_want, prep::test::area(diff),
      s_got.polygons, s_want.polygons, s_got.rings, s_want.rings);
  EXPECT_EQ(s_got.polygons, s_want.polygons) << what;
  EXPECT_EQ(s_got.rings, s_want.rings) << what;
}

// detail::make_valid_by_parts on `rings` with the method; null when the
// split did not apply.
G by_parts(GEOSContextHandle_t h, const Rings& rings, bool structure) {
  const G whole = polygon_of(h, rings);
  GEOSGeometry* r = prep::detail::make_valid_by_parts(
      h, whole.g, rings, [&](GEOSContextHandle_t th, const GEOSGeometry* part) {
        return make_valid(th, part, structure).release();
      });
  return r ? polygonal(h, r) : G();
}

// The same with a window (offsets from kX0, kY0); `left_out` says what the
// repair left out.
G by_parts_in(GEOSContextHandle_t h, const Rings& rings, bool structure, const double (&w)[4],
              prep::detail::LeftOut& left_out) {
  const G whole = polygon_of(h, rings);
  const prep::detail::Envelope window{kX0 + w[0], kY0 + w[1], kX0 + w[2], kY0 + w[3]};
  GEOSGeometry* r = prep::detail::make_valid_by_parts(
      h, whole.g, rings,
      [&](GEOSContextHandle_t th, const GEOSGeometry* part) {
        return make_valid(th, part, structure).release();
      },
      &window, &left_out);
  return r ? polygonal(h, r) : G();
}

const char* method_name(bool structure) {
  return structure ? "structure" : "linework";
}

// ------------------------------------------------------------ the unit --

// The repair by parts of `rings` (`structure`: the structure method, else
// linework) against GEOS MakeValid of the whole polygon, reported under
// `what`; false, comparing nothing, when the split did not apply.
bool split_equals_whole(const Geos& geos, const Rings& rings, bool structure,
                        const std::string& what) {
  const G got = by_parts(geos.h, rings, structure);
  if (!got.g) return false;
  const G whole = polygon_of(geos.h, rings);
  const G want = polygonal(geos.h, make_valid(geos.h, whole.g, structure).g);
  expect_same(geos.h, got, want, what + method_name(structure));
  return true;
}

TEST(RepairByParts, HostilePolygonEqualsWholeMakeValid) {
  Geos geos;
  const Rings rings = hostile_polygon();
  ASSERT_GT(rings.size(), 4000u);
  const G whole = polygon_of(geos.h, rings);
  ASSERT_NE(GEOSisValid_r(geos.h, whole.g), 1);
  for (const bool structure : {false, true})
    EXPECT_TRUE(split_equals_whole(geos, rings, structure, "")) << "the split did not apply";
}

using prep::test::Rng;

// A non-convex shell (a 1 km square with a deep notch) and holes of random
// shape (squares, triangles, bow-ties, thin bars), place and size.
Rings random_polygon(uint64_t seed) {
  Rng rng(seed);
  Rings rings{ring({{0, 0},
                    {1000, 0},
                    {1000, 1000},
                    {600, 1000},
                    {600, 300},
                    {400, 300},
                    {400, 1000},
                    {0, 1000}})};
  const int holes = 100 + int(rng.uniform() * 200);
  for (int k = 0; k < holes; ++k) {
    const double cx = rng.in(-50, 1050), cy = rng.in(-50, 1050);
    const double r = rng.uniform() < 0.8 ? rng.in(2, 15) : rng.in(15, 120);
    const double u = rng.uniform();
    if (u < 0.6) {
      rings.push_back(square(cx, cy, r));
    } else if (u < 0.8) {
      rings.push_back(ring({{cx - r, cy - r}, {cx + r, cy - r * 0.3}, {cx, cy + r}}));
    } else if (u < 0.9) {
      rings.push_back(
          ring({{cx - r, cy - r}, {cx + r, cy + r}, {cx + r, cy - r}, {cx - r, cy + r}}));
    } else {
      rings.push_back(rect(cx - 4 * r, cy - 1, cx + 4 * r, cy + 1));
    }
  }
  return rings;
}

TEST(RepairByParts, RandomPolygonsEqualWholeMakeValid) {
  Geos geos;
  int split = 0, cases = 0;
  for (uint64_t seed = 1; seed <= 12; ++seed) {
    const Rings rings = random_polygon(seed * 0x9E3779B97F4A7C15ull);
    for (const bool structure : {false, true}) {
      ++cases;
      split += split_equals_whole(geos, rings, structure, "seed " + std::to_string(seed) + ", ");
    }
  }
  // Most random polygons have groups of holes clear of the shell.
  std::printf("split %d of %d\n", split, cases);
  EXPECT_GE(split, cases / 2) << split << " of " << cases << " split";
}

// A continent: one large C-shaped hole whose envelope holds most of the
// other holes, which lie in its bay (touching nothing), inside it (lakes'
// islands: holes in a hole, the repair's islands), across its coast, or
// are bow-ties; one hole crosses both the shell and the coast. Grouped by
// envelope contact this is one group touching the
// shell, the whole repair; by ring contact the bay's holes stay apart.
TEST(RepairByParts, ContinentSizedHoleEqualsWholeMakeValid) {
  Geos geos;
  Rings rings{rect(0, 0, 2000, 2000)};
  rings.push_back(ring({{100, 100},
                        {1900, 100},
                        {1900, 600},
                        {600, 600},
                        {600, 1400},
                        {1900, 1400},
                        {1900, 1900},
                        {100, 1900}}));
  Rng rng(0x5EA5);
  for (int k = 0; k < 300; ++k) {
    const double cx = rng.in(120, 1880), cy = rng.in(120, 1880), r = rng.in(2, 12);
    if (rng.uniform() < 0.1)
      rings.push_back(
          ring({{cx - r, cy - r}, {cx + r, cy + r}, {cx + r, cy - r}, {cx - r, cy + r}}));
    else
      rings.push_back(square(cx, cy, r));
  }
  rings.push_back(square(50, 1000, 60));  // across the shell and the coast
  for (const bool structure : {false, true})
    EXPECT_TRUE(split_equals_whole(geos, rings, structure, "continent, "))
        << "the split did not apply";
}

TEST(RepairByParts, FewHolesAreLeftToTheWholeRepair) {
  Geos geos;
  Rings few{rect(0, 0, 100, 100), square(50, 50, 5), rect(-10, 40, 20, 60)};
  EXPECT_FALSE(by_parts(geos.h, few, false).g);
}

// A self-crossing shell: its own repair is the shell's area the holes are
// placed in. A bow-tie shell (two triangles meeting at (1000, 1000)) with
// grid holes in the right triangle, one of them crossing its edge, and a
// grid hole over the crossing point.
TEST(RepairByParts, SelfCrossingShellEqualsWholeMakeValid) {
  Geos geos;
  Rings bowtie_shell{ring({{0, 0}, {2000, 2000}, {2000, 0}, {0, 2000}})};
  for (int k = 0; k < 100; ++k) {
    const int row = k / 10;
    bowtie_shell.push_back(square(1500 + (k % 10) * 30, 700 + row * 30, 5));
  }
  bowtie_shell.push_back(square(1300, 1300, 5));  // crosses the triangle's edge
  bowtie_shell.push_back(square(1000, 1000, 5));  // around the crossing point
  for (const bool structure : {false, true})
    EXPECT_TRUE(split_equals_whole(geos, bowtie_shell, structure, "bow-tie shell, "))
        << "the split did not apply";
}

// A shell that winds twice around an inner square: its ring goes around the
// 2 km square, then around [500, 1500]^2 once more, crossing itself at
// (500, 500). The inner square has crossing parity 0 (the linework method
// leaves it out), the band x > 1500 parity 1. Which holes are clear of the
// shell is decided by crossing parity against the shell ring, without the
// shell's own repair: holes in the band are clear, holes in the inner
// square are not (they go into the base repair with the shell), and with
// only band holes the base repair is the shell's own repair.
TEST(RepairByParts, DoublyWoundShellEqualsWholeMakeValid) {
  Geos geos;
  const prep::Ring shell = ring({{0, 0},
                                 {2000, 0},
                                 {2000, 2000},
                                 {0, 2000},
                                 {0, 500},
                                 {1500, 500},
                                 {1500, 1500},
                                 {500, 1500},
                                 {500, 100}});
  Rings band{shell};
  for (int k = 0; k < 100; ++k) {
    const int row = k / 10;
    band.push_back(square(1620 + (k % 10) * 35, 200 + row * 160, 5));
  }
  Rings both = band;
  for (int k = 0; k < 64; ++k) {
    const int row = k / 8;
    both.push_back(square(600 + (k % 8) * 110, 600 + row * 110, 5));
  }
  both.push_back(square(1500, 1000, 5));  // across the inner loop's edge
  for (const Rings* rings : {&band, &both}) {
    const G whole = polygon_of(geos.h, *rings);
    ASSERT_NE(GEOSisValid_r(geos.h, whole.g), 1);
    for (const bool structure : {false, true})
      EXPECT_TRUE(split_equals_whole(geos, *rings, structure,
                                     rings == &band ? "band holes, " : "band and inner holes, "))
          << "the split did not apply";
  }
}

// random_polygon with a bow-tie ear in the shell's top right corner (its
// edges cross at (1050, 950)) and a second one on the left edge, as a
// coastline that crosses itself.
TEST(RepairByParts, RandomPolygonsWithASelfCrossingShellEqualWholeMakeValid) {
  Geos geos;
  int split = 0, cases = 0;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    Rings rings = random_polygon(seed * 0xD1B54A32D192ED03ull);
    rings[0] = ring({{0, 0},
                     {1000, 0},
                     {1000, 900},
                     {1100, 1000},
                     {1100, 900},
                     {1000, 1000},
                     {600, 1000},
                     {600, 300},
                     {400, 300},
                     {400, 1000},
                     {0, 1000},
                     {0, 600},
                     {-80, 520},
                     {-80, 600},
                     {0, 520}});
    const G whole = polygon_of(geos.h, rings);
    ASSERT_NE(GEOSisValid_r(geos.h, whole.g), 1);
    for (const bool structure : {false, true}) {
      ++cases;
      split += split_equals_whole(geos, rings, structure,
                                  "self-crossing shell, seed " + std::to_string(seed) + ", ");
    }
  }
  std::printf("split %d of %d\n", split, cases);
  EXPECT_GE(split, cases / 2) << split << " of " << cases << " split";
}

// ------------------------------------------------- through clean() --

prep::SceneFeatures clean_one(const Rings& rings, prep::RepairMethod method) {
  prep::ProjectedFeatures in = prep::test::one_polygon_input("holes", rings);
  prep::BuildSpec scene;
  scene.repair = method;
  return prep::clean(std::move(in), scene);
}

TEST(RepairByParts, CleanRepairsTheHostilePolygonAsGeosMakeValidOfTheWhole) {
  Geos geos;
  const Rings rings = hostile_polygon();
  const G whole = polygon_of(geos.h, rings);
  for (const bool structure : {false, true}) {
    const prep::SceneFeatures out =
        clean_one(rings, structure ? prep::RepairMethod::structure : prep::RepairMethod::linework);
    std::vector<G> polys;
    double sum = 0;
    for (const prep::ScenePolygon& p : out.polygons) {
      polys.push_back(prep::test::polygon(geos.h, p));
      sum += prep::test::polygon_area(p);  // independent of GEOS
      // Orientation: shell counter-clockwise, holes clockwise.
      EXPECT_GT(prep::test::ring_area(p.shell), 0);
      for (const Ring& hole : p.holes) EXPECT_LT(prep::test::ring_area(hole), 0);
    }
    const G got = multipolygon(geos.h, std::move(polys));
    const G want = polygonal(geos.h, make_valid(geos.h, whole.g, structure).g);
    expect_same(geos.h, got, want, std::string("clean, ") + method_name(structure));
    // The manifest: one repair with GEOS's area of the repair, naming the
    // collapsed pieces when GEOS's repair of the whole has any.
    ASSERT_EQ(out.manifest.entries.size(), 1u);
    const prep::ManifestEntry& e = out.manifest.entries[0];
    EXPECT_EQ(e.action, prep::ManifestAction::repaired);
    EXPECT_NE(e.reason.find("made valid ("), std::string::npos) << e.reason;
    const G whole_fixed = make_valid(geos.h, whole.g, structure);
    const bool collapsed = has_non_polygon(geos.h, whole_fixed.g);
    std::printf("%s: %s\n", method_name(structure), e.reason.c_str());
    EXPECT_EQ(e.reason.find("discarded collapsed") != std::string::npos, collapsed) << e.reason;
    EXPECT_NEAR(e.area_after, prep::test::area(want), 1e-9 * prep::test::area(want));
    EXPECT_NEAR(sum, prep::test::area(want), 1e-6 * prep::test::area(want));
  }
}

// The same output at any thread count (one part: the same bytes).
// The repairs of the parts run in parallel: the same rings in the same order
// on one thread as on four.
TEST(RepairByParts, CleanOutputDoesNotDependOnTheRunOrTheThreads) {
  const Rings rings = hostile_polygon();
  prep::SceneFeatures a, b;
  {
    const tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    a = clean_one(rings, prep::RepairMethod::linework);
  }
  {
    const tbb::global_control four(tbb::global_control::max_allowed_parallelism, 4);
    b = clean_one(rings, prep::RepairMethod::linework);
  }
  auto same = [](const Ring& p, const Ring& q) {
    if (p.size() != q.size()) return false;
    for (size_t i = 0; i < p.size(); ++i)
      if (p[i].x != q[i].x || p[i].y != q[i].y) return false;
    return true;
  };
  ASSERT_EQ(a.polygons.size(), b.polygons.size());
  for (size_t i = 0; i < a.polygons.size(); ++i) {
    EXPECT_TRUE(same(a.polygons[i].shell, b.polygons[i].shell)) << i;
    ASSERT_EQ(a.polygons[i].holes.size(), b.polygons[i].holes.size()) << i;
    for (size_t k = 0; k < a.polygons[i].holes.size(); ++k)
      EXPECT_TRUE(same(a.polygons[i].holes[k], b.polygons[i].holes[k])) << i << " " << k;
  }
}

// ------------------------------------------------------------ stress --

// tests/hostile/generate.py --big, poly_100k_holes_touching_shell.
Rings touching_100k() {
  auto pt = [](double x, double y) { return Point2{x, y}; };
  Rings rings{Ring{pt(-5000, -5000), pt(5000, -5000), pt(5000, 5000), pt(-5000, 5000)}};
  for (int k = 0; k < 100000; ++k) {
    const int row = k / 316;
    const double cx = -4960 + 31.4 * (k % 316), cy = -4960 + 31.4 * row;
    const double x0 = k % 316 == 0 ? -5000 : cx - 10, y0 = k / 316 == 0 ? -5000 : cy - 10;
    rings.push_back(Ring{pt(x0, y0), pt(x0, cy + 10), pt(cx + 10, cy + 10), pt(cx + 10, y0)});
  }
  return rings;
}

// detail::clip_many_holes of the valid `repair` against GEOS Intersection of
// the whole with the rectangle (offsets from kX0, kY0). False when the split
// did not apply.
bool clip_equals_whole(const Geos& geos, const G& repair, double x0, double y0, double x1,
                       double y1, const std::string& what) {
  GEOSContextHandle_t h = geos.h;
  GEOSGeometry* got =
      prep::detail::clip_many_holes(h, repair.g, kX0 + x0, kY0 + y0, kX0 + x1, kY0 + y1);
  if (!got) return false;
  const G got_area = polygonal(h, got);
  GEOSGeom_destroy_r(h, got);
  const G rect(h, GEOSGeom_createRectangle_r(h, kX0 + x0, kY0 + y0, kX0 + x1, kY0 + y1));
  const G whole(h, GEOSIntersection_r(h, repair.g, rect.g));
  expect_same(h, got_area, polygonal(h, whole.g), what);
  return true;
}

// Rectangles through the hostile polygon's hole grid (cutting holes), along
// grid hole edges (x = 1025: the edge of the holes centred at 1020), around
// the island block, across the strip, past the shell, and around it all.
constexpr double kClipRects[][4] = {{-100, 500, 1015, 1300},  {300, 300, 700, 700},
                                    {1025, 995, 1385, 1555},  {1360, 1360, 1600, 1600},
                                    {-50, 1000, 2050, 1010},  {1500, -100, 2300, 2300},
                                    {-500, -500, 2500, 2500}, {13, 17, 1987, 1993}};

TEST(ClipManyHoles, RepairsOfTheHostilePolygonEqualWholeIntersection) {
  Geos geos;
  const Rings rings = hostile_polygon();
  const G whole = polygon_of(geos.h, rings);
  for (const bool structure : {false, true}) {
    const G repair = make_valid(geos.h, whole.g, structure);
    ASSERT_TRUE(repair.g);
    ASSERT_EQ(GEOSisValid_r(geos.h, repair.g), 1);
    int k = 0;
    for (const auto& r : kClipRects) {
      const std::string what = "rect " + std::to_string(k++) + method_name(structure);
      EXPECT_TRUE(clip_equals_whole(geos, repair, r[0], r[1], r[2], r[3], what))
          << what << ": the split did not apply";
    }
  }
}

TEST(ClipManyHoles, RepairsOfRandomPolygonsEqualWholeIntersection) {
  Geos geos;
  for (uint64_t seed = 1; seed <= 8; ++seed) {
    const Rings rings = random_polygon(seed * 0x9E3779B97F4A7C15ull);
    const G whole = polygon_of(geos.h, rings);
    const G repair = make_valid(geos.h, whole.g, false);
    ASSERT_TRUE(repair.g);
    Rng rng(seed);
    for (int k = 0; k < 4; ++k) {
      const double x0 = rng.in(-100, 600), y0 = rng.in(-100, 600);
      const double x1 = x0 + rng.in(100, 700), y1 = y0 + rng.in(100, 700);
      const std::string what = "seed " + std::to_string(seed) + ", rect " + std::to_string(k);
      const GEOSGeometry* g = repair.g;
      size_t holes = 0;
      for (int i = 0; i < GEOSGetNumGeometries_r(geos.h, g); ++i) {
        const GEOSGeometry* p = GEOSGetGeometryN_r(geos.h, g, i);
        if (GEOSGeomTypeId_r(geos.h, p) == GEOS_POLYGON)
          holes += size_t(GEOSGetNumInteriorRings_r(geos.h, p));
      }
      const bool applies = clip_equals_whole(geos, repair, x0, y0, x1, y1, what);
      EXPECT_EQ(applies, holes >= prep::detail::kClipByHolesMinHoles) << what;
    }
  }
}

TEST(ClipManyHoles, FewHolesOrOtherGeometriesAreLeftToTheWholeIntersection) {
  Geos geos;
  Rings rings{rect(0, 0, 1000, 1000)};
  for (int i = 0; i < 10; ++i) rings.push_back(square(50 + 90.0 * i, 500, 20));
  const G few = polygon_of(geos.h, rings);
  EXPECT_EQ(prep::detail::clip_many_holes(geos.h, few.g, kX0, kY0, kX0 + 500, kY0 + 500), nullptr);
  const double xy[4] = {kX0, kY0, kX0 + 900, kY0 + 900};
  const G line(geos.h, GEOSGeom_createLineString_r(
                           geos.h, GEOSCoordSeq_copyFromBuffer_r(geos.h, xy, 2, 0, 0)));
  EXPECT_EQ(prep::detail::clip_many_holes(geos.h, line.g, kX0, kY0, kX0 + 500, kY0 + 500), nullptr);
}

// ------------------------------------------------- a repair in a window --
//
// With a window (clean passes the extent a part is clipped to next), the
// hole groups clear of the shell whose envelope misses the window are left
// out of the repair: inside the window the repair is GEOS MakeValid of the
// whole all the same (GEOS Intersection of both with the window), and with
// only lone valid holes left out, its area less theirs is the whole
// repair's area.
TEST(RepairByParts, RepairInAWindowEqualsWholeMakeValidInsideIt) {
  Geos geos;
  GEOSContextHandle_t h = geos.h;
  std::vector<std::pair<std::string, Rings>> cases{{"hostile", hostile_polygon()}};
  for (uint64_t seed = 1; seed <= 4; ++seed)
    cases.emplace_back("seed " + std::to_string(seed),
                       random_polygon(seed * 0x9E3779B97F4A7C15ull));
  size_t groups_left_out = 0, lone_left_out = 0, only_lone = 0;
  for (const auto& [name, rings] : cases) {
    const G whole = polygon_of(h, rings);
    for (const bool structure : {false, true}) {
      const G want_all = polygonal(h, make_valid(h, whole.g, structure).g);
      int k = 0;
      for (const auto& w : kClipRects) {
        const std::string what =
            name + ", window " + std::to_string(k++) + ", " + method_name(structure);
        prep::detail::LeftOut left_out;
        const G got_all = by_parts_in(h, rings, structure, w, left_out);
        if (!got_all.g) {
          ADD_FAILURE() << what << ": the split did not apply";
          continue;
        }
        ASSERT_EQ(GEOSisValid_r(h, got_all.g), 1) << what;
        const G rect(h,
                     GEOSGeom_createRectangle_r(h, kX0 + w[0], kY0 + w[1], kX0 + w[2], kY0 + w[3]));
        const G got(h, GEOSIntersection_r(h, got_all.g, rect.g));
        const G want(h, GEOSIntersection_r(h, want_all.g, rect.g));
        if (prep::test::area(want) > 0)
          expect_same(h, polygonal(h, got.g), polygonal(h, want.g), what);
        else
          EXPECT_EQ(prep::test::area(got), 0) << what;
        groups_left_out += left_out.groups;
        lone_left_out += left_out.lone_holes;
        if (left_out.groups == 0) {
          ++only_lone;
          const double a = prep::test::area(want_all);
          EXPECT_NEAR(prep::test::area(got_all) - left_out.lone_hole_area, a, 1e-9 * a) << what;
        }
      }
    }
  }
  std::printf("left out: %zu groups, %zu lone holes; %zu repairs with only lone holes left out\n",
              groups_left_out, lone_left_out, only_lone);
  EXPECT_GT(groups_left_out, 0u);
  EXPECT_GT(lone_left_out, 0u);
  EXPECT_GT(only_lone, 0u);
}

// Through clean(): the hostile polygon clipped to a window that leaves
// groups out (the area after the whole repair is then not known: null,
// "inside the scene extent") and to one that leaves only lone holes out
// (the whole repair's area); the kept polygons against GEOS Intersection of
// GEOS MakeValid of the whole with the extent.
TEST(RepairByParts, CleanRepairsAPolygonCrossingTheExtentAsGeosMakeValidOfTheWhole) {
  Geos geos;
  GEOSContextHandle_t h = geos.h;
  const Rings rings = hostile_polygon();
  const G whole = polygon_of(h, rings);
  // The hostile polygon's groups of more than one hole (or one invalid
  // hole) lie in the columns x = 630..780 and at 1372..1718: [300, 700]^2
  // leaves most of them out, [600, 1800] x [-100, 2100] none (only lone
  // grid holes).
  const double windows[][4] = {{300, 300, 700, 700}, {600, -100, 1800, 2100}};
  for (const bool structure : {false, true}) {
    const G want_all = make_valid(h, whole.g, structure);
    const double area_all = prep::test::area(polygonal(h, want_all.g));
    for (const auto& w : windows) {
      prep::ProjectedFeatures in = prep::test::one_polygon_input("holes", rings);
      in.clip = prep::Extent{kX0 + w[0], kY0 + w[1], kX0 + w[2], kY0 + w[3]};
      prep::BuildSpec scene;
      scene.repair = structure ? prep::RepairMethod::structure : prep::RepairMethod::linework;
      const prep::SceneFeatures out = prep::clean(std::move(in), scene);
      std::vector<G> polys;
      for (const prep::ScenePolygon& p : out.polygons) polys.push_back(prep::test::polygon(h, p));
      const G rect(h,
                   GEOSGeom_createRectangle_r(h, kX0 + w[0], kY0 + w[1], kX0 + w[2], kY0 + w[3]));
      const G want(h, GEOSIntersection_r(h, want_all.g, rect.g));
      const std::string what = std::string("clean in a window, ") + method_name(structure);
      expect_same(h, multipolygon(h, std::move(polys)), polygonal(h, want.g), what);
      ASSERT_EQ(out.manifest.entries.size(), 1u) << what;
      const prep::ManifestEntry& e = out.manifest.entries[0];
      EXPECT_EQ(e.action, prep::ManifestAction::repaired) << what;
      std::printf("%s: %s, area before %.17g after %.17g\n", what.c_str(), e.reason.c_str(),
                  e.area_before, e.area_after);
      const bool groups_out = e.reason.find("inside the scene extent") != std::string::npos;
      EXPECT_EQ(groups_out, &w == &windows[0]) << what << ": " << e.reason;
      if (groups_out) {
        EXPECT_TRUE(std::isnan(e.area_after)) << what;
        EXPECT_FALSE(std::isnan(e.area_before)) << what;
      } else {
        EXPECT_NEAR(e.area_after, area_all, 1e-9 * area_all) << what;
      }
    }
  }
}

TEST(RepairByParts, Stress100kHolesTouchingTheShellEqualsWholeMakeValid) {
  const char* on = std::getenv("DECALPREP_STRESS_CLEAN");
  if (!on || std::string(on) != "1")
    GTEST_SKIP() << "set DECALPREP_STRESS_CLEAN=1 (ctest -L stress)";
  Geos geos;
  const Rings rings = touching_100k();
  const G whole = polygon_of(geos.h, rings);
  for (const bool structure : {false, true}) {
    using clock = std::chrono::steady_clock;
    const auto t0 = clock::now();
    const prep::SceneFeatures out =
        clean_one(rings, structure ? prep::RepairMethod::structure : prep::RepairMethod::linework);
    const auto t1 = clock::now();
    std::vector<G> polys;
    for (const prep::ScenePolygon& p : out.polygons)
      polys.push_back(prep::test::polygon(geos.h, p));
    const G got = multipolygon(geos.h, std::move(polys));
    const G want = polygonal(geos.h, make_valid(geos.h, whole.g, structure).g);
    const auto t2 = clock::now();
    std::printf("%s: clean %.1f s, GEOS MakeValid of the whole %.1f s\n", method_name(structure),
                std::chrono::duration<double>(t1 - t0).count(),
                std::chrono::duration<double>(t2 - t1).count());
    expect_same(geos.h, got, want, std::string("100k, ") + method_name(structure));
  }
}

}  // namespace

}  // namespace clean_repair_by_parts
