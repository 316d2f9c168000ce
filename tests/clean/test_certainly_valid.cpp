// The validity fast path of clean (libprep/clean/detail/certainly_valid.hpp)
// against GEOS isValid in double precision on the same rings. The function
// is a one-sided proof: whenever it says "valid", GEOS must agree. It must
// also prove most plainly valid polygons (simple shells, holes well inside
// and apart), or it has degenerated into "never sure".
//
// Generated rings, all from one fixed seed: simple star-shaped shells with
// 0..8 holes; self-touching and self-crossing shells; holes inside, outside,
// touching and crossing the shell, nested and overlapping holes; collinear,
// duplicate and spike vertices; vertices nudged a few ulps around an edge;
// random point sets; star shells whose angles swap (crossings), snapped to a
// grid (touching); each under exact and rounding (rotated) placements, near
// the origin and at UTM-sized offsets.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "detail/certainly_valid.hpp"
#include "geos_oracle.hpp"
#include "test_support.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace clean_certainly_valid {

namespace {

using prep::Point2;
using prep::Ring;
using Rings = std::vector<Ring>;

using prep::test::describe;
using prep::test::Rng;

// n vertices around c at increasing angles (jitter < 1 keeps them in order:
// a simple star-shaped ring; jitter > 1 lets neighbours swap: crossings),
// radii between rmin * r and r.
Ring star(Rng& rng, Point2 c, double r, int n, double jitter, double rmin, bool clockwise) {
  Ring ring;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * (i + jitter * (rng.uniform() - 0.5)) / n;
    const double rr = r * (rmin + (1 - rmin) * rng.uniform());
    ring.push_back({c.x + rr * std::cos(a), c.y + rr * std::sin(a)});
  }
  if (clockwise) std::reverse(ring.begin(), ring.end());
  return ring;
}

Ring from(std::initializer_list<std::pair<double, double>> pts) {
  Ring r;
  for (const auto& [x, y] : pts) r.push_back({x, y});
  return r;
}

// Where a sample is placed: exact (a power-of-two scale and an offset that
// keep small integer coordinates exact) or rotated (every coordinate rounded).
Rings place(const Rings& rings, Rng& rng) {
  const int mode = rng.below(4);
  const double scale = std::ldexp(1.0, rng.below(21) - 10);  // 2^-10 .. 2^10
  const double ox = mode >= 2 ? 500000 : 0, oy = mode >= 2 ? 4800000 : 0;
  const bool rotate = mode % 2 == 1;
  return prep::test::placed(rings, scale, ox, oy, 2 * M_PI * rng.uniform(), rotate);
}

// ------------------------------------------------------------- generators --

// A simple star shell with 0..8 holes, each a small star well inside the
// shell and apart from the others: GEOS-valid by construction.
Rings plainly_valid(Rng& rng) {
  const double r = 100;
  const int n = 8 + rng.below(40);
  // Vertices at radius >= 0.6 r, neighbours < 1.9 * 2 pi / 8 apart: the
  // disc of radius 0.6 r cos(0.75) > 0.43 r around the centre is inside.
  Rings rings{star(rng, {0, 0}, r, n, 0.9, 0.6, rng.below(2) == 1)};
  const int holes = rng.below(9);
  for (int k = 0; k < holes; ++k) {
    const double a = 2 * M_PI * k / holes;
    const double hr =
        0.9 * (holes == 1 ? 0.15 * r : std::min(0.15 * r, 0.2 * r * std::sin(M_PI / holes)));
    const Point2 c{0.2 * r * std::cos(a), 0.2 * r * std::sin(a)};
    rings.push_back(star(rng, c, hr, 4 + rng.below(9), 0.5, 0.5, rng.below(2) == 1));
  }
  return rings;
}

