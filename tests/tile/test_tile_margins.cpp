// Margins (prep/tile.hpp, formats/SPEC.md "Tiling scheme"): a tile's scene
// holds every part that reaches its square grown by the margin, static
// strokes and polygons by the stroke margin, dynamic lines by half a tile;
// polygons are cut on the grown square's border. Expected areas are worked
// out by hand (rectangles, a diamond's cut corners).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "prep/tile.hpp"
#include "tile_scenes.hpp"

namespace {

using namespace tile_test;
using prep::TileKey;

constexpr double kEps = 1e-3;  // "just inside / outside": far above rounding

std::set<int64_t> line_fids(const std::vector<prep::SceneLine>& lines) {
  std::set<int64_t> out;
  for (const prep::SceneLine& l : lines) out.insert(l.fid);
  return out;
}

bool planned(const prep::TilePlan& p, const TileKey& k) {
  return p.tiles.count(k) != 0;
}

// The one polygon piece of `key`'s scene.
prep::ScenePolygon only_piece(const prep::SceneFeatures& s, const prep::TilePlan& p,
                              const TileKey& key) {
  const prep::SceneFeatures t = prep::tile_scene(s, p, key);
  EXPECT_EQ(t.polygons.size(), 1u) << prep::tile_name(key);
  return t.polygons.empty() ? prep::ScenePolygon{} : t.polygons.front();
}

TEST(TileMargins, APolygonSceneHasTheOneMetreFloorAndHalfATileForDynamicLines) {
  prep::SceneFeatures s = scene();
  s.polygons.push_back(polygon(1, rect(10, 10, 20, 20)));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  EXPECT_EQ(p.size, 250.0);
  EXPECT_EQ(p.margin, 1.0);
  EXPECT_EQ(p.dynamic_margin, 125.0);
}

TEST(TileMargins, AStaticLineJustInsideTheMarginIsKeptJustOutsideIsNot) {
  // Width 10 at a 60 degree miter limit: margin 1.01 * 5 / sin(30 deg) = 10.1.
  prep::ModelOptions o;
  o.miter_limit_deg = 60;
  const double m = 10.1;
  prep::SceneFeatures s = scene();
  const double w = 10;
  s.lines.push_back(line(1, kRoads, {{10, 250 + m - kEps}, {240, 250 + m - kEps}}, w));
  s.lines.push_back(line(2, kRoads, {{10, 250 + m + kEps}, {240, 250 + m + kEps}}, w));
  s.lines.push_back(line(3, kRoads, {{10, -m + kEps}, {240, -m + kEps}}, w));
  s.lines.push_back(line(4, kRoads, {{10, -m - kEps}, {240, -m - kEps}}, w));
  s.lines.push_back(line(5, kRoads, {{250 + m - kEps, 10}, {250 + m - kEps, 240}}, w));
  s.lines.push_back(line(6, kRoads, {{250 + m + kEps, 10}, {250 + m + kEps, 240}}, w));
  const prep::TilePlan p = prep::tile_plan(s, o, 250);
  EXPECT_NEAR(p.margin, m, 1e-12);
  ASSERT_TRUE(planned(p, {0, 0}));
  EXPECT_EQ(p.tiles.at({0, 0}).lines, (std::vector<uint32_t>{0, 2, 4}));
  const prep::SceneFeatures t = prep::tile_scene(s, p, {0, 0});
  EXPECT_EQ(line_fids(t.lines), (std::set<int64_t>{1, 3, 5}));
  // Kept whole, in the tile's coordinates (origin (125, 125)).
  for (const prep::SceneLine& l : t.lines) {
    ASSERT_EQ(l.points.size(), 2u);
    if (l.fid == 1) {
      EXPECT_NEAR(l.points[0].x, 10 - 125, 1e-9);
      EXPECT_NEAR(l.points[0].y, 250 + m - kEps - 125, 1e-9);
      EXPECT_NEAR(l.points[1].x, 240 - 125, 1e-9);
    }
  }
}

TEST(TileMargins, ADynamicLineReachesHalfATile) {
  prep::SceneFeatures s = scene();
  s.dynamic_lines.push_back(line(1, kDynamic, {{10, 375 - kEps}, {240, 375 - kEps}}, 4));
  s.dynamic_lines.push_back(line(2, kDynamic, {{10, 375 + kEps}, {240, 375 + kEps}}, 4));
  s.dynamic_lines.push_back(line(3, kDynamic, {{-125 + kEps, 10}, {-125 + kEps, 240}}, 4));
  s.dynamic_lines.push_back(line(4, kDynamic, {{-125 - kEps, 10}, {-125 - kEps, 240}}, 4));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  EXPECT_EQ(p.dynamic_margin, 125.0);
  EXPECT_EQ(p.margin, 1.0);  // dynamic widths are pixels: no static reach
  const prep::SceneFeatures t = prep::tile_scene(s, p, {0, 0});
  EXPECT_EQ(line_fids(t.dynamic_lines), (std::set<int64_t>{1, 3}));
  EXPECT_TRUE(t.lines.empty());
}

TEST(TileMargins, APolygonWithinTheReachIsKeptVertexForVertex) {
  // Box [200, 250.5] x [10, 20]: inside tile (0, 0)'s reach [-1, 251]^2.
  prep::SceneFeatures s = scene();
  s.polygons.push_back(polygon(7, rect(200, 10, 250.5, 20)));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  const prep::ScenePolygon q = only_piece(s, p, {0, 0});
  ASSERT_EQ(q.shell.size(), 4u);
  const prep::Ring want = rect(75, -115, 125.5, -105);  // minus the origin (125, 125)
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_DOUBLE_EQ(q.shell[i].x, want[i].x) << i;
    EXPECT_DOUBLE_EQ(q.shell[i].y, want[i].y) << i;
  }
  // Tile (1, 0) reaches back to x = 249: it gets [249, 250.5] x [10, 20].
  EXPECT_NEAR(area(only_piece(s, p, {1, 0})), 1.5 * 10, 1e-9);
  EXPECT_EQ(p.tiles.size(), 2u);
}

