// PartSimplifier and part_area / part_length (prep/clean.hpp), the overview
// levels' simplification (formats/SPEC.md "Overview levels"): the result
// lies within the tolerance of the part by GEOS's Hausdorff distance (both
// ways), stays valid and oriented, and the measures are the analytic ones.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "geos_oracle.hpp"
#include "prep/clean.hpp"
#include "test_support.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace clean_part_simplifier {

namespace {

using prep::Point2, prep::Ring, prep::test::G, prep::test::Geos;

// A circle of radius r with n vertices whose radius wobbles by +-wobble.
Ring wobbly_circle(double cx, double cy, double r, int n, double wobble, bool ccw) {
  Ring out;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    const double rr = r + wobble * ((i % 3) - 1);
    out.push_back({cx + rr * std::cos(a), cy + rr * std::sin(a)});
  }
  if (!ccw) std::reverse(out.begin(), out.end());
  return out;
}

double hausdorff(GEOSContextHandle_t h, const G& a, const G& b) {
  double d = -1;
  EXPECT_EQ(GEOSHausdorffDistanceDensify_r(h, a.g, b.g, 0.01, &d), 1);
  return d;
}

TEST(PartSimplifier, APolygonWithAHoleStaysWithinTheToleranceValidAndOriented) {
  Geos geos;
  prep::ScenePolygon p;
  p.shell = wobbly_circle(0, 0, 100, 400, 0.3, true);
  p.holes.push_back(wobbly_circle(10, 0, 40, 200, 0.2, false));
  p.area = 123.0;  // the feature's key: left alone
  const prep::ScenePolygon before = p;
  const double tol = 1.0;
  prep::PartSimplifier s(tol);
  ASSERT_TRUE(s.polygon(p, "test"));
  EXPECT_LT(p.shell.size(), before.shell.size() / 4);
  ASSERT_EQ(p.holes.size(), 1u);
  EXPECT_GT(prep::test::ring_area(p.shell), 0);
  EXPECT_LT(prep::test::ring_area(p.holes[0]), 0);
  EXPECT_EQ(p.area, 123.0);
  EXPECT_TRUE(prep::test::is_valid(geos.h, p));
  const double d =
      hausdorff(geos.h, prep::test::polygon(geos.h, before), prep::test::polygon(geos.h, p));
  EXPECT_LE(d, tol + 1e-9);
  EXPECT_GT(d, 0.1);  // it did simplify
}

// A polygon whose holes crowd its shell and each other: small wobbly
// circles placed at random, some within the tolerance of the shell, so
// that simplifying each ring alone often makes them cross or leave the
// shell. Only holes that keep the polygon valid are placed (GEOS decides).
prep::ScenePolygon crowded(GEOSContextHandle_t h, prep::test::Rng& rng) {
  prep::ScenePolygon p;
  p.shell = wobbly_circle(0, 0, 100, 240 + rng.below(240), 0.6, true);
  const int holes = 4 + rng.below(24);
  for (int k = 0; k < holes; ++k) {
    // Half of them with their outer side 0.2 to 1.4 from the shell's circle.
    const double a = rng.in(0, 2 * M_PI), size = rng.in(0.8, 4);
    const double r = rng.uniform() < 0.5 ? 100 - size - rng.in(0.2, 1.4) : rng.in(0, 90);
    Ring hole = wobbly_circle(r * std::cos(a), r * std::sin(a), size, 8 + rng.below(24),
                              rng.in(0, 0.4), false);
    p.holes.push_back(std::move(hole));
    if (!prep::test::is_valid(h, p)) p.holes.pop_back();
  }
  return p;
}

bool vertices_are_the_parts(const Ring& simple, const Ring& part) {
  std::vector<std::pair<double, double>> all;
  for (const Point2& v : part) all.push_back({v.x, v.y});
  std::sort(all.begin(), all.end());
  return std::all_of(simple.begin(), simple.end(), [&](const Point2& v) {
    return std::binary_search(all.begin(), all.end(), std::make_pair(v.x, v.y));
  });
}

