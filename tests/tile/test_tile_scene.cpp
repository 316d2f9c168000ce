// tile_scene (prep/tile.hpp): one tile's cut of a synthetic scene, piece by
// piece, against areas and lengths worked out by hand: a 1000 m square over
// a 4 x 4 grid of 250 m tiles, a polyline crossing tile borders (whole
// segments plus one neighbour at each end), a long segment pulled into the
// tile's safe box, the dash phase of a cut line, the tile's own counts.
#include <gtest/gtest.h>

#include <cmath>

#include "prep/tile.hpp"
#include "tile_scenes.hpp"

namespace {

using namespace tile_test;
using prep::TileKey;

double overlap(double a0, double a1, double b0, double b1) {
  return std::max(0.0, std::min(a1, b1) - std::max(a0, b0));
}

TEST(TileScene, ASquareOverFourByFourTilesCoversEachSquareOnce) {
  // Absolute [0, 1000]^2 in a frame whose origin is (500, 500); 250 m
  // tiles, margin 1 m: tiles x, y in -1..4 (floor(-1/250) .. floor(1001/250)).
  prep::SceneFeatures s = scene(500, 500);
  s.polygons.push_back(polygon(1, rect(-500, -500, 500, 500)));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  ASSERT_EQ(p.tiles.size(), 36u);
  double in_squares = 0;
  int full = 0;
  for (int64_t x = -1; x <= 4; ++x) {
    for (int64_t y = -1; y <= 4; ++y) {
      const TileKey k{x, y};
      ASSERT_TRUE(p.tiles.count(k)) << prep::tile_name(k);
      const prep::SceneFeatures t = prep::tile_scene(s, p, k);
      EXPECT_EQ(t.frame.origin_x, 250.0 * x + 125);
      EXPECT_EQ(t.frame.origin_y, 250.0 * y + 125);
      ASSERT_EQ(t.polygons.size(), 1u) << prep::tile_name(k);
      const prep::ScenePolygon& q = t.polygons[0];
      ASSERT_EQ(q.shell.size(), 4u);
      // The piece: the square within the reach [250x - 1, 250x + 251]^2.
      const double want = overlap(250.0 * x - 1, 250.0 * x + 251, 0, 1000) *
                          overlap(250.0 * y - 1, 250.0 * y + 251, 0, 1000);
      EXPECT_NEAR(area(q), want, 1e-6 * want) << prep::tile_name(k);
      EXPECT_EQ(q.area, 1e6);  // drawing order: the whole square's
      // Its part inside the tile's own square [-125, 125]^2 (tile coordinates).
      const prep::Extent b = prep::ring_box(q.shell);
      const double own = overlap(b.xmin, b.xmax, -125, 125) * overlap(b.ymin, b.ymax, -125, 125);
      const bool inner = x >= 0 && x <= 3 && y >= 0 && y <= 3;
      EXPECT_NEAR(own, inner ? 62500.0 : 0.0, 1e-6 * 62500) << prep::tile_name(k);
      full += own > 0;
      in_squares += own;
      // The tile's counts: one feature, one part, four vertices.
      ASSERT_EQ(t.manifest.layers.size(), s.layers.size());
      EXPECT_EQ(t.manifest.layers[kPolys].read, 1u);
      EXPECT_EQ(t.manifest.layers[kPolys].kept, 1u);
      EXPECT_EQ(t.manifest.layers[kPolys].parts, 1u);
      EXPECT_EQ(t.manifest.layers[kPolys].vertices_out, 4u);
      EXPECT_EQ(t.manifest.layers[kRoads].read, 0u);
      EXPECT_EQ(t.manifest.layers[kPolys].layer, "polys");
    }
  }
  EXPECT_EQ(full, 16);
  EXPECT_NEAR(in_squares, 1e6, 1e-6 * 1e6);
  // An inner tile's extent is its piece's box: the reach, [-126, 126]^2.
  const prep::Extent e = prep::tile_scene(s, p, {1, 2}).extent;
  EXPECT_NEAR(e.xmin, -126, 1e-9);
  EXPECT_NEAR(e.ymax, 126, 1e-9);
}

TEST(TileScene, ALineKeepsTheSegmentsThatReachPlusOneNeighbourEachSide) {
  // Vertices every 100 m on y = 125 from x = 0 to 1000, width 0.2 (margin
  // 1 m). Tile X's reach is [250X - 1, 250X + 251]; the segments whose
  // boxes meet it, grown by one segment each way:
  //   X = -1: seg 0      -> + seg 1     [0, 200]
  //   X =  0: segs 0..2  -> + seg 3     [0, 400]
  //   X =  1: segs 2..5  -> + 1 and 6   [100, 700]
  //   X =  2: segs 4..7  -> + 3 and 8   [300, 900]
  //   X =  3: segs 7..9  -> + 6         [600, 1000]
  //   X =  4: seg 9      -> + 8         [800, 1000]
  prep::SceneFeatures s = scene();
  s.lines.push_back(line(1, kRoads, row(0, 1000, 100, 125), 0.2));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  ASSERT_EQ(p.tiles.size(), 6u);
  const double want[6][2] = {{0, 200}, {0, 400}, {100, 700}, {300, 900}, {600, 1000}, {800, 1000}};
  for (int64_t x = -1; x <= 4; ++x) {
    const prep::SceneFeatures t = prep::tile_scene(s, p, {x, 0});
    ASSERT_EQ(t.lines.size(), 1u) << x;
    const prep::SceneLine& l = t.lines[0];
    const double ox = 250.0 * x + 125;
    const double x0 = want[x + 1][0], x1 = want[x + 1][1];
    ASSERT_EQ(l.points.size(), size_t((x1 - x0) / 100) + 1) << x;
    EXPECT_NEAR(l.points.front().x, x0 - ox, 1e-9) << x;
    EXPECT_NEAR(l.points.back().x, x1 - ox, 1e-9) << x;
    EXPECT_NEAR(l.points.front().y, 0.0, 1e-9);
    EXPECT_NEAR(length(l), x1 - x0, 1e-9) << x;
    EXPECT_FALSE(l.closed);
    EXPECT_EQ(l.length, 1000.0);   // drawing order: the whole line's
    EXPECT_EQ(l.dash_start, 0.0);  // solid: no phase
  }
}

TEST(TileScene, ASegmentLongerThanATilesReachIsPulledIntoItsSafeBox) {
  // One segment from x = -5000 to 5000: tiles floor(-5001/250) = -21 ..
  // floor(5001/250) = 20, 42 of them. Tile X keeps the segment within its
  // square grown by a whole tile, [250X - 250, 250X + 500].
  prep::SceneFeatures s = scene();
  s.lines.push_back(line(1, kRoads, {{-5000, 125}, {5000, 125}}, 0.2));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  EXPECT_EQ(p.tiles.size(), 42u);
  EXPECT_EQ(p.tiles.begin()->first, (TileKey{-21, 0}));
  EXPECT_EQ(p.tiles.rbegin()->first, (TileKey{20, 0}));
  auto piece = [&](int64_t x) {
    const prep::SceneFeatures t = prep::tile_scene(s, p, {x, 0});
    EXPECT_EQ(t.lines.size(), 1u) << x;
    return t.lines.empty() ? prep::SceneLine{} : t.lines[0];
  };
  const prep::SceneLine mid = piece(0);
  ASSERT_EQ(mid.points.size(), 2u);
  EXPECT_NEAR(mid.points[0].x, -375, 1e-9);  // -250 - 125
  EXPECT_NEAR(mid.points[1].x, 375, 1e-9);   // 500 - 125
  const prep::SceneLine first = piece(-21);  // safe [-5500, -4750]
  EXPECT_NEAR(length(first), 250, 1e-9);
  const prep::SceneLine last = piece(20);  // safe [4750, 5500]
  EXPECT_NEAR(length(last), 250, 1e-9);
}

TEST(TileScene, ACutDashedLineStartsAtItsDistanceAlongTheWholeLine) {
  // The same cuts as above on a dashed layer: tile 2's piece starts at
  // x = 300, 300 m along the line; the long segment's tile-0 piece starts
  // where it was pulled in, at x = -250, 4750 m along.
  prep::SceneFeatures s = scene();
  s.lines.push_back(line(1, kDashed, row(0, 1000, 100, 125), 0.2));
  s.lines.push_back(line(2, kDashed, {{-5000, 125}, {5000, 125}}, 0.2));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  const prep::SceneFeatures t2 = prep::tile_scene(s, p, {2, 0});
  ASSERT_EQ(t2.lines.size(), 2u);
  EXPECT_NEAR(t2.lines[0].dash_start, 300, 1e-9);
  const prep::SceneFeatures t0 = prep::tile_scene(s, p, {0, 0});
  ASSERT_EQ(t0.lines.size(), 2u);
  EXPECT_NEAR(t0.lines[0].dash_start, 0, 1e-9);  // the piece starts at the line's start
  EXPECT_NEAR(t0.lines[1].dash_start, 4750, 1e-9);
}

TEST(TileScene, ATileOutsideThePlanIsEmptyWithItsOwnOrigin) {
  prep::SceneFeatures s = scene(10, 20);
  s.manifest.notes = {"flat terrain"};
  s.polygons.push_back(polygon(1, rect(0, 0, 10, 10)));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  const prep::SceneFeatures t = prep::tile_scene(s, p, {100, -100});
  EXPECT_TRUE(t.polygons.empty());
  EXPECT_TRUE(t.lines.empty());
  EXPECT_TRUE(t.dynamic_lines.empty());
  EXPECT_EQ(t.frame.origin_x, 25125.0);
  EXPECT_EQ(t.frame.origin_y, -24875.0);
  EXPECT_EQ(t.layers.size(), s.layers.size());
  EXPECT_EQ(t.manifest.notes, s.manifest.notes);
}

TEST(TileScene, APartTouchingTheReachAlongAnEdgeIsPlannedButLeavesNoPiece) {
  // Box xmax 249 + margin 1 = 250: the box reaches tile (1, 0), whose reach
  // starts at x = 249; the cut is the edge x = 249, no area.
  prep::SceneFeatures s = scene();
  s.polygons.push_back(polygon(1, rect(10, 10, 249, 240)));
  s.polygons.push_back(polygon(2, rect(10, 10, 248.999, 240)));
  const prep::TilePlan p = prep::tile_plan(s, {}, 250);
  ASSERT_EQ(p.tiles.size(), 2u);
  EXPECT_EQ(p.tiles.at({1, 0}).polygons, (std::vector<uint32_t>{0}));
  const prep::SceneFeatures t = prep::tile_scene(s, p, {1, 0});
  EXPECT_TRUE(t.polygons.empty());
  EXPECT_EQ(t.manifest.layers[kPolys].read, 0u);
  EXPECT_EQ(t.manifest.layers[kPolys].parts, 0u);
}

}  // namespace
