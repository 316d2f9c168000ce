// tile_plan (prep/tile.hpp): which tiles a scene makes and which parts
// each tile holds. Tile counts of synthetic scenes worked out by hand, and
// determinism: the same scene in another feature order gives the same tiles
// with the same features, and cutting the tiles on 1 or 4 threads (oneTBB)
// gives the same pieces, bit for bit (formats/SPEC.md "Tilesets": the same
// scene and options give the same bytes, whatever the number of threads).
#include <gtest/gtest.h>

#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <tuple>

#include "prep/error.hpp"
#include "prep/tile.hpp"
#include "test_support.hpp"
#include "tile_scenes.hpp"

namespace {

using namespace tile_test;
using prep::TileKey;

TEST(TilePlan, ASyntheticSceneMakesTheTilesCountedByHand) {
  // 250 m tiles, margin 1 m (width 0.2), dynamic margin 125 m:
  //  polygon [10, 990] x [10, 490]: x floor(9/250)..floor(991/250) = 0..3,
  //    y 0..floor(491/250) = 0..1: 8 tiles;
  //  line (10, 600)-(740, 600): x 0..floor(741/250) = 0..2, y 2: 3 tiles;
  //  dynamic line (1200, 1200)-(1210, 1200): x floor(1075/250)..
  //    floor(1335/250) = 4..5, y 4..5: 4 tiles. 15 in all, none shared.
  prep::SceneFeatures s = scene();
  s.polygons.push_back(polygon(1, rect(10, 10, 990, 490)));
  s.lines.push_back(line(2, kRoads, {{10, 600}, {740, 600}}, 0.2));
  s.dynamic_lines.push_back(line(3, kDynamic, {{1200, 1200}, {1210, 1200}}, 3));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  EXPECT_EQ(p.margin, 1.0);
  EXPECT_EQ(p.dynamic_margin, 125.0);
  ASSERT_EQ(p.tiles.size(), 15u);
  for (int64_t x = 0; x <= 3; ++x)
    for (int64_t y = 0; y <= 1; ++y) {
      const auto& m = p.tiles.at({x, y});
      EXPECT_EQ(m.polygons, (std::vector<uint32_t>{0}));
      EXPECT_TRUE(m.lines.empty() && m.dynamic_lines.empty());
    }
  for (int64_t x = 0; x <= 2; ++x) EXPECT_EQ(p.tiles.at({x, 2}).lines, (std::vector<uint32_t>{0}));
  for (int64_t x = 4; x <= 5; ++x)
    for (int64_t y = 4; y <= 5; ++y)
      EXPECT_EQ(p.tiles.at({x, y}).dynamic_lines, (std::vector<uint32_t>{0}));
}

TEST(TilePlan, AnEmptySceneHasNoTilesAndABadSizeIsRefused) {
  const prep::SceneFeatures s = scene();
  const prep::TilePlan p = prep::tile_plan(s, {}, 1000);
  EXPECT_TRUE(p.tiles.empty());
  EXPECT_EQ(p.margin, 1.0);
  EXPECT_EQ(p.dynamic_margin, 500.0);
  EXPECT_THROW(prep::tile_plan(s, {}, 0.5), prep::usage_error);
  EXPECT_THROW(prep::tile_plan(s, {}, 4'000'001), prep::usage_error);
}

TEST(TilePlan, TheWidestStrokeSetsTheMargin) {
  prep::ModelOptions o;
  o.miter_limit_deg = 60;  // sin(30 deg) = 1/2
  prep::SceneFeatures s = scene();
  s.lines.push_back(line(1, kRoads, {{0, 0}, {10, 0}}, 2));
  s.lines.push_back(line(2, kRoads, {{0, 0}, {10, 0}}, 8));
  s.dynamic_lines.push_back(line(3, kDynamic, {{0, 0}, {10, 0}}, 400));  // pixels: no reach
  EXPECT_NEAR(prep::tile_plan(s, o, 250).margin, 1.01 * 4 * 2, 1e-12);
}

// A scene of random rectangles and polylines over [0, 2000]^2 (300 m tiles
// do not divide it: parts cross borders at every offset), and its features
// in another order.
prep::SceneFeatures random_scene(uint64_t seed) {
  prep::test::Rng rng(seed);
  prep::SceneFeatures s = scene(1000, -3000);
  int64_t fid = 0;
  for (int i = 0; i < 60; ++i) {
    const double x = rng.in(-1000, 900), y = rng.in(3000, 4900);
    s.polygons.push_back(polygon(++fid, rect(x, y, x + rng.in(1, 400), y + rng.in(1, 400))));
  }
  for (int i = 0; i < 60; ++i) {
    prep::Ring r;
    const int n = 2 + rng.below(6);
    for (int k = 0; k < n; ++k) r.push_back({rng.in(-1000, 1000), rng.in(3000, 5000)});
    s.lines.push_back(line(++fid, i % 3 ? kRoads : kDashed, r, rng.in(0.5, 12)));
  }
  for (int i = 0; i < 20; ++i) {
    const double x = rng.in(-1000, 1000), y = rng.in(3000, 5000);
    s.dynamic_lines.push_back(line(++fid, kDynamic, {{x, y}, {x + rng.in(-300, 300), y + 50}}, 4));
  }
  return s;
}

template <class T>
void shuffle(std::vector<T>& v, prep::test::Rng& rng) {
  for (size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[size_t(rng.below(int(i)))]);
}

// The plan as tile -> the fids of its parts, per kind.
using FidPlan = std::map<TileKey, std::array<std::set<int64_t>, 3>>;
FidPlan fids_of(const prep::SceneFeatures& s, const prep::TilePlan& p) {
  FidPlan out;
  for (const auto& [k, m] : p.tiles) {
    auto& f = out[k];
    for (uint32_t i : m.polygons) f[0].insert(s.polygons[i].fid);
    for (uint32_t i : m.lines) f[1].insert(s.lines[i].fid);
    for (uint32_t i : m.dynamic_lines) f[2].insert(s.dynamic_lines[i].fid);
  }
  return out;
}

// Every piece of a tile as (kind, fid, coordinates), sorted: the tile's
// content whatever order the parts came in.
using Piece = std::tuple<int, int64_t, std::vector<double>>;
std::vector<Piece> pieces(const prep::SceneFeatures& t) {
  std::vector<Piece> out;
  auto coords = [](const std::vector<prep::Ring>& rings, double extra) {
    std::vector<double> c{extra};
    for (const prep::Ring& r : rings)
      for (const prep::Point2& q : r) c.insert(c.end(), {q.x, q.y});
    return c;
  };
  for (const prep::ScenePolygon& p : t.polygons) {
    std::vector<prep::Ring> rings{p.shell};
    rings.insert(rings.end(), p.holes.begin(), p.holes.end());
    out.emplace_back(0, p.fid, coords(rings, p.area));
  }
  for (const prep::SceneLine& l : t.lines)
    out.emplace_back(1, l.fid, coords({l.points}, l.dash_start));
  for (const prep::SceneLine& l : t.dynamic_lines)
    out.emplace_back(2, l.fid, coords({l.points}, 0));
  std::sort(out.begin(), out.end());
  return out;
}

TEST(TilePlan, TheTilesAreThoseOfEachPartsGrownBoxCountedFromTheDefinition) {
  // Tile (X, Y) holds a part when the part's box (absolute), grown by the
  // margin, meets [X s, (X+1) s] x [Y s, (Y+1) s]: X from floor((xmin - m)/s)
  // to floor((xmax + m)/s).
  const prep::SceneFeatures s = random_scene(7);
  const double size = 300;
  const prep::TilePlan p = prep::tile_plan(s, {}, size);
  std::set<TileKey> want;
  auto add = [&](const prep::Ring& r, double by) {
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (const prep::Point2& q : r) {
      x0 = std::min(x0, q.x + 1000), x1 = std::max(x1, q.x + 1000);
      y0 = std::min(y0, q.y - 3000), y1 = std::max(y1, q.y - 3000);
    }
    for (auto x = int64_t(std::floor((x0 - by) / size)); x <= int64_t(std::floor((x1 + by) / size));
         ++x)
      for (auto y = int64_t(std::floor((y0 - by) / size));
           y <= int64_t(std::floor((y1 + by) / size)); ++y)
        want.insert({x, y});
  };
  for (const prep::ScenePolygon& q : s.polygons) add(q.shell, p.margin);
  for (const prep::SceneLine& l : s.lines) add(l.points, p.margin);
  for (const prep::SceneLine& l : s.dynamic_lines) add(l.points, 150);
  std::set<TileKey> got;
  for (const auto& [k, m] : p.tiles) got.insert(k);
  EXPECT_EQ(got, want);
  EXPECT_GT(got.size(), 30u);
}

TEST(TilePlan, AnotherFeatureOrderGivesTheSameTilesAndPieces) {
  const prep::SceneFeatures a = random_scene(11);
  prep::SceneFeatures b = a;
  prep::test::Rng rng(99);
  shuffle(b.polygons, rng);
  shuffle(b.lines, rng);
  shuffle(b.dynamic_lines, rng);
  const prep::TilePlan pa = prep::tile_plan(a, {}, 300);
  const prep::TilePlan pb = prep::tile_plan(b, {}, 300);
  EXPECT_EQ(pa.margin, pb.margin);
  ASSERT_EQ(fids_of(a, pa), fids_of(b, pb));
  for (const auto& [k, m] : pa.tiles) {
    const prep::SceneFeatures ta = prep::tile_scene(a, pa, k);
    const prep::SceneFeatures tb = prep::tile_scene(b, pb, k);
    ASSERT_EQ(pieces(ta), pieces(tb)) << prep::tile_name(k);
    EXPECT_EQ(ta.extent.xmin, tb.extent.xmin);
    EXPECT_EQ(ta.extent.ymax, tb.extent.ymax);
  }
}

// Every tile of the plan cut side by side on `threads` threads.
std::vector<std::vector<Piece>> cut_all(const prep::SceneFeatures& s, const prep::TilePlan& p,
                                        int threads) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  std::vector<TileKey> keys;
  for (const auto& [k, m] : p.tiles) keys.push_back(k);
  std::vector<std::vector<Piece>> out(keys.size());
  tbb::parallel_for(size_t(0), keys.size(), [&](size_t i) {
    const prep::SceneFeatures t = prep::tile_scene(s, p, keys[i]);
    out[i] = pieces(t);
  });
  return out;
}

TEST(TilePlan, CuttingOnOneOrFourThreadsGivesTheSamePieces) {
  const prep::SceneFeatures s = random_scene(23);
  const prep::TilePlan p = prep::tile_plan(s, {}, 300);
  const auto one = cut_all(s, p, 1);
  const auto four = cut_all(s, p, 4);
  ASSERT_EQ(one.size(), p.tiles.size());
  size_t n = 0;
  for (size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one[i], four[i]) << i;
    n += one[i].size();
  }
  EXPECT_GT(n, 200u);
  // And the plan made under either limit is the same.
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
  EXPECT_EQ(fids_of(s, prep::tile_plan(s, {}, 300)), fids_of(s, p));
}

}  // namespace