// The oracle: GEOS isValid of the result, GEOS's Hausdorff distance within
// the tolerance, every vertex one of the part's, orientations kept.
TEST(PartSimplifier, CrowdedHolesStayValidWithinTheToleranceAndMostNeedNoGeos) {
  Geos geos;
  prep::test::Rng rng(20261128);
  const double tol = 1.5;
  prep::PartSimplifier s(tol);
  int parts = 0, holes = 0;
  for (int k = 0; k < 2000; ++k) {
    prep::ScenePolygon p = crowded(geos.h, rng);
    const prep::ScenePolygon before = p;
    ++parts;
    holes += int(p.holes.size());
    ASSERT_TRUE(s.polygon(p, "crowded"));
    ASSERT_TRUE(prep::test::is_valid(geos.h, p)) << "sample " << k;
    ASSERT_EQ(p.holes.size(), before.holes.size());
    EXPECT_GT(prep::test::ring_area(p.shell), 0);
    EXPECT_TRUE(vertices_are_the_parts(p.shell, before.shell)) << "sample " << k;
    // What comes back is the sections at the problems, not the whole shell.
    EXPECT_LT(p.shell.size(), before.shell.size() / 2) << "sample " << k;
    for (size_t i = 0; i < p.holes.size(); ++i) {
      EXPECT_LT(prep::test::ring_area(p.holes[i]), 0);
      EXPECT_TRUE(vertices_are_the_parts(p.holes[i], before.holes[i])) << "sample " << k;
    }
    // Vertex to geometry, both ways (a segment between two vertices within
    // the tolerance of one chord lies within it too).
    double d = -1;
    ASSERT_EQ(GEOSHausdorffDistance_r(geos.h, prep::test::polygon(geos.h, before).g,
                                      prep::test::polygon(geos.h, p).g, &d),
              1);
    EXPECT_LE(d, tol + 1e-9) << "sample " << k;
  }
  const prep::PartSimplifier::Counts& c = s.counts();
  std::printf(
      "%d parts, %d holes: %llu proved valid (%llu after giving %llu sections back), "
      "%llu left to GEOS\n",
      parts, holes, (unsigned long long)c.proved, (unsigned long long)c.with_sections_back,
      (unsigned long long)c.sections_back, (unsigned long long)c.geos);
  EXPECT_EQ(c.proved + c.geos, uint64_t(parts));
  // The sections given back are what makes crowded parts valid (78 of the
  // 2,000 here): without them each such part would go to GEOS, more than
  // the 1% allowed.
  EXPECT_GT(c.with_sections_back, uint64_t(parts / 50));
  EXPECT_LT(c.geos, uint64_t(parts / 100 + 1));
}

TEST(PartSimplifier, ALineStaysWithinTheTolerance) {
  Geos geos;
  prep::SceneLine l;
  for (int i = 0; i <= 200; ++i) l.points.push_back({i * 1.0, (i % 2) * 0.4 + 0.01 * i * i});
  const prep::SceneLine before = l;
  prep::PartSimplifier s(0.5);
  ASSERT_TRUE(s.line(l, "test"));
  EXPECT_LT(l.points.size(), before.points.size());
  EXPECT_LE(hausdorff(geos.h, prep::test::line(geos.h, before), prep::test::line(geos.h, l)),
            0.5 + 1e-9);
}

TEST(PartSimplifier, AClosedLineStaysARing) {
  Geos geos;
  prep::SceneLine ring;
  ring.closed = true;
  ring.points = wobbly_circle(0, 0, 50, 120, 0.1, true);
  const prep::SceneLine before = ring;
  prep::PartSimplifier s(0.5);
  ASSERT_TRUE(s.line(ring, "test"));
  EXPECT_GE(ring.points.size(), 3u);
  EXPECT_FALSE(ring.points.front().x == ring.points.back().x &&
               ring.points.front().y == ring.points.back().y);
  EXPECT_LE(hausdorff(geos.h, prep::test::line(geos.h, before), prep::test::line(geos.h, ring)),
            0.5 + 1e-9);
  // A ring much smaller than the tolerance stays a ring of three corners or
  // more (GEOS keeps rings; a level drops it by its length, not here).
  prep::SceneLine tiny;
  tiny.closed = true;
  tiny.points = {{0, 0}, {0.1, 0}, {0.1, 0.1}, {0, 0.1}};
  prep::PartSimplifier coarse(5.0);
  ASSERT_TRUE(coarse.line(tiny, "test"));
  EXPECT_GE(tiny.points.size(), 3u);
}

TEST(PartSimplifier, AreaAndLengthAreTheAnalyticOnes) {
  prep::ScenePolygon p;
  p.shell = {{0, 0}, {10, 0}, {10, 10}, {0, 10}};
  p.holes = {{{2, 2}, {2, 4}, {4, 4}, {4, 2}}};
  EXPECT_DOUBLE_EQ(prep::part_area(p), 100.0 - 4.0);
  prep::SceneLine l;
  l.points = {{0, 0}, {3, 4}, {3, 10}};
  EXPECT_DOUBLE_EQ(prep::part_length(l), 5.0 + 6.0);
  l.closed = true;  // the closing segment from (3, 10) back to (0, 0)
  EXPECT_DOUBLE_EQ(prep::part_length(l), 11.0 + std::sqrt(9.0 + 100.0));
}

}  // namespace

}  // namespace clean_part_simplifier
