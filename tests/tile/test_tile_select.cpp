// Which tiles of a tileset a view draws (prep/tile.hpp), on an index
// in memory: an 8 x 8 grid of 100 m tiles with overview levels 1..3 (200,
// 400, 800 m; resolution S 2^L / 1024), against analytic pixel sizes and
// budgets counted by hand in decoded blob bytes.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "prep/error.hpp"
#include "prep/render.hpp"
#include "prep/tile.hpp"

namespace {

namespace R = prep::render;

constexpr double kTile = 100;
constexpr int kLevels = 3;
constexpr int kGrid = 8;  // level-0 tiles a side
// Package bytes per tile of each level: a parent is smaller than its four children.
constexpr uint64_t kBytes[kLevels + 1] = {1000, 1200, 1500, 2000};
// Decoded blob bytes per tile of each level (what --gpu-budget counts):
// 11 to 12 times the package bytes, as zstd packs real tiles.
constexpr uint64_t kBlobBytes[kLevels + 1] = {11500, 13000, 17000, 23000};

double resolution(int l) {
  return kTile * std::ldexp(1.0, l) / 1024;
}

prep::TileEntry entry(int l, int64_t x, int64_t y) {
  const double s = kTile * std::ldexp(1.0, l);
  prep::TileEntry t;
  t.key = {x, y};
  t.square = {double(x) * s, double(y) * s, double(x + 1) * s, double(y + 1) * s};
  t.origin_x = (double(x) + 0.5) * s;
  t.origin_y = (double(y) + 0.5) * s;
  t.bytes = kBytes[l];
  return t;
}

// The full pyramid over [0, 800)^2; the frame origin at (400, 400).
prep::TilesetIndex pyramid(int levels = kLevels) {
  prep::TilesetIndex ix;
  ix.tile_size = kTile;
  ix.frame.origin_x = ix.frame.origin_y = 400;
  ix.extent = {0, 0, kGrid * kTile, kGrid * kTile};
  for (int64_t x = 0; x < kGrid; ++x)
    for (int64_t y = 0; y < kGrid; ++y) ix.tiles.push_back(entry(0, x, y));
  for (int l = 1; l <= levels; ++l) {
    prep::TileLevel lv;
    lv.level = l;
    lv.tile_size = kTile * std::ldexp(1.0, l);
    lv.resolution = resolution(l);
    const int n = kGrid >> l;
    for (int64_t x = 0; x < n; ++x)
      for (int64_t y = 0; y < n; ++y) lv.tiles.push_back(entry(l, x, y));
    ix.levels.push_back(lv);
  }
  return ix;
}

// Options whose blob_bytes gives kBlobBytes[level] and records each tile
// asked, as "level/x/y", in `asked` (when given).
R::TileSelectOptions with_blobs(std::vector<std::string>* asked = nullptr) {
  R::TileSelectOptions o;
  o.blob_bytes = [asked](int l, const prep::TileEntry& t) {
    if (asked)
      asked->push_back(std::to_string(l) + "/" + std::to_string(t.key.x) + "/" +
                       std::to_string(t.key.y));
    return kBlobBytes[l];
  };
  return o;
}

// The drawn tiles' blob and package bytes, summed from the levels drawn.
std::pair<uint64_t, uint64_t> drawn_bytes(const R::TileSelection& s) {
  uint64_t blob = 0, package = 0;
  for (const R::SelectedTile& t : s.tiles) {
    blob += kBlobBytes[t.level];
    package += kBytes[t.level];
  }
  return {blob, package};
}

// A top-down view of `abs` (absolute coordinates) for the index's origin.
R::Camera topdown(const prep::TilesetIndex& ix, prep::Extent abs) {
  const double ox = ix.frame.origin_x, oy = ix.frame.origin_y;
  return R::topdown_camera({abs.xmin - ox, abs.ymin - oy, abs.xmax - ox, abs.ymax - oy}, 0, 10);
}

// Every level-0 tile that meets `view` lies in exactly one drawn square, and
// every drawn square holds only such tiles' ground: no gap, no overlap.
void expect_cover(const prep::TilesetIndex& ix, const R::TileSelection& s,
                  const std::optional<prep::Extent>& view) {
  auto inside = [](const prep::Extent& a, const prep::Extent& b) {
    return a.xmin >= b.xmin && a.xmax <= b.xmax && a.ymin >= b.ymin && a.ymax <= b.ymax;
  };
  auto meets = [](const prep::Extent& a, const prep::Extent& b) {
    return a.xmin < b.xmax && b.xmin < a.xmax && a.ymin < b.ymax && b.ymin < a.ymax;
  };
  for (const prep::TileEntry& t : ix.tiles) {
    if (view && !meets(t.square, *view)) continue;
    int holders = 0;
    for (const R::SelectedTile& d : s.tiles) holders += inside(t.square, d.entry->square);
    EXPECT_EQ(holders, 1) << "level-0 tile " << t.key.x << "," << t.key.y;
  }
  for (size_t i = 0; i < s.tiles.size(); ++i)
    for (size_t j = i + 1; j < s.tiles.size(); ++j)
      EXPECT_FALSE(meets(s.tiles[i].entry->square, s.tiles[j].entry->square))
          << "level " << s.tiles[i].level << " and level " << s.tiles[j].level << " overlap";
}

TEST(TileSelect, TopDownOrthographicViewDrawsTheLevelWhoseResolutionFitsThePixel) {
  const prep::TilesetIndex ix = pyramid();
  // The whole 800 m at H pixels: a pixel of 800/H m; the expected level is
  // the coarsest L with 100 2^L / 1024 <= 800 / H, i.e. 2^L <= 8192 / H.
  const std::map<uint32_t, int> expected = {{300, 3},  {1024, 3}, {1100, 2}, {2048, 2},
                                            {3000, 1}, {4096, 1}, {5000, 0}, {9000, 0}};
  for (auto [h, level] : expected) {
    const R::TileSelection s =
        R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), h, h, 0, 10, with_blobs());
    ASSERT_FALSE(s.tiles.empty());
    for (const R::SelectedTile& t : s.tiles) {
      EXPECT_EQ(t.level, level) << h << " pixels";
      EXPECT_DOUBLE_EQ(t.pixel_size, 800.0 / h);
      EXPECT_EQ(t.blob_bytes, kBlobBytes[level]);
    }
    const size_t n = size_t(kGrid >> level) * size_t(kGrid >> level);
    EXPECT_EQ(s.tiles.size(), n) << h << " pixels";
    EXPECT_EQ(s.per_level[size_t(level)], n);
    EXPECT_EQ(s.package_bytes, n * kBytes[level]);
    EXPECT_EQ(s.blob_bytes, n * kBlobBytes[level]);
    EXPECT_EQ(s.full_detail_bytes, 64 * kBytes[0]);
    EXPECT_EQ(s.full_detail_tiles, 64u);
    expect_cover(ix, s, std::nullopt);
  }
}

