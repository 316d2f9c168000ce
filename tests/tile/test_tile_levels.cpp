// Overview levels (formats/SPEC.md "Overview levels"): which parts a level
// keeps. The level filter lives inside the tile step (libprep/pipeline), so
// it is tested through one small in-process tileset build of a synthetic
// scene in absolute UTM metres (the frame CRS is the source's: no
// projection changes a length), read back through read_tileset_index.
//
// 1024 m tiles; level 1: 2048 m tiles, r = 2048 / 1024 = 2 m, min_area
// r^2 = 4 m^2, min_length r = 2 m. X0 = 2048 * 245, Y0 = 2048 * 1954, so
// level-1 tile (245, 1954) starts at (X0, Y0) and level-0 tile (490, 3908)
// too.
//   blocks  P1 3 x 3 (9 m^2, kept)      P2 1.5 x 1.5 (2.25, dropped)
//           P3 2.01^2 (4.0401, kept)    P4 1.99^2 (3.9601, dropped)
//           P5 16 x 16 across x = X0 + 2048 (kept; two level-1 tiles)
//           P6 3 x 3 at Y0 + 1100 (kept; level-0 row 3909)
//   paths   L1 3 m (kept)  L2 1.5 m (dropped)  L3 2.01 m (kept)  L4 1.99 m (dropped)
// --levels auto: level 0 covers the data's box with 3 x 2 = 6 tiles, level
// 1 with 2 x 1 <= 4: one level.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <map>
#include <string>

#include "prep/pipeline.hpp"
#include "prep/tile.hpp"
#include "test_support.hpp"
#include "tile_scenes.hpp"

namespace {

constexpr double X0 = 2048.0 * 245, Y0 = 2048.0 * 1954;

std::string num(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

std::string feature(const std::string& geometry) {
  return R"({"type":"Feature","properties":{},"geometry":)" + geometry + "}";
}

std::string square(double x, double y, double side) {
  const std::string x0 = num(x), y0 = num(y), x1 = num(x + side), y1 = num(y + side);
  return feature(R"({"type":"Polygon","coordinates":[[[)" + x0 + "," + y0 + "],[" + x1 + "," + y0 +
                 "],[" + x1 + "," + y1 + "],[" + x0 + "," + y1 + "],[" + x0 + "," + y0 + "]]]}");
}

// A side x side square with square holes, each (x offset, y offset, side)
// from the square's lower-left corner.
std::string square_with_holes(double x, double y, double side,
                              const std::vector<std::array<double, 3>>& holes) {
  auto ring = [](double x0, double y0, double d, bool cw) {
    const std::string a = num(x0), b = num(y0), c = num(x0 + d), e = num(y0 + d);
    return cw ? "[[" + a + "," + b + "],[" + a + "," + e + "],[" + c + "," + e + "],[" + c + "," +
                    b + "],[" + a + "," + b + "]]"
              : "[[" + a + "," + b + "],[" + c + "," + b + "],[" + c + "," + e + "],[" + a + "," +
                    e + "],[" + a + "," + b + "]]";
  };
  std::string rings = ring(x, y, side, false);
  for (const auto& h : holes) rings += "," + ring(x + h[0], y + h[1], h[2], true);
  return feature(R"({"type":"Polygon","coordinates":[)" + rings + "]}");
}

std::string segment(double x, double y, double len) {
  return feature(R"({"type":"LineString","coordinates":[[)" + num(x) + "," + num(y) + "],[" +
                 num(x + len) + "," + num(y) + "]]}");
}

std::string collection(const std::vector<std::string>& features) {
  std::string s =
      R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"urn:ogc:def:crs:EPSG::32631"}},"features":[)";
  for (size_t i = 0; i < features.size(); ++i) s += (i ? "," : "") + features[i];
  return s + "]}\n";
}

// The layer named `name` of `layers` (zero counts when it is not listed).
prep::LayerCounts layer(const std::vector<prep::LayerCounts>& layers, const std::string& name) {
  for (const prep::LayerCounts& c : layers)
    if (c.layer == name) return c;
  return {};
}

