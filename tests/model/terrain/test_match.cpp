// Terrain matching on Monaco's roads with the SRTM tile N43E007, checked
// against GDAL's own bilinear resampling, plus synthetic cases.
#include <gtest/gtest.h>
#include <unistd.h>

#include <memory>
#include <random>
#include <set>

#include "prep/model.hpp"
#include "terrain/terrain.hpp"
#include "terrain_fixtures.hpp"

namespace {

using terraintest::GdalBilinear;
using terraintest::MonacoFrame;

prep::SceneFeatures dynamic_scene(const prep::SceneFrame& frame,
                                  std::vector<prep::SceneLine> lines) {
  prep::SceneFeatures s;
  s.frame = frame;
  prep::LayerSpec layer;
  layer.name = "roads";
  layer.kind = prep::DecalKind::line;
  layer.dynamic = true;
  s.layers.push_back(layer);
  s.dynamic_lines = std::move(lines);
  return s;
}

bool has_note(const prep::DecalModel& m, const std::string& what) {
  for (const auto& n : m.manifest.notes)
    if (n.find(what) != std::string::npos) return true;
  return false;
}

class MonacoTerrain : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!terraintest::monaco_available()) return;
    frame = std::make_unique<MonacoFrame>();
    roads = terraintest::monaco_roads(*frame);
    oracle = std::make_unique<GdalBilinear>(terraintest::monaco_dem());
    // An oracle copy whose voids hold the fill policy's values (validated
    // cell by cell in StoredHeightsEqualGdalBilinearOnTenThousandVertices).
    filled = std::make_unique<GdalBilinear>(terraintest::monaco_dem());
    prep::DemSampler dem(terraintest::monaco_dem(), frame->frame(), 1.0, std::nullopt);
    double px0 = 1e300, py0 = 1e300, px1 = -1e300, py1 = -1e300;
    for (const auto& l : roads)
      for (const auto& p : l.points) {
        double lon, lat;
        frame->reverse(p.x, p.y, lon, lat);
        px0 = std::min(px0, oracle->px(lon)), px1 = std::max(px1, oracle->px(lon));
        py0 = std::min(py0, oracle->py(lat)), py1 = std::max(py1, oracle->py(lat));
      }
    dem.load(px0, py0, px1, py1);
    for (int j = std::max(0, int(py0) - 2); j <= std::min(filled->height() - 1, int(py1) + 2); ++j)
      for (int i = std::max(0, int(px0) - 2); i <= std::min(filled->width() - 1, int(px1) + 2); ++i)
        if (oracle->invalid(i, j)) filled->patch(i, j, dem.height(i + 0.5, j + 0.5));
  }
  static void TearDownTestSuite() {
    filled.reset();
    oracle.reset();
    frame.reset();
  }
  void SetUp() override {
    if (!terraintest::monaco_available()) GTEST_SKIP() << "missing " << terraintest::monaco_pbf();
    ASSERT_GT(roads.size(), 1000u);
  }
  static prep::DecalModel build(const prep::ModelOptions& opt) {
    prep::DecalModel m;
    prep::build_dynamic(dynamic_scene(frame->frame(), roads), opt, terraintest::monaco_dem(), m);
    return m;
  }
  static std::unique_ptr<MonacoFrame> frame;
  static std::vector<prep::SceneLine> roads;
  static std::unique_ptr<GdalBilinear> oracle, filled;
};
std::unique_ptr<MonacoFrame> MonacoTerrain::frame;
std::vector<prep::SceneLine> MonacoTerrain::roads;
std::unique_ptr<GdalBilinear> MonacoTerrain::oracle;
std::unique_ptr<GdalBilinear> MonacoTerrain::filled;