TEST(TileSelect, NonSquarePixelsChooseByTheFinerSide) {
  const prep::TilesetIndex ix = pyramid();
  // 800 m wide over 4096 columns (0.195 m = r_1: level 1) and 800 m high
  // over 512 rows (1.56 m: level 3 if that side counted).
  const R::TileSelection s = R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 4096, 512, 0, 10);
  for (const R::SelectedTile& t : s.tiles) EXPECT_EQ(t.level, 1);
}

TEST(TileSelect, PerspectiveViewIsFinerNearTheEyeAndCoarserFar) {
  const prep::TilesetIndex ix = pyramid();
  const double o = 400;  // frame origin
  R::Camera c;
  c.projection = R::Projection::perspective;
  c.fov_y_deg = 45;
  // Low over the west edge, looking east along the middle of the grid.
  c.eye = {-o - 5, 400 - o, 8};
  c.target = {800 - o, 400 - o, 0};
  c.near = 0.1;
  const uint32_t w = 1280, h = 720;
  const R::TileSelection s = R::select_tiles(ix, c, w, h, 0, 10);
  ASSERT_FALSE(s.tiles.empty());
  const double k = 2 * std::tan(22.5 * std::numbers::pi / 180) / h;
  // The analytic pixel size at the point of a square nearest the eye (the
  // footprint reaches past the grid here, so the whole square is visible).
  auto pixel = [&](const prep::Extent& sq) {
    const double ex = c.eye[0] + o, ey = c.eye[1] + o, ez = c.eye[2];
    const double dx = std::max({sq.xmin - ex, 0.0, ex - sq.xmax});
    const double dy = std::max({sq.ymin - ey, 0.0, ey - sq.ymax});
    const double dz = std::max(ez - 10, 0.0);
    return std::sqrt(dx * dx + dy * dy + dz * dz) * k;
  };
  // The upper corners see the sky: no footprint, every square visible whole.
  ASSERT_FALSE(s.footprint);
  int nearest_level = -1, farthest_level = -1;
  for (const R::SelectedTile& t : s.tiles) {
    const prep::Extent& sq = t.entry->square;
    EXPECT_NEAR(t.pixel_size, pixel(sq), 1e-9);
    // Drawn: its resolution within a pixel (level 0 always).
    if (t.level > 0) {
      EXPECT_LE(resolution(t.level), pixel(sq));
    }
    // Its parent was not: the parent's resolution exceeds the parent's pixel.
    if (t.level < kLevels) {
      const double ps = kTile * std::ldexp(1.0, t.level + 1);
      const prep::Extent parent{std::floor(sq.xmin / ps) * ps, std::floor(sq.ymin / ps) * ps,
                                std::floor(sq.xmin / ps) * ps + ps,
                                std::floor(sq.ymin / ps) * ps + ps};
      EXPECT_GT(resolution(t.level + 1), pixel(parent)) << "level " << t.level;
    }
    if (sq.xmin == 0 && sq.ymin <= 400 && 400 < sq.ymax) nearest_level = t.level;
    if (sq.xmax == 800 && sq.ymin <= 400 && 400 < sq.ymax) farthest_level = t.level;
  }
  EXPECT_EQ(nearest_level, 0);
  // The far half of the grid lies 405 m away and more: 0.47 m pixels, level 2
  // (r_2 = 0.39 m); level 3's one tile reaches the eye, so it is never drawn.
  EXPECT_EQ(farthest_level, 2);
  EXPECT_GT(s.per_level[0], 0u);
  EXPECT_LT(s.package_bytes, s.full_detail_bytes);
  expect_cover(ix, s, s.footprint);
}