// The tileset of the scene above with `levels` overview levels, built in
// `dir`, its index read back.
// `blocks` replaces the blocks above when given.
prep::TilesetIndex build(const prep::test::TempDir& dir, int levels,
                         const std::vector<std::string>& blocks_features = {}) {
  const std::string blocks = dir.file("blocks.geojson"), paths = dir.file("paths.geojson");
  prep::test::write_text(
      blocks,
      collection(!blocks_features.empty()
                     ? blocks_features
                     : std::vector<std::string>{
                           square(X0 + 100, Y0 + 100, 3), square(X0 + 200, Y0 + 100, 1.5),
                           square(X0 + 300, Y0 + 100, 2.01), square(X0 + 400, Y0 + 100, 1.99),
                           square(X0 + 2040, Y0 + 100, 16), square(X0 + 100, Y0 + 1100, 3)}));
  prep::test::write_text(
      paths, collection({segment(X0 + 500, Y0 + 100, 3), segment(X0 + 500, Y0 + 200, 1.5),
                         segment(X0 + 500, Y0 + 300, 2.01), segment(X0 + 500, Y0 + 400, 1.99)}));
  prep::BuildSpec spec;
  spec.crs = "EPSG:32631";
  spec.assume_crs = "EPSG:32631";
  spec.tile_size = 1024;
  spec.levels = levels;
  prep::LayerSpec b;
  b.name = "blocks";
  b.source = blocks;
  b.kind = prep::DecalKind::polygon;
  prep::LayerSpec p;
  p.name = "paths";
  p.source = paths;
  p.kind = prep::DecalKind::line;
  p.style.width = 0.5;
  spec.layers = {b, p};
  prep::BuildRequest req;
  req.output = dir.file("ts");
  prep::run_build(spec, req);
  return prep::read_tileset_index(req.output);
}

// Each level tile's (blocks, paths) kept counts.
std::map<prep::TileKey, std::pair<uint64_t, uint64_t>> kept_by_tile(
    const std::vector<prep::TileEntry>& tiles, int level) {
  std::map<prep::TileKey, std::pair<uint64_t, uint64_t>> out;
  for (const prep::TileEntry& t : tiles) {
    out[t.key] = {layer(t.layers, "blocks").kept, layer(t.layers, "paths").kept};
    EXPECT_EQ(t.file, prep::tile_file(level, t.key));
  }
  return out;
}

// The scene built once per test program with --levels auto.
class TileLevels : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new prep::test::TempDir("tile_levels");
    index_ = new prep::TilesetIndex(build(*dir_, prep::kLevelsAuto));
  }
  static void TearDownTestSuite() {
    delete index_;
    delete dir_;
  }
  static const prep::TilesetIndex& ix() { return *index_; }

 private:
  static inline prep::test::TempDir* dir_ = nullptr;
  static inline prep::TilesetIndex* index_ = nullptr;
};

TEST_F(TileLevels, AutoStopsAtTheFirstLevelOfAtMostFourTiles) {
  EXPECT_EQ(ix().minor, prep::kTilesetMinorLevels);
  ASSERT_EQ(ix().levels.size(), 1u);
  const prep::TileLevel& l = ix().levels[0];
  EXPECT_EQ(l.level, 1);
  EXPECT_EQ(l.tile_size, 2048.0);
  EXPECT_EQ(l.resolution, 2.0);
  EXPECT_EQ(l.min_area, 4.0);
  EXPECT_EQ(l.min_length, 2.0);
}

TEST_F(TileLevels, LevelZeroKeepsEveryPartInTheTilesItsKeysGive) {
  // (490, 3908): P1-P4 and L1-L4; P5 in 491 and 492; P6 in (490, 3909).
  const auto got = kept_by_tile(ix().tiles, 0);
  const std::map<prep::TileKey, std::pair<uint64_t, uint64_t>> want{
      {{490, 3908}, {4, 4}}, {{491, 3908}, {1, 0}}, {{492, 3908}, {1, 0}}, {{490, 3909}, {1, 0}}};
  EXPECT_EQ(got, want);
  EXPECT_EQ(layer(ix().manifest.layers, "blocks").kept, 6u);
  EXPECT_EQ(layer(ix().manifest.layers, "paths").kept, 4u);
}

TEST_F(TileLevels, PolygonsBelowMinAreaAreDroppedAndCounted) {
  ASSERT_EQ(ix().levels.size(), 1u);
  const prep::LayerCounts c = layer(ix().levels[0].layers, "blocks");
  EXPECT_EQ(c.read, 6u);  // parts_in: P5 once, though two tiles hold it
  EXPECT_EQ(c.parts, 4u);
  EXPECT_EQ(c.dropped_small, 2u);
  EXPECT_EQ(c.vertices_in, 6u * 5);  // rings counted closed
  EXPECT_EQ(c.vertices_out, 4u * 5);
}

TEST_F(TileLevels, LinesBelowMinLengthAreDroppedAndCounted) {
  ASSERT_EQ(ix().levels.size(), 1u);
  const prep::LayerCounts c = layer(ix().levels[0].layers, "paths");
  EXPECT_EQ(c.read, 4u);
  EXPECT_EQ(c.parts, 2u);
  EXPECT_EQ(c.dropped_small, 2u);
  EXPECT_EQ(c.vertices_in, 8u);
  EXPECT_EQ(c.vertices_out, 4u);
}