// Terrain matching on real data. The SRTM tile has voids (-32768) near the coast, so:
// (a) every no-data cell a stored vertex uses must hold the value of a valid
//     cell at the smallest Chebyshev distance (the documented policy;
//     brute-force search here), read back from a DemSampler at the cell
//     centre; those values are patched into the oracle's copy;
// (b) 10,000 sampled vertex heights must equal GDAL's bilinear to 1e-3 m;
// (c) the manifest's count of vertex heights that used a filled cell must
//     equal the count found here over all vertices.
TEST_F(MonacoTerrain, StoredHeightsEqualGdalBilinearOnTenThousandVertices) {
  const prep::DecalModel m = build({});
  ASSERT_GT(m.dyn_vertices.size(), 10000u);
  auto pixel_of = [&](const prep::ivec4& v) {
    double lon, lat;
    frame->reverse(v[0] * 1e-3, v[1] * 1e-3, lon, lat);
    return prep::Point2{oracle->px(lon), oracle->py(lat)};
  };
  // Void cells used by any stored vertex, and the vertices using them.
  std::set<std::pair<int, int>> voids;
  uint64_t touching = 0;
  double px0 = 1e300, py0 = 1e300, px1 = -1e300, py1 = -1e300;
  for (const auto& v : m.dyn_vertices) {
    const prep::Point2 p = pixel_of(v);
    px0 = std::min(px0, p.x), px1 = std::max(px1, p.x), py0 = std::min(py0, p.y),
    py1 = std::max(py1, p.y);
    bool t = false;
    for (const auto& c : oracle->stencil(p.x, p.y))
      if (oracle->invalid(c.first, c.second)) {
        voids.insert(c);
        t = true;
      }
    touching += t;
  }
  EXPECT_TRUE(has_note(m, std::to_string(touching) + " of " +
                              std::to_string(m.dyn_vertices.size()) +
                              " vertex heights used a filled cell"));
  // (a) the fill values, checked against a brute-force nearest search.
  prep::DemSampler dem(terraintest::monaco_dem(), frame->frame(), 1.0, std::nullopt);
  dem.load(px0, py0, px1, py1);
  GdalBilinear patched(terraintest::monaco_dem());
  for (const auto& [i, j] : voids) {
    const double filled = dem.height(i + 0.5, j + 0.5);
    bool found = false;
    for (int r = 1; r < 64 && !found; ++r) {
      for (int dj = -r; dj <= r; ++dj)
        for (int di = -r; di <= r; ++di) {
          if (std::max(std::abs(di), std::abs(dj)) != r) continue;
          const int ci = i + di, cj = j + dj;
          if (ci < 0 || cj < 0 || ci >= oracle->width() || cj >= oracle->height()) continue;
          if (!oracle->invalid(ci, cj) && oracle->raw(ci, cj) == filled) found = true;
        }
      bool any_valid = false;  // stop at the first ring holding a valid cell
      for (int dj = -r; dj <= r && !any_valid; ++dj)
        for (int di = -r; di <= r; ++di) {
          const int ci = i + di, cj = j + dj;
          if (std::max(std::abs(di), std::abs(dj)) == r && ci >= 0 && cj >= 0 &&
              ci < oracle->width() && cj < oracle->height() && !oracle->invalid(ci, cj))
            any_valid = true;
        }
      if (any_valid) break;
    }
    ASSERT_TRUE(found) << "void cell (" << i << ", " << j << ") filled with " << filled
                       << ", not a nearest valid value";
    patched.patch(i, j, filled);
  }
  // (b) 10,000 sampled vertices against GDAL's bilinear.
  std::mt19937_64 rng(5);
  std::uniform_int_distribution<size_t> pick(0, m.dyn_vertices.size() - 1);
  double worst = 0;
  int clean = 0;
  for (int k = 0; k < 10000; ++k) {
    const auto& v = m.dyn_vertices[pick(rng)];
    const prep::Point2 p = pixel_of(v);
    const double expected = patched.at_pixel(p.x, p.y);
    bool t = false;
    for (const auto& c : oracle->stencil(p.x, p.y)) t = t || oracle->invalid(c.first, c.second);
    clean += !t;
    worst = std::max(worst, std::abs(v[2] * 1e-3 - expected));
    ASSERT_NEAR(v[2] * 1e-3, expected, 1e-3) << "vertex at (" << v[0] << ", " << v[1] << ")";
  }
  EXPECT_GT(clean, 9000);
  std::printf(
      "max |stored - GDAL bilinear| over 10000 vertices (%d clean stencils): %.6f m; %zu void "
      "cells "
      "used, %llu of %zu vertices touch one\n",
      clean, worst, voids.size(), static_cast<unsigned long long>(touching), m.dyn_vertices.size());
  // Terrain range over the window read contains every stored height.
  for (const auto& v : m.dyn_vertices) {
    ASSERT_GE(v[2] * 1e-3, m.terrain_min - 1e-3);
    ASSERT_LE(v[2] * 1e-3, m.terrain_max + 1e-3);
  }
  EXPECT_LT(m.terrain_min, m.terrain_max);
  EXPECT_TRUE(has_note(m, "no-data cells filled (nearest valid cell)"));
  EXPECT_TRUE(has_note(m, "SRTMHGT"));
}

