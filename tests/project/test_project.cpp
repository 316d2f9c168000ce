// Reprojection against GeographicLib reference
// values (an implementation independent of PROJ), the axis order, and widths
// in ground metres.
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <GeographicLib/Geodesic.hpp>
#include <GeographicLib/TransverseMercatorExact.hpp>
#include <GeographicLib/UTMUPS.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "../read/fixtures.hpp"
#include "../read/scene_fixtures.hpp"
#include "epsg_wkt.hpp"
#include "prep/error.hpp"
#include "prep/pipeline.hpp"
#include "prep/project.hpp"

namespace {

prep::FeatureSet grid_of_points(double lon_c, double lat_c, double span) {
  prep::FeatureSet fs;
  prep::SourceLayer layer;
  layer.spec.name = "pts";
  layer.spec.kind = prep::DecalKind::line;
  layer.srs_wkt = epsg_wkt(4326);
  prep::SourceFeature f;
  for (int i = 0; i <= 4; ++i)
    for (int j = 0; j <= 4; ++j)
      f.rings.emplace_back().push_back(
          {lon_c - span + span * 0.5 * i, lat_c - span + span * 0.5 * j});
  layer.features.push_back(f);
  fs.layers.push_back(layer);
  return fs;
}

class LocalTm : public testing::TestWithParam<double> {};

TEST_P(LocalTm, MatchesGeographicLibExactTransverseMercatorTo1Micrometre) {
  const double lat_c = GetParam(), lon_c = 10.0, span = 0.05;
  prep::FeatureSet fs = grid_of_points(lon_c, lat_c, span);
  const prep::FeatureSet original = fs;
  prep::SceneFrame frame = prep::choose_frame(fs, "");
  ASSERT_TRUE(std::isfinite(frame.tm_lon0));
  EXPECT_NEAR(frame.tm_lon0, lon_c, 1e-9);
  EXPECT_NEAR(frame.tm_lat0, lat_c, 1e-9);
  prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});

  // Reference: Karney's exact TM (elliptic functions), not a series.
  const GeographicLib::TransverseMercatorExact tm(GeographicLib::Constants::WGS84_a(),
                                                  GeographicLib::Constants::WGS84_f(), 1.0);
  double x0 = 0, y0 = 0;
  tm.Forward(frame.tm_lon0, frame.tm_lat0, frame.tm_lon0, x0, y0);
  const auto& in = original.layers[0].features[0].rings;
  const auto& out = p.features.layers[0].features[0].rings;
  ASSERT_EQ(in.size(), out.size());
  for (size_t i = 0; i < in.size(); ++i) {
    double x = 0, y = 0;
    tm.Forward(frame.tm_lon0, in[i][0].y, in[i][0].x, x, y);
    EXPECT_NEAR(out[i][0].x + frame.origin_x, x, 1e-6)
        << "lon " << in[i][0].x << " lat " << in[i][0].y;
    EXPECT_NEAR(out[i][0].y + frame.origin_y, y - y0, 1e-6)
        << "lon " << in[i][0].x << " lat " << in[i][0].y;
  }
  // The frame's point scale factor against the exact TM's k.
  double gamma = 0, k = 0, x = 0, y = 0;
  tm.Forward(frame.tm_lon0, lat_c + span, lon_c + span, x, y, gamma, k);
  EXPECT_NEAR(prep::frame_scale_factor(frame, x, y - y0), k, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Latitudes, LocalTm, testing::Values(0.0, 45.0, 70.0));

