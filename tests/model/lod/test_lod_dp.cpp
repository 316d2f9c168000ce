// LOCALIS LOD set against an independent Douglas-Peucker oracle, and the
// structural guarantees of the visibility rule (decal/format.hpp).
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>
#include <cmath>
#include <random>

#include "dp_oracle.hpp"
#include "lod/lod.hpp"
#include "lod_chain.hpp"
#include "prep/error.hpp"

namespace {

using lodtest::Pt;
using prep::ivec2;

// ---- oracle: plain recursive Douglas-Peucker (dp_oracle.hpp) ----
using lodtest::oracle_dp;

std::vector<ivec2> random_polyline(std::mt19937_64& rng, size_t n) {
  std::uniform_real_distribution<double> turn(-1.2, 1.2), step(1.0, 60.0), u(0, 1);
  std::vector<ivec2> pts;
  double x = 0, y = 0, dir = u(rng) * 6.28;
  for (size_t i = 0; i < n; ++i) {
    ivec2 q{static_cast<int32_t>(std::llround(x * 1000)),
            static_cast<int32_t>(std::llround(y * 1000))};
    if (pts.empty() || pts.back() != q) pts.push_back(q);
    dir += turn(rng);
    const double s = u(rng) < 0.2 ? 0.0 : step(rng);  // some collinear runs
    x += std::cos(dir) * (s + 0.5);
    y += std::sin(dir) * (s + 0.5);
  }
  return pts;
}

// random_polyline moved by a random offset in [0, spread) on each axis (in
// the integer units of the points), so that lines scattered this way overlap.
std::vector<ivec2> scattered_polyline(std::mt19937_64& rng, size_t n, double spread) {
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<ivec2> pts = random_polyline(rng, n);
  const int32_t dx = static_cast<int32_t>(u(rng) * spread),
                dy = static_cast<int32_t>(u(rng) * spread);
  for (auto& p : pts) p = {p[0] + dx, p[1] + dy};
  return pts;
}

std::vector<Pt> metres(const std::vector<ivec2>& q, bool closed) {
  std::vector<Pt> p;
  for (const auto& v : q) p.push_back({v[0] * 1e-3, v[1] * 1e-3});
  if (closed) p.push_back(p.front());
  return p;
}

TEST(LodSegments, UniformThresholdWithoutDependeesEqualsDouglasPeucker) {
  std::mt19937_64 rng(20240611);
  std::vector<prep::LodInputLine> lines;
  std::uniform_int_distribution<size_t> len(2, 90);
  for (uint32_t i = 0; i < 1000; ++i) {
    prep::LodInputLine l;
    l.points = random_polyline(rng, len(rng));
    l.closed = l.points.size() >= 3 && (i % 5 == 0);
    l.line = i;
    if (l.points.size() < 2) l.points.push_back({l.points[0][0] + 1000, l.points[0][1]});
    lines.push_back(std::move(l));
  }
  prep::LodOptions opt;
  opt.dependees = false;
  const prep::LodSet set = prep::build_lod(lines, opt);
  ASSERT_EQ(set.line_range.size(), lines.size());

  std::uniform_real_distribution<double> u(0, 1);
  size_t compared = 0, simplified = 0;
  for (uint32_t i = 0; i < lines.size(); ++i) {
    const auto p = metres(lines[i].points, lines[i].closed);
    std::vector<double> seen;
    std::vector<bool> all(p.size(), false);
    oracle_dp(p, 0, p.size() - 1, -1.0, all, &seen);
    double emax = 0;
    for (double d : seen) emax = std::max(emax, d);
    for (int trial = 0; trial < 3; ++trial) {
      // A threshold clear of every DP distance (floats are stored).
      double eps = 0;
      for (int tries = 0; tries < 100; ++tries) {
        eps = emax * 1.2 * u(rng) * u(rng);
        bool clear = true;
        for (double d : seen) clear = clear && std::abs(d - eps) > 1e-5 * std::max(1.0, d);
        if (clear) break;
      }
      std::vector<bool> keep(p.size(), false);
      keep.front() = keep.back() = true;
      oracle_dp(p, 0, p.size() - 1, eps, keep, nullptr);
      std::vector<uint32_t> expected;
      for (uint32_t k = 0; k < p.size(); ++k)
        if (keep[k]) expected.push_back(set.line_points[i][0] + k);

      const decal::LodCamera cam{u(rng) * 1000, u(rng) * 1000, u(rng) * 100};
      const auto vis =
          decal::visible_segments(set.points, set.segments, cam, decal::LinearThreshold{eps, 0});
      std::string why;
      const auto chain = lodtest::visible_chain(set, i, vis, &why);
      ASSERT_TRUE(chain) << "line " << i << " eps " << eps << ": " << why;
      EXPECT_EQ(*chain, expected) << "line " << i << " (" << p.size() << " points) eps " << eps;
      ++compared;
      simplified += expected.size() < p.size();
    }
  }
  EXPECT_EQ(compared, 3000u);
  EXPECT_GT(simplified, 1000u) << "thresholds too small to exercise simplification";
}

TEST(LodSegments, AttributedSetHasTwoNMinusOneSegmentsPerLine) {
  std::mt19937_64 rng(7);
  std::vector<prep::LodInputLine> lines;
  for (uint32_t i = 0; i < 50; ++i) {
    prep::LodInputLine l;
    l.points = random_polyline(rng, 2 + i);
    l.line = i;
    if (l.points.size() < 2) continue;
    lines.push_back(l);
  }
  const auto set = prep::build_lod(lines, {});
  for (uint32_t i = 0; i < lines.size(); ++i) {
    const uint32_t n = set.line_points[i][1] - 1;
    EXPECT_EQ(set.line_range[i][1], 2 * n - 1) << "line " << i;
  }
}

// Distance-dependent thresholds (linear, quadratic, steps), with dependees
// and both error rules: always one connected polyline first -> last.
TEST(LodSegments, DistanceDependentThresholdAlwaysGivesConnectedPolyline) {
  std::mt19937_64 rng(99);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<prep::LodInputLine> lines;
  for (uint32_t i = 0; i < 300; ++i) {
    prep::LodInputLine l;
    // Scattered over 2 km so that some overlap (dependees, cycles).
    l.points = scattered_polyline(rng, 3 + i % 60, 2e6);
    l.closed = l.points.size() >= 3 && i % 7 == 0;
    l.line = i;
    if (l.points.size() < 3) continue;
    lines.push_back(std::move(l));
  }
  for (auto rule : {prep::LodErrorRule::dp_exact, prep::LodErrorRule::subtree_max}) {
    prep::LodOptions opt;
    opt.error_rule = rule;
    const auto set = prep::build_lod(lines, opt);
    EXPECT_GT(set.stats.dependee_edges, 0u);
    size_t total_visible = 0, total_original = 0;
    for (int cam_i = 0; cam_i < 60; ++cam_i) {
      const decal::LodCamera cam{u(rng) * 2000, u(rng) * 2000, 10 + u(rng) * 500};
      const double base = u(rng) * 5, slope = u(rng) * 0.05;
      decal::LodThreshold eps;
      switch (cam_i % 3) {
        case 0: eps = decal::LinearThreshold{base, slope}; break;
        case 1: eps = [=](double d) { return base + slope * 0.01 * (d > 0 ? d * d : 0.0); }; break;
        default: eps = [=](double d) { return base * std::floor(std::max(d, 0.0) / 200.0); }; break;
      }
      const auto vis = decal::visible_segments(set.points, set.segments, cam, eps);
      for (uint32_t i = 0; i < lines.size(); ++i) {
        std::string why;
        const auto chain = lodtest::visible_chain(set, i, vis, &why);
        ASSERT_TRUE(chain) << "rule " << int(rule) << " camera " << cam_i << " line " << i << ": "
                           << why;
        total_visible += chain->size() - 1;
        total_original += set.line_points[i][1] - 1;
      }
    }
    EXPECT_LT(total_visible, total_original * 9 / 10) << "thresholds did not simplify";
  }
}

TEST(LodSegments, MutualDependeesAreMergedIntoOneProxy) {
  // Each line's interior point lies inside the other's triangle: a cycle.
  std::vector<prep::LodInputLine> lines(2);
  lines[0].points = {{0, 0}, {10000, 10000}, {20000, 0}};
  lines[0].line = 0;
  lines[1].points = {{0, 12000}, {10000, 1000}, {20000, 12000}};
  lines[1].line = 1;
  const auto set = prep::build_lod(lines, {});
  EXPECT_EQ(set.stats.cycles, 1u);
  EXPECT_EQ(set.stats.points_in_cycles, 2u);
  const auto& a = set.points[1];
  const auto& b = set.points[4];
  EXPECT_EQ(a.eval_x, 10000);
  EXPECT_EQ(a.eval_y, 5500);
  EXPECT_EQ(b.eval_x, a.eval_x);
  EXPECT_EQ(b.eval_y, a.eval_y);
  EXPECT_EQ(a.e_star, b.e_star);
  EXPECT_EQ(a.d_star, b.d_star);
  // Proxy radius: both points are 4.5 m from the centroid.
  EXPECT_GE(a.d_star, 4.5f);
  EXPECT_NEAR(a.e_star, 11.0, 1e-3);  // max of the two DP errors (10 m and 11 m)
  for (double eps : {0.0, 5.0, 10.5, 11.5, 100.0})
    EXPECT_EQ(decal::lod_point_included(a, {3, 4, 5}, decal::LinearThreshold{eps, 0}),
              decal::lod_point_included(b, {3, 4, 5}, decal::LinearThreshold{eps, 0}));
}

TEST(LodSegments, LineEndInsideBaselinePolygonKeepsTheSplitterAlways) {
  // Line 1 ends inside the triangle of line 0's only interior point: that
  // point can never be dropped, whatever the threshold.
  std::vector<prep::LodInputLine> lines(2);
  lines[0].points = {{0, 0}, {10000, 10000}, {20000, 0}};
  lines[1].points = {{10000, 3000}, {10000, -20000}};
  lines[1].line = 1;
  const auto set = prep::build_lod(lines, {});
  EXPECT_TRUE(set.points[1].flags & decal::kLodPointAlways);
  const auto vis =
      decal::visible_segments(set.points, set.segments, {0, 0, 0}, decal::LinearThreshold{1e6, 0});
  std::string why;
  const auto chain = lodtest::visible_chain(set, 0, vis, &why);
  ASSERT_TRUE(chain) << why;
  EXPECT_EQ(chain->size(), 3u);
}

TEST(LodSegments, OutputDoesNotDependOnThreadCount) {
  std::mt19937_64 rng(31);
  std::vector<prep::LodInputLine> lines;
  for (uint32_t i = 0; i < 200; ++i) {
    prep::LodInputLine l;
    l.points = scattered_polyline(rng, 3 + i % 40, 5e5);
    l.line = i;
    if (l.points.size() >= 2) lines.push_back(std::move(l));
  }
  auto bytes = [](const prep::LodSet& s) {
    std::string b(reinterpret_cast<const char*>(s.points.data()),
                  s.points.size() * sizeof(decal::LodPoint));
    b.append(reinterpret_cast<const char*>(s.segments.data()),
             s.segments.size() * sizeof(decal::LodSegment));
    return b;
  };
  std::string one, two;
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 1);
    one = bytes(prep::build_lod(lines, {}));
  }
  {
    tbb::global_control c(tbb::global_control::max_allowed_parallelism, 2);
    two = bytes(prep::build_lod(lines, {}));
  }
  EXPECT_GT(prep::build_lod(lines, {}).stats.dependee_edges, 0u);
  EXPECT_EQ(one, two);
}

TEST(LodSegments, TooShortLineIsAnInputError) {
  std::vector<prep::LodInputLine> lines(1);
  lines[0].points = {{0, 0}};
  EXPECT_THROW(prep::build_lod(lines, {}), prep::input_error);
}

}  // namespace
