// PartSimplifier and part_area / part_length (prep/clean.hpp), the overview
// levels' simplification (formats/SPEC.md "Overview levels"): the result
// lies within the tolerance of the part by GEOS's Hausdorff distance (both
// ways), stays valid and oriented, and the measures are the analytic ones.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "geos_oracle.hpp"
#include "prep/clean.hpp"

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

double signed_area(const Ring& r) {
  double a = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    const Point2& p = r[i];
    const Point2& q = r[(i + 1) % r.size()];
    a += p.x * q.y - q.x * p.y;
  }
  return a / 2;
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
  EXPECT_GT(signed_area(p.shell), 0);
  EXPECT_LT(signed_area(p.holes[0]), 0);
  EXPECT_EQ(p.area, 123.0);
  EXPECT_TRUE(prep::test::is_valid(geos.h, p));
  const double d =
      hausdorff(geos.h, prep::test::polygon(geos.h, before), prep::test::polygon(geos.h, p));
  EXPECT_LE(d, tol + 1e-9);
  EXPECT_GT(d, 0.1);  // it did simplify
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