TEST(Project, Epsg4326IsReadAsLonLatNotInAuthorityOrder) {
  // Under authority order, 7.42 would be taken as a latitude: hundreds of
  // kilometres off.
  prep::FeatureSet fs = grid_of_points(7.42, 43.73, 0.01);
  const prep::FeatureSet original = fs;
  prep::SceneFrame frame = prep::choose_frame(fs, "EPSG:32632");
  prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});
  const auto& in = original.layers[0].features[0].rings;
  const auto& out = p.features.layers[0].features[0].rings;
  for (size_t i = 0; i < in.size(); ++i) {
    int zone = 0;
    bool north = true;
    double x = 0, y = 0;
    GeographicLib::UTMUPS::Forward(in[i][0].y, in[i][0].x, zone, north, x, y, 32);
    EXPECT_NEAR(out[i][0].x + frame.origin_x, x, 1e-6);
    EXPECT_NEAR(out[i][0].y + frame.origin_y, y, 1e-6);
  }
  // The origin is the data centre, rounded to whole metres.
  EXPECT_EQ(frame.origin_x, std::round(frame.origin_x));
  EXPECT_NEAR(out[12][0].x, 0.0, 1.0);
  EXPECT_NEAR(out[12][0].y, 0.0, 1.0);
}

TEST(Project, GeographicCrsIsRejectedAsSceneFrame) {
  prep::FeatureSet fs = grid_of_points(7.42, 43.73, 0.01);
  EXPECT_THROW(prep::choose_frame(fs, "EPSG:4326"), prep::input_error);
  EXPECT_THROW(prep::choose_frame(fs, "not a crs"), prep::input_error);
}

// Web Mercator (spherical formulas on WGS84 geodetic coordinates).
constexpr double kR = 6378137.0;
double merc_x(double lon) {
  return kR * lon * M_PI / 180;
}
double merc_y(double lat) {
  return kR * std::log(std::tan(M_PI / 4 + lat * M_PI / 360));
}