// A star shell of radius 100 with 9..200 small holes scattered inside the
// disc of radius 43 (inside the shell, see plainly_valid) on a grid of
// cells, one hole per cell, apart: GEOS-valid. With `misplace`, every
// other polygon has one hole, anywhere in the list, disturbed: moved out to
// radius 90..140 (outside or across the shell), put inside the previous
// hole, or grown over its neighbour; a single such hole among up to 200
// must stop the proof.
Rings many_holes(Rng& rng, bool misplace) {
  const double r = 100;
  Rings rings{star(rng, {0, 0}, r, 16 + rng.below(40), 0.9, 0.6, rng.below(2) == 1)};
  const int holes = 9 + rng.below(192);
  const int disturbed = misplace && rng.below(2) == 0 ? 1 + rng.below(holes - 1) : -1;
  const int side = int(std::ceil(std::sqrt(double(holes)))) + 1;
  const double cell = 2 * 0.43 * r / std::sqrt(2.0) / side;  // the grid fits the disc
  for (int k = 0; k < holes; ++k) {
    const int row = k / side;
    Point2 c{-0.43 * r / std::sqrt(2.0) + (k % side + 0.5) * cell,
             -0.43 * r / std::sqrt(2.0) + (row + 0.5) * cell};
    double hr = 0.3 * cell;
    if (k == disturbed) {
      switch (rng.below(3)) {
        case 0: {  // out, or across the shell
          const double a = 2 * M_PI * rng.uniform(), d = r * (0.9 + 0.5 * rng.uniform());
          c = {d * std::cos(a), d * std::sin(a)};
          break;
        }
        case 1:  // inside the previous hole
          if (rings.size() > 1) {
            c = rings.back()[0];
            c = {0.5 * (c.x + rings.back()[rings.back().size() / 2].x),
                 0.5 * (c.y + rings.back()[rings.back().size() / 2].y)};
            hr = 0.05 * cell;
          }
          break;
        default:  // over the neighbour
          hr = 0.9 * cell;
      }
    }
    rings.push_back(star(rng, c, hr, 4 + rng.below(9), 0.5, 0.5, rng.below(2) == 1));
  }
  return rings;
}

// Hand-built shapes on small integers (exact before placement).
std::map<std::string, Rings> shapes() {
  const Ring square = from({{0, 0}, {10, 0}, {10, 10}, {0, 10}});
  std::map<std::string, Rings> s;
  s["square"] = {square};
  s["square with a hole"] = {square, from({{3, 3}, {3, 7}, {7, 7}, {7, 3}})};
  s["bow-tie"] = {from({{0, 0}, {10, 10}, {10, 0}, {0, 10}})};
  s["shell touching itself at a vertex"] = {from({{0, 0}, {4, 0}, {2, 2}, {4, 4}, {0, 4}, {2, 2}})};
  s["shell vertex on its own edge"] = {from({{0, 0}, {4, 0}, {4, 2}, {2, 0}, {1, 2}, {0, 2}})};
  s["shell overlapping itself along an edge"] = {
      from({{0, 0}, {6, 0}, {6, 2}, {4, 2}, {4, 0}, {2, 0}, {2, 2}, {0, 2}})};
  s["spike"] = {from({{0, 0}, {4, 0}, {4, 4}, {2, 4}, {2, 6}, {2, 4}, {0, 4}})};
  s["collinear vertices"] = {from({{0, 0}, {5, 0}, {10, 0}, {10, 10}, {0, 10}, {0, 5}})};
  s["duplicate vertices"] = {from({{0, 0}, {10, 0}, {10, 0}, {10, 10}, {0, 10}, {0, 10}})};
  s["hole outside the shell"] = {square, from({{20, 0}, {20, 5}, {25, 5}, {25, 0}})};
  s["hole touching the shell at a point"] = {square, from({{0, 5}, {4, 3}, {4, 7}})};
  s["hole touching the shell along an edge"] = {square, from({{0, 2}, {4, 2}, {4, 6}, {0, 6}})};
  s["hole crossing the shell"] = {square, from({{6, 2}, {14, 2}, {14, 8}, {6, 8}})};
  s["hole containing the shell"] = {square, from({{-5, -5}, {15, -5}, {15, 15}, {-5, 15}})};
  s["hole equal to the shell"] = {square, square};
  s["nested holes"] = {square, from({{1, 1}, {9, 1}, {9, 9}, {1, 9}}),
                       from({{3, 3}, {7, 3}, {7, 7}, {3, 7}})};
  s["holes touching at a point"] = {square, from({{1, 1}, {5, 1}, {5, 5}, {1, 5}}),
                                    from({{5, 5}, {9, 5}, {9, 9}, {5, 9}})};
  s["holes sharing an edge"] = {square, from({{1, 1}, {5, 1}, {5, 5}, {1, 5}}),
                                from({{5, 1}, {9, 1}, {9, 5}, {5, 5}})};
  s["overlapping holes"] = {square, from({{1, 1}, {6, 1}, {6, 6}, {1, 6}}),
                            from({{4, 4}, {9, 4}, {9, 9}, {4, 9}})};
  s["identical holes"] = {square, from({{3, 3}, {7, 3}, {7, 7}, {3, 7}}),
                          from({{3, 3}, {7, 3}, {7, 7}, {3, 7}})};
  s["hole vertex on a hole edge"] = {square, from({{1, 1}, {5, 1}, {5, 5}, {1, 5}}),
                                     from({{5, 3}, {8, 1}, {8, 5}})};
  return s;
}