TEST(TileSelect, RandomViewsNeverLeaveGapsOrOverlaps) {
  const prep::TilesetIndex ix = pyramid();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  for (int i = 0; i < 300; ++i) {
    R::Camera c;
    c.projection = i % 3 ? R::Projection::perspective : R::Projection::orthographic;
    c.eye = {-600 + 1200 * u(rng), -600 + 1200 * u(rng), 2 + 600 * u(rng)};
    c.target = {-400 + 800 * u(rng), -400 + 800 * u(rng), 0};
    c.fov_y_deg = 20 + 60 * u(rng);
    c.near = 0.1;
    c.ortho_h = 20 + 800 * u(rng);
    c.ortho_w = c.ortho_h * 16 / 9;
    c.depth_range = 1e4;
    R::TileSelectOptions o = with_blobs();
    if (i % 4 == 0) o.gpu_budget = 230000 + uint64_t(460000 * u(rng));
    R::TileSelection s;
    try {
      s = R::select_tiles(ix, c, 640, 360, 0, 10, o);
    } catch (const prep::resource_error&) {
      continue;  // over a budget even at level 3 (checked below)
    }
    const auto [blob, package] = drawn_bytes(s);
    EXPECT_EQ(s.blob_bytes, blob);
    EXPECT_EQ(s.package_bytes, package);
    if (o.gpu_budget) {
      EXPECT_LE(blob, o.gpu_budget);
    }
    expect_cover(ix, s, s.footprint);
  }
}