TEST_F(MonacoTerrain, NoStoredPieceIsLongerThanLmax) {
  for (double lmax : {0.0, 7.5}) {
    prep::ModelOptions opt;
    opt.lmax = lmax;
    const prep::DecalModel m = build(opt);
    double used = lmax;
    if (lmax == 0) {
      // Default: half the DEM cell (3 arc-seconds; the east-west side is
      // the smaller at 43.7 N), measured with GeographicLib.
      double lon, lat;
      frame->reverse(0, 0, lon, lat);
      const prep::Point2 a = frame->forward(lon, lat), b = frame->forward(lon + 3.0 / 3600, lat);
      used = 0.5 * std::hypot(b.x - a.x, b.y - a.y);
      EXPECT_NEAR(used, 33.6, 0.5);
    }
    double longest = 0;
    uint64_t minimum_needed = 0, original = 0;
    for (size_t v = 0; v < m.dyn_vertices.size(); ++v) {
      const int32_t nx = m.dyn_prev_next[v][1];
      if (nx < 0) continue;
      const auto& a = m.dyn_vertices[v];
      const auto& b = m.dyn_vertices[static_cast<size_t>(nx)];
      longest = std::max(longest, std::hypot(double(b[0] - a[0]), double(b[1] - a[1])) * 1e-3);
    }
    // The default lmax is taken at the data centre; allow its variation over
    // Monaco's 4 km (cos(lat) changes by < 0.1 %).
    EXPECT_LE(longest, used * (lmax == 0 ? 1.001 : 1.0) + 1e-6) << "lmax " << lmax;
    for (const auto& l : roads) {
      original += l.points.size();
      const size_t n = l.points.size(), nseg = l.closed ? n : n - 1;
      for (size_t k = 0; k < nseg; ++k) {
        const auto& p = l.points[k];
        const auto& q = l.points[(k + 1) % n];
        minimum_needed +=
            static_cast<uint64_t>(std::ceil(std::hypot(q.x - p.x, q.y - p.y) / (used * 1.001)));
      }
      if (!l.closed) ++minimum_needed;
    }
    EXPECT_GE(m.dyn_vertices.size(), minimum_needed);
    EXPECT_GT(m.dyn_vertices.size(), original);
    EXPECT_TRUE(has_note(m, "vertices in " + std::to_string(original)));
    EXPECT_TRUE(has_note(m, "stored " + std::to_string(m.dyn_vertices.size())));
    std::printf("lmax %.3f m: %llu input vertices -> %zu stored, longest piece %.4f m\n", used,
                static_cast<unsigned long long>(original), m.dyn_vertices.size(), longest);
  }
}

// Every original vertex is kept, in order, at its quantised position.
TEST_F(MonacoTerrain, OriginalVerticesAreKeptInOrder) {
  prep::ModelOptions opt;
  opt.terrain_tolerance = 0.5;
  const prep::DecalModel m = build(opt);
  ASSERT_EQ(m.dyn_line_start.size(), roads.size());
  for (size_t li = 0; li < roads.size(); ++li) {
    const uint32_t first = m.dyn_line_start[li];
    const uint32_t end =
        li + 1 < roads.size() ? m.dyn_line_start[li + 1] : uint32_t(m.dyn_vertices.size());
    size_t k = 0;
    for (uint32_t v = first; v < end && k < roads[li].points.size(); ++v) {
      ASSERT_EQ(m.dyn_vertices[v][3], int32_t(li));
      const auto& p = roads[li].points[k];
      if (m.dyn_vertices[v][0] == std::llround(p.x * 1000) &&
          m.dyn_vertices[v][1] == std::llround(p.y * 1000))
        ++k;
    }
    ASSERT_EQ(k, roads[li].points.size()) << "line " << li;
  }
}

TEST_F(MonacoTerrain, AdaptiveModeStaysWithinToleranceUnderOneMetreSampling) {
  prep::ModelOptions fixed_opt;
  const prep::DecalModel fixed = build(fixed_opt);
  prep::ModelOptions opt;
  opt.terrain_tolerance = 0.5;
  const prep::DecalModel m = build(opt);
  double worst = 0;
  uint64_t samples = 0;
  for (size_t v = 0; v < m.dyn_vertices.size(); ++v) {
    const int32_t nx = m.dyn_prev_next[v][1];
    if (nx < 0) continue;
    const auto& a = m.dyn_vertices[v];
    const auto& b = m.dyn_vertices[static_cast<size_t>(nx)];
    const double len = std::hypot(double(b[0] - a[0]), double(b[1] - a[1])) * 1e-3;
    const int n = std::max(1, static_cast<int>(std::ceil(len / 1.0)));
    for (int i = 0; i <= n; ++i) {
      const double t = double(i) / n;
      const double x = a[0] + t * (b[0] - a[0]), y = a[1] + t * (b[1] - a[1]);
      const double z = (a[2] + t * (b[2] - a[2])) * 1e-3;
      double lon, lat;
      frame->reverse(x * 1e-3, y * 1e-3, lon, lat);
      const double dev = std::abs(z - filled->at(lon, lat));
      worst = std::max(worst, dev);
      ++samples;
    }
  }
  EXPECT_LE(worst, 0.5);
  EXPECT_LT(m.dyn_vertices.size(), fixed.dyn_vertices.size());
  EXPECT_TRUE(has_note(m, "adaptive, tolerance 0.500 m"));
  std::printf(
      "adaptive 0.5 m: %zu vertices vs %zu with fixed lmax (%.1f %% saved); max deviation %.4f m "
      "over "
      "%llu samples at <= 1 m spacing\n",
      m.dyn_vertices.size(), fixed.dyn_vertices.size(),
      100.0 * (1.0 - double(m.dyn_vertices.size()) / double(fixed.dyn_vertices.size())), worst,
      static_cast<unsigned long long>(samples));
}