// A 10 ground-metre line, 10 m wide, at 60°N in EPSG:3857 (where one
// ground metre is about two Web Mercator metres).
std::string write_3857_line(const prep::test::TempDir& dir) {
  double lat2 = 0, lon2 = 0;
  GeographicLib::Geodesic::WGS84().Direct(60.0, 10.0, 90.0, 10.0, lat2, lon2);
  char json[1024];
  std::snprintf(
      json, sizeof json,
      R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:3857"}},
"features":[{"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[%.6f,%.6f],[%.6f,%.6f]]}}]})",
      merc_x(10.0), merc_y(60.0), merc_x(lon2), merc_y(lat2));
  prep::test::write_text(dir.file("line3857.geojson"), json);
  return dir.file("line3857.geojson");
}

prep::SceneFeatures build_line(const std::string& path, const std::string& crs) {
  prep::BuildSpec s = prep::test::one_layer("l", path, prep::DecalKind::line);
  s.layers[0].style.width = 10.0;
  s.crs = crs;
  return prep::test::dry_run(s);
}

TEST(Project, TenMetreLineInWebMercatorAt60NorthStaysTenGroundMetres) {
  prep::test::TempDir dir;
  const std::string path = write_3857_line(dir);
  // Default frame: local TM, where frame metres are ground metres.
  prep::SceneFeatures tm = build_line(path, "");
  ASSERT_EQ(tm.lines.size(), 1u);
  const auto& a = tm.lines[0].points;
  const double tm_len = std::hypot(a[1].x - a[0].x, a[1].y - a[0].y);
  EXPECT_NEAR(tm_len, 10.0, 0.05);
  EXPECT_NEAR(tm.lines[0].length, 10.0, 0.05);
  EXPECT_NEAR(tm.lines[0].width, 10.0, 0.05);

  // Frame = EPSG:3857: the stored width grows with the frame's scale so that
  // it still covers 10 ground metres.
  prep::SceneFeatures wm = build_line(path, "EPSG:3857");
  ASSERT_EQ(wm.lines.size(), 1u);
  const auto& b = wm.lines[0].points;
  const double frame_len = std::hypot(b[1].x - b[0].x, b[1].y - b[0].y);
  const double frame_per_ground = frame_len / 10.0;  // the line is 10 ground metres
  EXPECT_NEAR(frame_per_ground, 2.0, 0.02);
  EXPECT_NEAR(wm.lines[0].width / frame_per_ground, 10.0, 0.05);
  EXPECT_NEAR(wm.lines[0].length, 10.0, 0.05);
}

TEST(Project, WebMercatorScaleFactorMatchesTheAnalyticValue) {
  prep::FeatureSet fs = grid_of_points(10.0, 60.0, 0.01);
  prep::SceneFrame frame = prep::choose_frame(fs, "EPSG:3857");
  const double e2 = GeographicLib::Constants::WGS84_f() * (2 - GeographicLib::Constants::WGS84_f());
  for (double lat : {59.995, 60.0, 60.005}) {
    const double s = std::sin(lat * M_PI / 180), c = std::cos(lat * M_PI / 180);
    const double k = std::sqrt(1 - e2 * s * s) / c;  // east-west scale of Web Mercator
    const double x = merc_x(10.0) - frame.origin_x, y = merc_y(lat) - frame.origin_y;
    EXPECT_NEAR(prep::frame_scale_factor(frame, x, y), k, 1e-6 * k) << lat;
  }
}

// PROJ through GDAL from one CRS to another, x/y in GIS order: the oracle.
std::unique_ptr<OGRCoordinateTransformation> proj_transform(const std::string& from_wkt,
                                                            const std::string& to_wkt) {
  OGRSpatialReference src, dst;
  src.SetFromUserInput(from_wkt.c_str());
  src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  dst.SetFromUserInput(to_wkt.c_str());
  dst.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return std::unique_ptr<OGRCoordinateTransformation>(
      OGRCreateCoordinateTransformation(&src, &dst));
}

// The per-vertex transformation is a verified polynomial approximation of
// PROJ's (project.cpp); the oracle here is PROJ itself, vertex by vertex,
// over extents far larger than a scene (so the approximation has to split
// cells) and for a projected source (UTM inverse + TM forward).
void expect_matches_proj_per_vertex(const std::string& src_wkt, double x0, double y0, double w,
                                    double h, const std::string& crs, int per_feature = 25) {
  prep::FeatureSet fs;
  prep::SourceLayer layer;
  layer.spec.name = "pts";
  layer.spec.kind = prep::DecalKind::line;
  layer.srs_wkt = src_wkt;
  prep::test::Rng rng(12345);
  auto next = [&] { return rng.uniform(); };
  // 2,000 features of 25 vertices: enough for the approximation to fit
  // cells (it keeps the exact path for sparse data).
  for (int f = 0; f < 2000; ++f) {
    prep::SourceFeature feat;
    feat.feature = uint64_t(f);
    prep::Ring& r = feat.rings.emplace_back();
    for (int i = 0; i < per_feature; ++i) r.push_back({x0 + w * next(), y0 + h * next()});
    layer.features.push_back(feat);
  }
  fs.layers.push_back(layer);
  const prep::FeatureSet original = fs;
  prep::SceneFrame frame = prep::choose_frame(fs, crs);
  prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});

  const auto t = proj_transform(src_wkt, frame.crs_wkt);
  ASSERT_TRUE(t);
  double worst = 0;
  const auto& in = original.layers[0].features;
  const auto& out = p.features.layers[0].features;
  ASSERT_EQ(in.size(), out.size());
  for (size_t f = 0; f < in.size(); ++f) {
    ASSERT_EQ(out[f].rings[0].size(), in[f].rings[0].size());
    for (size_t i = 0; i < in[f].rings[0].size(); ++i) {
      double x = in[f].rings[0][i].x, y = in[f].rings[0][i].y;
      ASSERT_TRUE(t->Transform(1, &x, &y));
      worst = std::max({worst, std::fabs(out[f].rings[0][i].x + frame.origin_x - x),
                        std::fabs(out[f].rings[0][i].y + frame.origin_y - y)});
    }
  }
  EXPECT_LT(worst, 1e-7) << "largest deviation from PROJ per vertex, metres";
}