TEST(TileSelect, BudgetReplacesChildrenByTheirParentUntilTheViewFits) {
  const prep::TilesetIndex ix = pyramid();
  const R::Camera c = topdown(ix, {0, 0, 800, 800});
  // 8192 pixels: 0.098 m, every tile at level 0: 64 x 11 500 = 736 000 blob
  // bytes (64 000 package bytes).
  R::TileSelectOptions o = with_blobs();
  R::TileSelection s = R::select_tiles(ix, c, 8192, 8192, 0, 10, o);
  ASSERT_EQ(s.blob_bytes, 736000u);
  ASSERT_EQ(s.package_bytes, 64000u);
  // 345 000: each level-1 parent saves 4 x 11 500 - 13 000 = 33 000 blob
  // bytes, so 12 merges (736000 - 12 x 33000 = 340000 <= 345000 < 373000).
  o.gpu_budget = 345000;
  s = R::select_tiles(ix, c, 8192, 8192, 0, 10, o);
  EXPECT_EQ(s.blob_bytes, 340000u);
  EXPECT_EQ(s.package_bytes, 16u * 1000u + 12u * 1200u);
  EXPECT_EQ(s.coarsened, 12u);
  EXPECT_EQ(s.per_level[1], 12u);
  EXPECT_EQ(s.per_level[0], 64u - 48u);
  expect_cover(ix, s, std::nullopt);
  // 23 000 bytes: the one level-3 tile.
  o.gpu_budget = 23000;
  s = R::select_tiles(ix, c, 8192, 8192, 0, 10, o);
  EXPECT_EQ(s.blob_bytes, 23000u);
  ASSERT_EQ(s.tiles.size(), 1u);
  EXPECT_EQ(s.tiles[0].level, 3);
  // Below the coarsest level's 23 000 bytes: a resource error naming both.
  o.gpu_budget = 22999;
  try {
    R::select_tiles(ix, c, 8192, 8192, 0, 10, o);
    FAIL() << "expected resource_error";
  } catch (const prep::resource_error& e) {
    EXPECT_EQ(e.code(), prep::ExitCode::resource);
    EXPECT_NE(std::string(e.what()).find("22999 bytes"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("need 23000 bytes"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("(2000 package bytes)"), std::string::npos) << e.what();
  }
}

// The budget is GPU memory: a budget that holds the view's package bytes
// but not its decoded blobs coarsens the view until the blobs fit. (Counted
// in package bytes, as before, 100 000 would hold all 64 level-0 tiles.)
TEST(TileSelect, BudgetCountsDecodedBlobBytesNotPackageBytes) {
  const prep::TilesetIndex ix = pyramid();
  const R::Camera c = topdown(ix, {0, 0, 800, 800});
  std::vector<std::string> asked;
  R::TileSelectOptions o = with_blobs(&asked);
  const R::TileSelection free = R::select_tiles(ix, c, 8192, 8192, 0, 10, o);
  ASSERT_EQ(free.package_bytes, 64000u);
  ASSERT_EQ(free.blob_bytes, 736000u);
  // Without a budget only the drawn tiles are asked, each once.
  EXPECT_EQ(asked.size(), 64u);
  asked.clear();
  o.gpu_budget = 100000;  // > 64 000 package bytes, < 736 000 blob bytes
  const R::TileSelection s = R::select_tiles(ix, c, 8192, 8192, 0, 10, o);
  // The 16 level-1 merges (33 000 each) leave 208 000; level-2 parents save
  // 4 x 13 000 - 17 000 = 35 000 each: all 4 (68 000 <= 100 000 < 103 000).
  EXPECT_GT(s.coarsened, 0u);
  EXPECT_EQ(s.coarsened, 20u);
  EXPECT_EQ(s.per_level[2], 4u);
  EXPECT_EQ(s.tiles.size(), 4u);
  EXPECT_EQ(s.blob_bytes, 4u * 17000u);
  EXPECT_EQ(s.package_bytes, 4u * 1500u);
  EXPECT_LE(drawn_bytes(s).first, o.gpu_budget);
  for (const R::SelectedTile& t : s.tiles) EXPECT_EQ(t.blob_bytes, kBlobBytes[t.level]);
  expect_cover(ix, s, std::nullopt);
  // Asked: the 64 drawn level-0 tiles, then each parent the budget drew in
  // their place (16 of level 1, 4 of level 2), each once; never level 3.
  EXPECT_EQ(asked.size(), 64u + 16u + 4u);
  EXPECT_EQ(std::set<std::string>(asked.begin(), asked.end()).size(), asked.size());
  for (const std::string& a : asked) EXPECT_NE(a[0], '3') << a;
}

TEST(TileSelect, ABudgetNeedsTheBlobBytesAndTheirFailuresPassThrough) {
  const prep::TilesetIndex ix = pyramid();
  const R::Camera c = topdown(ix, {0, 0, 800, 800});
  R::TileSelectOptions o;
  o.gpu_budget = 1u << 30;
  EXPECT_THROW(R::select_tiles(ix, c, 64, 64, 0, 10, o), prep::usage_error);
  o.blob_bytes = [](int, const prep::TileEntry& t) -> uint64_t {
    throw prep::format_error("render: " + t.file + ": not a .decals package");
  };
  EXPECT_THROW(R::select_tiles(ix, c, 64, 64, 0, 10, o), prep::format_error);
}

TEST(TileSelect, BudgetMergesTheGroupWhoseParentHasTheSmallestErrorInPixelsFirst) {
  const prep::TilesetIndex ix = pyramid();
  R::Camera c;
  c.eye = {-405, 0, 8};
  c.target = {400, 0, 0};
  c.near = 0.1;
  const double k = 2 * std::tan(22.5 * std::numbers::pi / 180) / 720;
  auto sse = [&](int l, const prep::TileKey& key) {  // r_l over the pixel at the nearest point
    const double s = kTile * std::ldexp(1.0, l), ex = -5, ey = 400;
    const double dx = std::max({double(key.x) * s - ex, 0.0, ex - double(key.x + 1) * s});
    const double dy = std::max({double(key.y) * s - ey, 0.0, ey - double(key.y + 1) * s});
    return resolution(l) / (std::hypot(dx, dy) * k);
  };
  R::TileSelectOptions o = with_blobs();
  const R::TileSelection free = R::select_tiles(ix, c, 1280, 720, 0, 10, o);
  // The groups that can merge: four drawn children of one parent.
  std::map<std::pair<int, prep::TileKey>, int> children;
  for (const R::SelectedTile& t : free.tiles)
    ++children[{t.level + 1, {t.entry->key.x >> 1, t.entry->key.y >> 1}}];
  double least = INFINITY;
  for (const auto& [parent, n] : children)
    if (n == 4) least = std::min(least, sse(parent.first, parent.second));
  ASSERT_TRUE(std::isfinite(least));
  o.gpu_budget = free.blob_bytes - 1;
  const R::TileSelection tight = R::select_tiles(ix, c, 1280, 720, 0, 10, o);
  EXPECT_LE(tight.blob_bytes, o.gpu_budget);
  EXPECT_LE(drawn_bytes(tight).first, o.gpu_budget);
  EXPECT_EQ(tight.coarsened, 1u);
  EXPECT_EQ(tight.tiles.size(), free.tiles.size() - 3);
  // The new tile is a parent of least error among the groups.
  std::set<std::pair<int, prep::TileKey>> before;
  for (const R::SelectedTile& t : free.tiles) before.insert({t.level, t.entry->key});
  int added = 0;
  for (const R::SelectedTile& t : tight.tiles)
    if (!before.count({t.level, t.entry->key})) {
      ++added;
      EXPECT_DOUBLE_EQ(sse(t.level, t.entry->key), least);
    }
  EXPECT_EQ(added, 1);
}

TEST(TileSelect, AbsentTilesAreEmptyAndLeaveNoGapAtOtherLevels) {
  prep::TilesetIndex ix = pyramid();
  // Level-1 tile (1, 1) absent (its content below a pixel there), and
  // level-0 tile (0, 0) absent (no data at all).
  auto& l1 = ix.levels[0].tiles;
  l1.erase(std::find_if(l1.begin(), l1.end(), [](const prep::TileEntry& t) {
    return t.key == prep::TileKey{1, 1};
  }));
  ix.tiles.erase(ix.tiles.begin());
  // 4096 pixels over 800 m: level 1 everywhere.
  const R::TileSelection s = R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 4096, 4096, 0, 10);
  EXPECT_EQ(s.tiles.size(), 15u);
  for (const R::SelectedTile& t : s.tiles) {
    EXPECT_EQ(t.level, 1);
    EXPECT_FALSE(t.entry->key == (prep::TileKey{1, 1}));
  }
  // 8192 pixels: level 0 everywhere, the four children of the absent level-1
  // tile included; the absent level-0 tile draws nothing.
  const R::TileSelection f = R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 8192, 8192, 0, 10);
  EXPECT_EQ(f.tiles.size(), 63u);
  EXPECT_EQ(f.per_level[0], 63u);
}