// A square whose hole has one vertex on the shell's bottom edge at a
// rounded point, then moved k ulps up or down: touching, just inside, or
// just crossing, decided by GEOS in exact arithmetic.
Rings nudged_hole(Rng& rng) {
  const Point2 a{0, 0}, b{10 + rng.uniform(), 0.5 * (rng.uniform() - 0.5)};
  const Ring shell{a, b, {b.x, 10}, {0, 10}};
  const double t = 0.2 + 0.6 * rng.uniform();
  Point2 on{a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)};
  for (int k = rng.below(7) - 3; k != 0; k += k > 0 ? -1 : 1)
    on.y = std::nextafter(on.y, k > 0 ? INFINITY : -INFINITY);
  return {shell, {on, {on.x + 2, 4}, {on.x - 2, 4}}};
}

// Random points in a box: mostly self-crossing.
Rings random_points(Rng& rng) {
  Ring r;
  const int n = 3 + rng.below(10);
  for (int i = 0; i < n; ++i) r.push_back({100 * rng.uniform(), 100 * rng.uniform()});
  return {r};
}

// A star shell with angles that may swap and holes that may cross it or
// each other, half of them snapped to a 1-unit grid (touching, collinear).
Rings random_star(Rng& rng) {
  const bool snap = rng.below(2) == 0;
  const double r = 20 + 80 * rng.uniform();
  Rings rings{star(rng, {0, 0}, r, 4 + rng.below(29), rng.below(4) == 0 ? 3.0 : 0.9, 0.5,
                   rng.below(3) == 0)};
  const int holes = rng.below(4);
  for (int h = 0; h < holes; ++h)
    rings.push_back(star(rng, {r * 0.3 * (rng.uniform() - 0.5), r * 0.3 * (rng.uniform() - 0.5)},
                         r * (h == 2 ? 0.9 : 0.2), 4 + rng.below(7), 0.5, 0.5, rng.below(5) != 0));
  if (snap)
    for (Ring& ring : rings)
      for (Point2& p : ring) p = {std::round(p.x), std::round(p.y)};
  return rings;
}

// --------------------------------------------------------------- oracle --

// GEOS isValid of the polygon (rings[0] shell, then holes); nullopt when
// GEOS cannot even build it (fewer than 3 distinct points in a ring).
std::optional<bool> geos_valid(const prep::test::Geos& geos, const Rings& rings) {
  for (const Ring& r : rings)
    if (r.size() < 3) return std::nullopt;
  prep::ScenePolygon p;
  p.shell = rings[0];
  p.holes.assign(rings.begin() + 1, rings.end());
  prep::test::G g;
  try {
    g = prep::test::polygon(geos.h, p);
  } catch (const std::runtime_error&) {  // GEOS returned null
    return std::nullopt;
  }
  const char v = GEOSisValid_r(geos.h, g.g);
  if (v == 2) return std::nullopt;
  return v == 1;
}

struct Tally {
  int samples = 0, geos_valid = 0, proven = 0;
};

// Checks the one-sided property on one sample and counts it under `kind`.
void check(const prep::test::Geos& geos, const std::string& kind, const Rings& rings,
           std::map<std::string, Tally>& tally) {
  const bool proven = prep::detail::certainly_valid(rings);
  const std::optional<bool> valid = geos_valid(geos, rings);
  Tally& t = tally[kind];
  ++t.samples;
  t.proven += proven;
  if (!valid) {
    EXPECT_FALSE(proven) << kind << ": proven valid, but GEOS cannot build it: " << describe(rings);
    return;
  }
  t.geos_valid += *valid;
  if (proven) {
    EXPECT_TRUE(*valid) << kind << ": proven valid, GEOS says invalid: " << describe(rings);
  }
}

void print(const std::map<std::string, Tally>& tally) {
  for (const auto& [kind, t] : tally)
    std::printf("%-42s %5d samples, %5d valid for GEOS, %5d proven\n", kind.c_str(), t.samples,
                t.geos_valid, t.proven);
}