TEST(TileMargins, APolygonCrossingTheReachIsCutOnItsBorder) {
  prep::SceneFeatures s = scene();
  s.polygons.push_back(polygon(1, rect(100, 100, 400, 200)));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  EXPECT_EQ(p.tiles.size(), 2u);  // x: floor(99/250) .. floor(401/250)
  const prep::ScenePolygon a = only_piece(s, p, {0, 0});
  EXPECT_NEAR(area(a), (251 - 100) * 100.0, 1e-9);
  EXPECT_GT(signed_area(a.shell), 0);  // shells stay counter-clockwise
  const prep::Extent box = prep::ring_box(a.shell);
  EXPECT_NEAR(box.xmax, 251 - 125, 1e-9);  // on the reach, in tile coordinates
  EXPECT_NEAR(box.xmin, 100 - 125, 1e-9);
  EXPECT_NEAR(area(only_piece(s, p, {1, 0})), (400 - 249) * 100.0, 1e-9);
  // The drawing-order key stays the whole feature's.
  EXPECT_EQ(a.area, 300.0 * 100.0);
}

TEST(TileMargins, AHoledPolygonsPiecesHaveTheAreaOfShellMinusHoleInTheReach) {
  // Shell [0, 500]^2, hole [200, 300]^2, 250 m tiles, margin 1: each tile's
  // piece is (shell - hole) within [250x - 1, 250x + 251] x [250y - 1, 250y + 251].
  prep::SceneFeatures s = scene();
  prep::Ring hole = rect(200, 200, 300, 300);
  std::reverse(hole.begin(), hole.end());
  s.polygons.push_back(polygon(1, rect(0, 0, 500, 500), {hole}));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  auto overlap = [](double a0, double a1, double b0, double b1) {
    return std::max(0.0, std::min(a1, b1) - std::max(a0, b0));
  };
  EXPECT_EQ(p.tiles.size(), 16u);  // x, y in -1..2
  double total = 0;
  for (const auto& [k, members] : p.tiles) {
    const double x0 = 250.0 * k.x - 1, x1 = 250.0 * k.x + 251;
    const double y0 = 250.0 * k.y - 1, y1 = 250.0 * k.y + 251;
    const double want = overlap(x0, x1, 0, 500) * overlap(y0, y1, 0, 500) -
                        overlap(x0, x1, 200, 300) * overlap(y0, y1, 200, 300);
    EXPECT_NEAR(area(only_piece(s, p, k)), want, 1e-9 * want) << prep::tile_name(k);
    total += want;
  }
  // The four inner tiles: 251^2 - 51^2 = 60400 each.
  EXPECT_NEAR(area(only_piece(s, p, {1, 1})), 60400, 1e-6);
  EXPECT_GT(total, 250000.0 - 10000.0);
}

TEST(TileMargins, ADiamondLosesFourCornerTrianglesToTheReach) {
  // Centre (125, 125), half-diagonal 200: area 2 * 200^2 = 80000. The reach
  // [-1, 251]^2 cuts 74 m off each corner: four triangles of 74^2.
  prep::SceneFeatures s = scene();
  s.polygons.push_back(polygon(1, {{325, 125}, {125, 325}, {-75, 125}, {125, -75}}));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  EXPECT_NEAR(area(only_piece(s, p, {0, 0})), 80000 - 4 * 74.0 * 74.0, 1e-6);
}

TEST(TileMargins, AnInsetOutlineIsCutAsItsRingAndStaysClosed) {
  // Inset outline: the whole width is the band, 2 m; at 60 degrees the margin
  // is 1.01 * 2 / sin(30 deg) = 4.04. The ring [0, 500]^2 cut to tile
  // (0, 0)'s reach is the ring of [0, 254.04]^2.
  prep::ModelOptions o;
  o.miter_limit_deg = 60;
  prep::SceneFeatures s = scene();
  s.lines.push_back(line(1, kOutlines, rect(0, 0, 500, 500), 2, true));
  const prep::TilePlan p = prep::tile_plan(s, o, 250);
  EXPECT_NEAR(p.margin, 4.04, 1e-12);
  const prep::SceneFeatures t = prep::tile_scene(s, p, {0, 0});
  ASSERT_EQ(t.lines.size(), 1u);
  const prep::SceneLine& l = t.lines.front();
  EXPECT_TRUE(l.closed);
  EXPECT_EQ(l.points.size(), 4u);
  EXPECT_GT(signed_area(l.points), 0);  // the input's orientation
  EXPECT_NEAR(signed_area(l.points), 254.04 * 254.04, 1e-6);
  EXPECT_EQ(l.length, 2000.0);  // drawing order: the whole ring's
}

TEST(TileMargins, AClosedLineWithinTheReachStaysWholeAndClosed) {
  prep::SceneFeatures s = scene();
  s.lines.push_back(line(1, kRoads, rect(10, 10, 100, 100), 0.2, true));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  const prep::SceneFeatures t = prep::tile_scene(s, p, {0, 0});
  ASSERT_EQ(t.lines.size(), 1u);
  EXPECT_TRUE(t.lines[0].closed);
  EXPECT_EQ(t.lines[0].points.size(), 4u);
  EXPECT_NEAR(length(t.lines[0]), 360.0, 1e-9);
}

}  // namespace