TEST(TileSelect, ATilesetWithoutLevelsDrawsTheLevel0TilesThatMeetTheView) {
  const prep::TilesetIndex ix = pyramid(0);
  // Absolute 150..350 x 420..780: tiles x 1..3, y 4..7.
  const R::TileSelection s = R::select_tiles(ix, topdown(ix, {150, 420, 350, 780}), 64, 64, 0, 10);
  std::set<std::pair<int64_t, int64_t>> got, want;
  for (const R::SelectedTile& t : s.tiles) got.insert({t.entry->key.x, t.entry->key.y});
  for (int64_t x = 1; x <= 3; ++x)
    for (int64_t y = 4; y <= 7; ++y) want.insert({x, y});
  EXPECT_EQ(got, want);
  EXPECT_EQ(s.package_bytes, s.full_detail_bytes);
  // In index order (x, then y).
  for (size_t i = 1; i < s.tiles.size(); ++i)
    EXPECT_LT(s.tiles[i - 1].entry->key, s.tiles[i].entry->key);
}

TEST(TileSelect, ForcedLevelDrawsThatLevelEverywhere) {
  const prep::TilesetIndex ix = pyramid();
  R::TileSelectOptions o = with_blobs();
  o.level = 2;
  const R::TileSelection s = R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 64, 64, 0, 10, o);
  EXPECT_EQ(s.tiles.size(), 4u);
  for (const R::SelectedTile& t : s.tiles) EXPECT_EQ(t.level, 2);
  o.level = 4;
  EXPECT_THROW(R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 64, 64, 0, 10, o),
               prep::usage_error);
  o.level = 0;
  o.gpu_budget = 736000;  // level 0's 64 x 11 500 blob bytes
  EXPECT_EQ(R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 64, 64, 0, 10, o).blob_bytes,
            736000u);
  o.gpu_budget = 735999;
  EXPECT_THROW(R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 64, 64, 0, 10, o),
               prep::resource_error);
  o.gpu_budget = 100000;  // above its 64 000 package bytes
  EXPECT_THROW(R::select_tiles(ix, topdown(ix, {0, 0, 800, 800}), 64, 64, 0, 10, o),
               prep::resource_error);
}

}  // namespace