TEST(CertainlyValid, NeverProvesAPolygonThatGeosCallsInvalid) {
  const prep::test::Geos geos;
  Rng rng(20261123);
  std::map<std::string, Tally> tally;
  for (const auto& [name, rings] : shapes())
    for (int k = 0; k < 40; ++k) check(geos, name, place(rings, rng), tally);
  for (int k = 0; k < 600; ++k)
    check(geos, "hole vertex nudged around the shell edge", place(nudged_hole(rng), rng), tally);
  for (int k = 0; k < 600; ++k) check(geos, "random points", place(random_points(rng), rng), tally);
  for (int k = 0; k < 1500; ++k)
    check(geos, "random star with holes", place(random_star(rng), rng), tally);
  for (int k = 0; k < 500; ++k) check(geos, "plainly valid", place(plainly_valid(rng), rng), tally);
  // More than 8 holes (the indexed placement): some outside the shell,
  // overlapping, nested or crossing it.
  for (int k = 0; k < 300; ++k)
    check(geos, "many holes, some misplaced", place(many_holes(rng, true), rng), tally);
  // Degenerate rings are never proven.
  EXPECT_FALSE(prep::detail::certainly_valid({from({{0, 0}, {1, 0}})}));
  EXPECT_FALSE(
      prep::detail::certainly_valid({from({{0, 0}, {1, 0}, {1, 1}}), from({{0, 0}, {1, 0}})}));
  print(tally);

  // The cases must exercise both answers, or the property proves nothing.
  int samples = 0, invalid = 0, proven = 0;
  for (const auto& [kind, t] : tally) {
    samples += t.samples;
    invalid += t.samples - t.geos_valid;
    proven += t.proven;
  }
  EXPECT_GT(invalid, samples / 4) << "too few GEOS-invalid samples";
  EXPECT_GT(proven, samples / 5) << "too few proven samples";
  // Each hand-built invalid shape really is invalid for GEOS (exact
  // placements keep it so), so the property was tested on it.
  for (const char* kind :
       {"bow-tie", "shell touching itself at a vertex", "shell vertex on its own edge", "spike",
        "hole outside the shell", "hole crossing the shell", "nested holes", "overlapping holes",
        "identical holes"})
    EXPECT_LT(tally[kind].geos_valid, tally[kind].samples) << kind;
}

TEST(CertainlyValid, ProvesAtLeast90PercentOfSimplePolygonsWithHolesApart) {
  const prep::test::Geos geos;
  Rng rng(7);
  int samples = 0, valid = 0, proven = 0;
  for (int k = 0; k < 1000; ++k) {
    const Rings rings = place(plainly_valid(rng), rng);
    ++samples;
    const std::optional<bool> v = geos_valid(geos, rings);
    ASSERT_TRUE(v.has_value() && *v)
        << "the generator made an invalid polygon: " << describe(rings);
    ++valid;
    proven += prep::detail::certainly_valid(rings);
  }
  std::printf("plainly valid: %d samples, %d valid for GEOS, %d proven\n", samples, valid, proven);
  EXPECT_GE(proven, 0.9 * samples);
  // The hand-built valid shapes without touching or collinear points.
  for (const char* kind : {"square", "square with a hole"}) {
    const Rings rings = shapes()[kind];
    EXPECT_TRUE(prep::detail::certainly_valid(rings)) << kind;
  }
}

// Polygons with 9..200 holes apart (the indexed placement) are proven, as
// GEOS finds them valid.
TEST(CertainlyValid, ProvesPolygonsWithManyHolesApart) {
  const prep::test::Geos geos;
  Rng rng(11);
  int proven = 0;
  for (int k = 0; k < 200; ++k) {
    const Rings rings = place(many_holes(rng, false), rng);
    const std::optional<bool> v = geos_valid(geos, rings);
    ASSERT_TRUE(v.has_value() && *v) << "the generator made an invalid polygon";
    proven += prep::detail::certainly_valid(rings);
  }
  std::printf("many holes apart: 200 samples, %d proven\n", proven);
  EXPECT_GE(proven, 180);
}

// A smooth star-shaped ring, r(a) = r (1 + 0.1 sin 5a), n vertices at
// jittered increasing angles.
Ring flower(Rng& rng, Point2 c, double r, int n, bool clockwise) {
  Ring ring;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * (i + 0.5 * (rng.uniform() - 0.5)) / n;
    const double rr = r * (1 + 0.1 * std::sin(5 * a));
    ring.push_back({c.x + rr * std::cos(a), c.y + rr * std::sin(a)});
  }
  if (clockwise) std::reverse(ring.begin(), ring.end());
  return ring;
}

// A valid polygon of 20000 + 500 vertices at a UTM-sized offset is still
// proven (the work budget grows with the vertex count), and GEOS agrees.
TEST(CertainlyValid, ProvesALargeSimplePolygon) {
  const prep::test::Geos geos;
  Rng rng(3);
  const Rings rings{flower(rng, {500000, 4800000}, 1000, 20000, false),
                    flower(rng, {500100, 4800000}, 100, 500, true)};
  const std::optional<bool> v = geos_valid(geos, rings);
  ASSERT_TRUE(v.has_value() && *v);
  EXPECT_TRUE(prep::detail::certainly_valid(rings));
}

}  // namespace

}  // namespace clean_certainly_valid