// A part of many vertices (project.cpp kParallelPartVertices) is projected
// in parallel chunks: the same vertices as 2,000 small features projected
// one per thread, bit for bit, and the same scale factor; PROJ per vertex
// is the oracle for both; a vertex PROJ cannot take is named as the serial
// path names it (the first in ring order).
TEST(Project, APartOfManyVerticesProjectsAsSmallPartsDoBitForBit) {
  prep::test::Rng rng(777);
  prep::SourceLayer small;
  small.spec.name = "rings";
  small.spec.kind = prep::DecalKind::line;
  small.srs_wkt = epsg_wkt(4326);
  prep::SourceFeature big;
  for (int f = 0; f < 2000; ++f) {
    prep::SourceFeature feat;
    feat.feature = uint64_t(f);
    prep::Ring& r = feat.rings.emplace_back();
    for (int i = 0; i < 50; ++i)
      r.push_back({7.0 + 0.5 * rng.uniform(), 43.5 + 0.5 * rng.uniform()});
    big.rings.push_back(r);
    small.features.push_back(std::move(feat));
  }
  prep::SourceLayer one = small;
  one.features = {big};
  prep::FeatureSet a, b;
  a.layers.push_back(small);
  b.layers.push_back(one);
  const prep::SceneFrame frame = prep::choose_frame(a, "");
  const prep::ProjectedFeatures pa = prep::project(a, frame, prep::BuildSpec{});
  const prep::ProjectedFeatures pb = prep::project(b, frame, prep::BuildSpec{});
  const auto& rings = pb.features.layers[0].features[0].rings;
  ASSERT_EQ(rings.size(), 2000u);
  const auto t = proj_transform(epsg_wkt(4326), frame.crs_wkt);
  ASSERT_TRUE(t);
  double worst = 0;
  size_t differ = 0;
  for (size_t f = 0; f < 2000; ++f) {
    const prep::Ring& want = pa.features.layers[0].features[f].rings[0];
    ASSERT_EQ(rings[f].size(), want.size());
    for (size_t i = 0; i < want.size(); ++i) {
      differ += rings[f][i].x != want[i].x || rings[f][i].y != want[i].y;
      double x = big.rings[f][i].x, y = big.rings[f][i].y;
      ASSERT_TRUE(t->Transform(1, &x, &y));
      worst = std::max({worst, std::fabs(rings[f][i].x + frame.origin_x - x),
                        std::fabs(rings[f][i].y + frame.origin_y - y)});
    }
  }
  EXPECT_EQ(differ, 0u) << "vertices of the big part that differ from the small parts'";
  EXPECT_LT(worst, 1e-7) << "largest deviation from PROJ per vertex, metres";

  // Two vertices PROJ cannot take (latitude 91): the first in ring order
  // is named, as the serial path would.
  prep::FeatureSet bad;
  bad.layers.push_back(one);
  bad.layers[0].features[0].rings[1500][7] = {7.1, 91.0};
  bad.layers[0].features[0].rings[1700][3] = {7.2, 92.0};
  try {
    prep::project(bad, frame, prep::BuildSpec{});
    FAIL() << "a vertex at latitude 91 was projected";
  } catch (const prep::error& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 7 (7.100000, 91.000000)"), std::string::npos)
        << e.what();
  }
}

TEST(Project, GeographicSourceOverAQuarterDegreeMatchesProjPerVertexTo100Nanometres) {
  expect_matches_proj_per_vertex(epsg_wkt(4326), 7.0, 43.5, 0.25, 0.25, "");
}

TEST(Project, UtmSourceOver40KilometresMatchesProjPerVertexTo100Nanometres) {
  expect_matches_proj_per_vertex(epsg_wkt(32632), 300000, 4800000, 40000, 40000, "");
}

// A continent into Equal Earth with 400,000 vertices: cells of hundreds of
// kilometres, where the degree-7 fit passes its check grid only when it
// holds between the grid's points too (the argument in project.cpp).
TEST(Project, ContinentIntoEqualEarthMatchesProjPerVertexTo100Nanometres) {
  expect_matches_proj_per_vertex(epsg_wkt(4326), -10.0, 35.0, 60.0, 35.0, "EPSG:8857", 200);
}

TEST(Project, GeographicSourceNearThePoleIntoPolarStereographicMatchesProjPerVertex) {
  expect_matches_proj_per_vertex(epsg_wkt(4326), -45.0, 85.0, 0.2, 0.1, "EPSG:3413");
}

}  // namespace