TEST_F(TileLevels, EachLevelTileHoldsWhatItKeepsOfItsWindow) {
  ASSERT_EQ(ix().levels.size(), 1u);
  const auto got = kept_by_tile(ix().levels[0].tiles, 1);
  // (245, 1954): P1, P3, P5, P6 and L1, L3; (246, 1954): P5.
  const std::map<prep::TileKey, std::pair<uint64_t, uint64_t>> want{{{245, 1954}, {4, 2}},
                                                                    {{246, 1954}, {1, 0}}};
  EXPECT_EQ(got, want);
}

TEST(TileLevelsTwo, TheCoarserLevelKeepsOnlyWhatReachesItsOwnThresholds) {
  // --levels 2: level 2 has 4096 m tiles, r = 4, min_area 16, min_length 4.
  // Only P5 (256 m^2) stays; every path (at most 3 m) goes. Level 2's
  // border x = 4096 * 123 = X0 + 2048 is level 1's: P5 is in two tiles.
  prep::test::TempDir dir("tile_levels2");
  const prep::TilesetIndex ix = build(dir, 2);
  ASSERT_EQ(ix.levels.size(), 2u);
  const prep::TileLevel& l2 = ix.levels[1];
  EXPECT_EQ(l2.level, 2);
  EXPECT_EQ(l2.tile_size, 4096.0);
  EXPECT_EQ(l2.min_area, 16.0);
  EXPECT_EQ(l2.min_length, 4.0);
  const prep::LayerCounts blocks = layer(l2.layers, "blocks"), paths = layer(l2.layers, "paths");
  EXPECT_EQ(blocks.read, 6u);
  EXPECT_EQ(blocks.parts, 1u);
  EXPECT_EQ(blocks.dropped_small, 5u);
  EXPECT_EQ(paths.read, 4u);
  EXPECT_EQ(paths.parts, 0u);
  EXPECT_EQ(paths.dropped_small, 4u);
  const std::map<prep::TileKey, std::pair<uint64_t, uint64_t>> want{{{122, 977}, {1, 0}},
                                                                    {{123, 977}, {1, 0}}};
  EXPECT_EQ(kept_by_tile(l2.tiles, 2), want);
  // Level 1 is the same with or without a level above it.
  EXPECT_EQ(layer(ix.levels[0].layers, "blocks").parts, 4u);
  EXPECT_EQ(layer(ix.levels[0].layers, "paths").parts, 2u);
}

TEST(TileLevelsHoles, HolesBelowMinAreaLeaveTheLevelAndAreCounted) {
  // A 40 m square with holes of 1.9 m (3.61 m^2), 2.1 m (4.41) and 5 m (25)
  // sides. Level 1 (min_area 4) keeps the 2.1 and 5 m holes, level 2
  // (min_area 16) the 5 m one; the part itself (1600 m^2 less its holes)
  // stays on both. Rings are counted closed: 5 vertices each.
  prep::test::TempDir dir("tile_levels_holes");
  const prep::TilesetIndex ix =
      build(dir, 2,
            {square_with_holes(X0 + 100, Y0 + 100, 40, {{2, 2, 1.9}, {10, 10, 2.1}, {20, 20, 5}})});
  ASSERT_EQ(ix.levels.size(), 2u);
  const prep::LayerCounts l1 = layer(ix.levels[0].layers, "blocks");
  const prep::LayerCounts l2 = layer(ix.levels[1].layers, "blocks");
  EXPECT_EQ(l1.parts, 1u);
  EXPECT_EQ(l1.holes_dropped_small, 1u);
  EXPECT_EQ(l1.vertices_in, 4u * 5);
  EXPECT_EQ(l1.vertices_out, 3u * 5);
  EXPECT_EQ(l2.parts, 1u);
  EXPECT_EQ(l2.holes_dropped_small, 2u);
  EXPECT_EQ(l2.vertices_out, 2u * 5);
  // Level 0 keeps every hole.
  EXPECT_EQ(layer(ix.manifest.layers, "blocks").vertices_out, 4u * 5);
  // The per-level note names the holes (the 4 paths, all below 4 m, go too).
  bool noted = false;
  for (const std::string& n : ix.manifest.notes)
    noted = noted ||
            (n.find("overview level 2: 4 of 5 parts dropped_small") == 0 &&
             n.find("; 2 holes of kept parts dropped_small (below 16 m2)") != std::string::npos);
  EXPECT_TRUE(noted);
}

}  // namespace
