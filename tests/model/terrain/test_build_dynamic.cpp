// build_dynamic(): dyn_* and lod_* blobs of a DecalModel from SceneFeatures.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>

#include "lod/lod.hpp"
#include "prep/error.hpp"
#include "prep/model.hpp"
#include "terrain_fixtures.hpp"

namespace {

prep::SceneFeatures two_layers() {
  prep::SceneFeatures s;
  prep::LayerSpec roads;
  roads.name = "roads";
  roads.kind = prep::DecalKind::line;
  roads.dynamic = true;
  roads.style.color.rgba = 0xff0000ffu;
  roads.style.corner = decal::CornerStyle::miter;
  prep::LayerSpec rivers = roads;
  rivers.name = "rivers";
  rivers.lod = true;
  rivers.style.color.attribute = "depth";
  rivers.style.color.ramp = {{0.0, 0xff000000u}, {10.0, 0xff0000ffu}};
  s.layers = {roads, rivers};
  auto line = [](std::vector<prep::Point2> pts, uint32_t layer, double length, double order,
                 double color) {
    prep::SceneLine l;
    l.points = std::move(pts);
    l.layer = layer;
    l.length = length;
    l.width = 4;
    l.order_value = order;
    l.color_value = color;
    return l;
  };
  s.dynamic_lines.push_back(line({{0, 0}, {100, 0}}, 0, 100, NAN, NAN));
  s.dynamic_lines.push_back(line({{0, 10}, {300, 10}}, 0, 300, NAN, NAN));
  s.dynamic_lines.push_back(
      line({{0, 20}, {50, 40}, {100, 20}, {150, 45}, {200, 20}}, 1, 240, NAN, 5.0));
  s.dynamic_lines.push_back(line({{5, 5}}, 0, 0, NAN, NAN));  // unusable
  return s;
}

TEST(BuildDynamic, FlatTerrainWithoutDemIsNotedAndLinesKeepTheirVertices) {
  const auto scene = two_layers();
  prep::DecalModel m;
  prep::build_dynamic(scene, {}, "", m);
  ASSERT_EQ(m.dyn_line_props.size(), 3u);
  EXPECT_EQ(m.dyn_vertices.size(), 2u + 2u + 5u);  // no DEM, no lmax: no subdivision
  for (const auto& v : m.dyn_vertices) EXPECT_EQ(v[2], 0);
  bool flat = false;
  for (const auto& n : m.manifest.notes)
    flat = flat || n.find("flat terrain z = 0") != std::string::npos;
  EXPECT_TRUE(flat);
  ASSERT_EQ(m.manifest.entries.size(), 1u);
  EXPECT_EQ(m.manifest.entries[0].action, prep::ManifestAction::dropped);
  EXPECT_EQ(m.terrain_min, 0);
  EXPECT_EQ(m.terrain_max, 0);
}

TEST(BuildDynamic, PropertiesCarryPixelWidthOrderColourAndStyle) {
  const auto scene = two_layers();
  prep::DecalModel m;
  prep::build_dynamic(scene, {}, "", m);
  const auto& p = m.dyn_line_props;
  EXPECT_FLOAT_EQ(p[0].half_width, 2.0f);  // 4 px wide
  // The later layer on top (rivers, 240 m: rank 0), then within roads the
  // longest on top: 300 m, 100 m.
  EXPECT_EQ(p[2].order, 0u);
  EXPECT_EQ(p[1].order, 1u);
  EXPECT_EQ(p[0].order, 2u);
  EXPECT_EQ(p[0].rgba, 0xff0000ffu);
  // Ramp halfway between black and red.
  EXPECT_EQ(p[2].rgba, 0xff000080u);
  EXPECT_FLOAT_EQ(p[2].value, 5.0f);
  EXPECT_TRUE(std::isnan(p[0].value));
  EXPECT_EQ(p[0].style & decal::kStyleCornerMask, uint32_t(decal::CornerStyle::miter));
  EXPECT_EQ(p[2].layer, 1u);
  EXPECT_EQ(p[0].clip_node, 0u);
}

TEST(BuildDynamic, LodLayerGetsAttributedSegmentsForItsLinesOnly) {
  const auto scene = two_layers();
  prep::DecalModel m;
  prep::build_dynamic(scene, {}, "", m);
  ASSERT_EQ(m.lod_line_range.size(), 1u);
  EXPECT_EQ(m.lod_points.size(), 5u);
  EXPECT_EQ(m.lod_segments.size(), 2u * 4u - 1u);
  for (const auto& pt : m.lod_points) EXPECT_EQ(pt.line, 2u);
  // Coarse threshold: only the base segment; zero threshold: all 4.
  const auto coarse = decal::visible_segments(m.lod_points, m.lod_segments, {0, 0, 10},
                                              decal::LinearThreshold{1e3, 0});
  ASSERT_EQ(coarse.size(), 1u);
  EXPECT_EQ(m.lod_segments[coarse[0]].a, 0u);
  EXPECT_EQ(m.lod_segments[coarse[0]].b, 4u);
  const auto fine = decal::visible_segments(m.lod_points, m.lod_segments, {0, 0, 10},
                                            decal::LinearThreshold{0, 0});
  EXPECT_EQ(fine.size(), 4u);
}

TEST(BuildDynamic, SubdividesAndSamplesADemInTheSceneCrs) {
  const std::string dir = terraintest::temp_dir("build");
  const double gt[6] = {0, 20, 0, 400, 0, -20};
  const std::string dem = terraintest::write_dem(dir + "/ramp.tif", 30, 30, gt, "EPSG:32632",
                                                 [](int i, int j) { return 10.0 * i + j; });
  auto scene = two_layers();
  scene.frame.crs_wkt = terraintest::wkt_of("EPSG:32632");
  scene.frame.origin_y = 100;
  prep::ModelOptions opt;
  opt.z_scale = 2;
  prep::DecalModel m;
  prep::build_dynamic(scene, opt, dem, m);
  // Default lmax = half of a 20 m cell.
  for (size_t v = 0; v < m.dyn_vertices.size(); ++v) {
    const int32_t nx = m.dyn_prev_next[v][1];
    if (nx < 0) continue;
    const auto& a = m.dyn_vertices[v];
    const auto& b = m.dyn_vertices[size_t(nx)];
    EXPECT_LE(std::hypot(double(b[0] - a[0]), double(b[1] - a[1])) * 1e-3, 10.0 + 1e-6);
  }
  EXPECT_GE(m.dyn_vertices.size(), 11u + 31u + 21u);  // ceil(len / 10) pieces + 1 per line
  // The ramp is a plane: z = 2 * (10 * (x/20 - 0.5) + ((400 - y)/20 - 0.5)).
  for (const auto& v : m.dyn_vertices) {
    const double x = v[0] * 1e-3, y = v[1] * 1e-3 + 100;
    const double expected = 2 * (10 * (x / 20 - 0.5) + ((400 - y) / 20 - 0.5));
    if (x >= 10 && x <= 590) {
      EXPECT_NEAR(v[2] * 1e-3, expected, 1e-3) << x << " " << y;
    }
  }
  EXPECT_DOUBLE_EQ(m.terrain_min, 0.0);
  EXPECT_DOUBLE_EQ(m.terrain_max, 2 * (10.0 * 29 + 29));
}

TEST(BuildDynamic, DemWithoutDynamicLinesIsNotReadAndNoted) {
  prep::SceneFeatures scene;
  prep::DecalModel m;
  prep::build_dynamic(scene, {}, "/nonexistent/dem.tif", m);
  EXPECT_TRUE(m.dyn_vertices.empty());
  ASSERT_EQ(m.manifest.notes.size(), 1u);
  EXPECT_NE(m.manifest.notes[0].find("not read"), std::string::npos);
}

TEST(BuildDynamic, UnreadableDemIsAGdalErrorNamingTheFile) {
  auto scene = two_layers();
  prep::DecalModel m;
  try {
    prep::build_dynamic(scene, {}, "/nonexistent/dem.tif", m);
    FAIL() << "no exception";
  } catch (const prep::gdal_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dem.tif"), std::string::npos) << e.what();
  }
}

TEST(BuildDynamic, InvalidTerrainOptionIsAUsageError) {
  const auto scene = two_layers();
  prep::ModelOptions opt;
  opt.z_scale = 0;
  prep::DecalModel m;
  EXPECT_THROW(prep::build_dynamic(scene, opt, "", m), prep::usage_error);
}

}  // namespace
