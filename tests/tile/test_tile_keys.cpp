// Tile keys and the grid (formats/SPEC.md "Tiling scheme", "Overview
// levels"): names and paths of tiles, squares and origins, which tile holds
// a point on a border, parents and children across levels, the level rule,
// the stroke margin arithmetic. Every expected value is worked out by hand
// from the SPEC's definitions.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>

#include "prep/error.hpp"
#include "prep/tile.hpp"
#include "tile_scenes.hpp"

namespace {

using prep::Extent;
using prep::TileKey;

prep::TilePlan grid(double size) {
  prep::TilePlan p;
  p.size = size;
  return p;
}

void expect_extent(const Extent& e, double xmin, double ymin, double xmax, double ymax) {
  EXPECT_EQ(e.xmin, xmin);
  EXPECT_EQ(e.ymin, ymin);
  EXPECT_EQ(e.xmax, xmax);
  EXPECT_EQ(e.ymax, ymax);
}

TEST(TileKeys, NamesAndFilesSpellTheKeyWithItsSign) {
  EXPECT_EQ(prep::tile_name({0, 0}), "x0_y0");
  EXPECT_EQ(prep::tile_name({3, -2}), "x3_y-2");
  EXPECT_EQ(prep::tile_name({-1000000000000, 7}), "x-1000000000000_y7");
  EXPECT_EQ(prep::tile_file(0, {0, 0}), "tiles/x0_y0.decals");
  EXPECT_EQ(prep::tile_file(0, {-4, 12}), "tiles/x-4_y12.decals");
  EXPECT_EQ(prep::tile_file(3, {-1, 5}), "tiles/L3/x-1_y5.decals");
  EXPECT_EQ(prep::tile_file(16, {0, -1}), "tiles/L16/x0_y-1.decals");
}

TEST(TileKeys, KeysSortByXThenY) {
  // tileset.json lists tiles "sorted by X then Y"; the plan is a map on TileKey.
  std::map<TileKey, int> m{{{1, -5}, 0}, {{0, 5}, 1}, {{1, 3}, 2}, {{-1, 9}, 3}, {{1, 2}, 4}};
  std::vector<TileKey> order;
  for (const auto& [k, v] : m) order.push_back(k);
  const std::vector<TileKey> want{{-1, 9}, {0, 5}, {1, -5}, {1, 2}, {1, 3}};
  EXPECT_EQ(order, want);
}

TEST(TileKeys, SquareAndOriginAreOnTheGridAnchoredAtZero) {
  const prep::TilePlan p = grid(250);
  expect_extent(p.square({0, 0}), 0, 0, 250, 250);
  expect_extent(p.square({-1, -1}), -250, -250, 0, 0);
  expect_extent(p.square({2, -3}), 500, -750, 750, -500);
  EXPECT_EQ(p.origin({0, 0}), std::make_pair(125.0, 125.0));
  EXPECT_EQ(p.origin({2, -3}), std::make_pair(625.0, -625.0));
  EXPECT_EQ(p.origin({-1, 0}), std::make_pair(-125.0, 125.0));
}

TEST(TileKeys, ThePointOnABorderBelongsToTheTileAboveIt) {
  // Half-open squares [X*s, (X+1)*s): a box of one point, grown by nothing.
  auto key_of = [](double x, double y) {
    const prep::TileRange r = prep::tile_range({x, y, x, y}, 0, 0, 0, 250);
    EXPECT_EQ(r.lo, r.hi);
    return r.lo;
  };
  EXPECT_EQ(key_of(0, 0), (TileKey{0, 0}));
  EXPECT_EQ(key_of(250, 0), (TileKey{1, 0}));
  EXPECT_EQ(key_of(249.999, 249.999), (TileKey{0, 0}));
  EXPECT_EQ(key_of(-0.001, 250), (TileKey{-1, 1}));
  EXPECT_EQ(key_of(-250, -250.001), (TileKey{-1, -2}));
}

TEST(TileKeys, RangeGrowsTheBoxAndAddsTheFrameOrigin) {
  // Local box [0, 1000]^2 around origin (500, -500), grown by 1:
  // absolute [499, -501] .. [1501, 501] -> x 1..6, y -3..2 at 250 m.
  const prep::TileRange r = prep::tile_range({0, 0, 1000, 1000}, 1, 500, -500, 250);
  EXPECT_EQ(r.lo, (TileKey{1, -3}));
  EXPECT_EQ(r.hi, (TileKey{6, 2}));
  EXPECT_TRUE(r.holds({1, -3}));
  EXPECT_TRUE(r.holds({6, 2}));
  EXPECT_FALSE(r.holds({0, 0}));
  EXPECT_FALSE(r.holds({6, 3}));
  EXPECT_FALSE(r.holds({7, -3}));
}

TEST(TileKeys, KeysAtTheIndexBoundStayExact) {
  // tileset.json's coordinate bound is +-1e12 m, a key of +-1e12 at 1 m.
  const int64_t k = 1'000'000'000'000;
  const prep::TilePlan one = grid(1);
  expect_extent(one.square({k - 1, -k}), 1e12 - 1, -1e12, 1e12, -1e12 + 1);
  EXPECT_EQ(one.origin({k - 1, -k}), std::make_pair(1e12 - 0.5, -1e12 + 0.5));
  // The largest tile: 4000 km; a point 1e12 m out is in tile 250000.
  const prep::TileRange r =
      prep::tile_range({1e12, -1e12, 1e12, -1e12}, 0, 0, 0, prep::kMaxTileSize);
  EXPECT_EQ(r.lo, (TileKey{250000, -250000}));
  expect_extent(grid(prep::kMaxTileSize).square({250000, -250000}), 1e12, -1e12, 1e12 + 4e6,
                -1e12 + 4e6);
}

TEST(TileKeys, TileSizeIsCheckedAgainstTheClosedRange) {
  EXPECT_NO_THROW(prep::check_tile_size(1));
  EXPECT_NO_THROW(prep::check_tile_size(4'000'000));
  EXPECT_NO_THROW(prep::check_tile_size(250));
  for (double bad : {0.0, 0.999, -250.0, 4'000'000.5, std::numeric_limits<double>::quiet_NaN(),
                     std::numeric_limits<double>::infinity()}) {
    EXPECT_THROW(prep::check_tile_size(bad), prep::usage_error) << bad;
  }
}

TEST(TileKeys, LevelParametersFollowTheSpecRule) {
  // s * 2^L, r = that / 1024, min_area r^2, min_length r.
  const prep::TileLevel l3 = prep::level_parameters(250, 3);
  EXPECT_EQ(l3.level, 3);
  EXPECT_EQ(l3.tile_size, 2000.0);
  EXPECT_EQ(l3.resolution, 1.953125);
  EXPECT_EQ(l3.min_area, 3.814697265625);
  EXPECT_EQ(l3.min_length, 1.953125);
  EXPECT_TRUE(l3.tiles.empty());
  EXPECT_TRUE(l3.layers.empty());
  // The deepest level of the smallest tile.
  const prep::TileLevel l16 = prep::level_parameters(1, prep::kMaxLevels);
  EXPECT_EQ(l16.tile_size, 65536.0);
  EXPECT_EQ(l16.resolution, 64.0);
  EXPECT_EQ(l16.min_area, 4096.0);
  // Tolerances: an eighth of the resolution; a line narrower than a pixel:
  // an eighth of its width.
  EXPECT_EQ(prep::level_tolerance(l3), 1.953125 / 8);
  EXPECT_EQ(prep::level_line_tolerance(l3, 1.0), 0.125);
  EXPECT_EQ(prep::level_line_tolerance(l3, 40.0), 1.953125 / 8);
  EXPECT_EQ(prep::level_line_tolerance(l3, 0.0), 1.953125 / 8);
}

TEST(TileKeys, AParentSquareIsItsFourChildrenAndHoldsTheirCentres) {
  // Level L tile (X, Y) covers level L-1 tiles (2X..2X+1, 2Y..2Y+1).
  const double s = 250;
  for (int level = 1; level <= 3; ++level) {
    const prep::TilePlan parent = grid(std::ldexp(s, level));
    const prep::TilePlan child = grid(std::ldexp(s, level - 1));
    for (const TileKey P : {TileKey{0, 0}, TileKey{-1, 0}, TileKey{3, -2}, TileKey{-5, -7}}) {
      const Extent ps = parent.square(P);
      const Extent lo = child.square({2 * P.x, 2 * P.y});
      const Extent hi = child.square({2 * P.x + 1, 2 * P.y + 1});
      expect_extent(ps, lo.xmin, lo.ymin, hi.xmax, hi.ymax);
      EXPECT_EQ(lo.xmax, hi.xmin);  // the children share the middle line
      // Each child's centre lies in the parent: its key at the parent's size
      // is floor(child / 2), also for negative keys.
      for (int64_t dx = 0; dx < 2; ++dx)
        for (int64_t dy = 0; dy < 2; ++dy) {
          const TileKey c{2 * P.x + dx, 2 * P.y + dy};
          const auto [cx, cy] = child.origin(c);
          EXPECT_EQ(prep::tile_range({cx, cy, cx, cy}, 0, 0, 0, parent.size).lo, P);
        }
    }
  }
}

TEST(TileKeys, TilesInMeetsViewsAsHalfOpenSquares) {
  prep::TilesetIndex ix;
  ix.tile_size = 250;
  const prep::TilePlan p = grid(250);
  for (int64_t x = 0; x < 2; ++x)
    for (int64_t y = 0; y < 2; ++y) {
      prep::TileEntry e;
      e.key = {x, y};
      e.square = p.square(e.key);
      ix.tiles.push_back(e);
    }
  auto keys = [&](const Extent& v) {
    std::vector<TileKey> out;
    for (const prep::TileEntry* t : prep::tiles_in(ix, v)) out.push_back(t->key);
    return out;
  };
  // A view that only touches tile (0, 0) along x = 250 does not meet it.
  EXPECT_EQ(keys({250, 0, 500, 100}), (std::vector<TileKey>{{1, 0}}));
  EXPECT_EQ(keys({249.5, 0, 500, 100}), (std::vector<TileKey>{{0, 0}, {1, 0}}));
  EXPECT_EQ(keys({100, 100, 400, 400}).size(), 4u);
  EXPECT_TRUE(keys({500, 500, 600, 600}).empty());
  EXPECT_TRUE(keys({-100, 0, 0, 250}).empty());
}

TEST(TileKeys, StrokeMarginIsTheWidestMiterReachPlusOnePercent) {
  prep::ModelOptions o;
  o.miter_limit_deg = 60;  // sin(30 deg) = 1/2: the reach is the half band twice
  EXPECT_NEAR(prep::stroke_margin_of(5, o), 10.1, 1e-12);
  EXPECT_EQ(prep::stroke_margin_of(0.1, o), 1.0);  // never below 1 m
  EXPECT_EQ(prep::stroke_margin_of(0, o), 1.0);
  o.miter_limit_deg = 180;  // sin(90 deg) = 1
  EXPECT_NEAR(prep::stroke_margin_of(5, o), 5.05, 1e-12);
  o.miter_limit_deg = 0;  // clamped to 1 degree
  EXPECT_NEAR(prep::stroke_margin_of(5, o), 5.05 / std::sin(M_PI / 360), 1e-9);

  // The half band: half the width; an inset / offset outline's whole width.
  prep::SceneFeatures s = tile_test::scene();
  s.lines.push_back(tile_test::line(1, tile_test::kRoads, {{0, 0}, {10, 0}}, 4));
  EXPECT_EQ(prep::stroke_half_width(s), 2.0);
  s.lines.push_back(tile_test::line(2, tile_test::kOutlines, tile_test::rect(0, 0, 5, 5), 3, true));
  EXPECT_EQ(prep::stroke_half_width(s), 3.0);
  s.lines.push_back(tile_test::line(3, tile_test::kRoads, {{0, 0}, {1, 0}},
                                    std::numeric_limits<double>::quiet_NaN()));
  EXPECT_EQ(prep::stroke_half_width(s), 3.0);  // a NaN width is no reach
  o.miter_limit_deg = 60;
  EXPECT_NEAR(prep::stroke_margin(s, o), 6.06, 1e-12);
}

TEST(TileKeys, RingBoxOfAnEmptyRingIsInverted) {
  const Extent b = prep::ring_box({});
  EXPECT_GT(b.xmin, b.xmax);
  EXPECT_GT(b.ymin, b.ymax);
  expect_extent(prep::ring_box({{3, -1}, {-2, 4}, {1, 1}}), -2, -1, 3, 4);
}

}  // namespace