TEST_F(MonacoTerrain, OutputDoesNotDependOnThreadCount) {
  prep::ModelOptions one, two;
  one.threads = 1;
  two.threads = 2;
  one.terrain_tolerance = two.terrain_tolerance = 0.3;
  const prep::DecalModel a = build(one), b = build(two);
  EXPECT_EQ(a.dyn_vertices, b.dyn_vertices);
  EXPECT_EQ(a.dyn_prev_next, b.dyn_prev_next);
  EXPECT_EQ(a.dyn_line_start, b.dyn_line_start);
  EXPECT_EQ(a.manifest.notes, b.manifest.notes);
}

TEST(TerrainMatch, ClosedOutlineWrapsAndOpenLineEndsAreMarked) {
  prep::SceneLine square;
  square.points = {{0, 0}, {100, 0}, {100, 100}, {0, 100}};
  square.closed = true;
  prep::SceneLine open;
  open.points = {{0, 200}, {50, 200}};
  prep::MatchOptions opt;
  opt.lmax = 30;
  const auto m = prep::match_terrain({square, open}, nullptr, opt);
  // 100 m sides in pieces of at most 30 m: 4 pieces each.
  ASSERT_EQ(m.line_start, (std::vector<uint32_t>{0, 16}));
  ASSERT_EQ(m.vertices.size(), 16u + 3u);
  for (uint32_t v = 0; v < 16; ++v) {
    EXPECT_EQ(m.prev_next[v][0], int32_t((v + 15) % 16));
    EXPECT_EQ(m.prev_next[v][1], int32_t((v + 1) % 16));
    EXPECT_EQ(m.vertices[v][3], 0);
    EXPECT_EQ(m.vertices[v][2], 0);
  }
  EXPECT_EQ(m.vertices[4][0], 100000);  // corner (100, 0) kept
  EXPECT_EQ(m.vertices[4][1], 0);
  EXPECT_EQ(m.vertices[15][0], 0);  // last piece of the closing side
  EXPECT_EQ(m.vertices[15][1], 25000);
  EXPECT_EQ(m.prev_next[16], (prep::ivec2{-1, 17}));
  EXPECT_EQ(m.prev_next[17], (prep::ivec2{16, 18}));
  EXPECT_EQ(m.prev_next[18], (prep::ivec2{17, -1}));
  EXPECT_EQ(m.vertices[18][0], 50000);
  EXPECT_LE(m.max_piece_length, 30.0);
}

TEST(TerrainMatch, PieceDeviationMatchesDenseSampling) {
  const std::string dir = terraintest::temp_dir("deviation");
  const double gt[6] = {0, 10, 0, 1000, 0, -10};
  const std::string path = terraintest::write_dem(
      dir + "/bumps.tif", 100, 100, gt, "EPSG:32632",
      [](int i, int j) { return 50 * std::sin(i * 0.9) * std::cos(j * 0.7) + i; });
  prep::DemSampler dem(path, {}, 1.0, std::nullopt);
  dem.load(0, 0, 100, 100);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(5, 95);
  for (int k = 0; k < 200; ++k) {
    const prep::Point2 a{u(rng), u(rng)}, b{u(rng), u(rng)};
    const double za = dem.height(a.x, a.y) + 1, zb = dem.height(b.x, b.y) - 2;
    const prep::PixelPathPoint path2[2] = {{0, a}, {1, b}};
    double arg = 0;
    const double dev = prep::piece_deviation(dem, path2, za, zb, &arg);
    double dense = 0;
    for (int i = 0; i <= 20000; ++i) {
      const double t = i / 20000.0;
      dense = std::max(dense, std::abs(za + t * (zb - za) -
                                       dem.height(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y))));
    }
    EXPECT_GE(dev, dense - 1e-9);
    EXPECT_NEAR(dev, dense, 1e-3 * std::max(1.0, dense));
  }
}

}  // namespace
