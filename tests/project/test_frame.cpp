// The default scene frame for data of any extent (libprep/project,
// choose_frame): the local TM kept for every scene it held before, data
// across the antimeridian, continental and world extents, and the width
// factor of the new frames. Oracles: GeographicLib's exact TM, OGR/PROJ
// transformations and PROJ's proj_factors, analytic values, and ogrinfo for
// the real world layer (spData's world.gpkg, scripts/fetch-data).
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <proj.h>
#include <GeographicLib/TransverseMercatorExact.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "../read/fixtures.hpp"
#include "../read/scene_fixtures.hpp"
#include "epsg_wkt.hpp"
#include "prep/error.hpp"
#include "prep/project.hpp"
#include "prep/read.hpp"

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// One layer of lon/lat rings (EPSG:4326, x = lon).
prep::FeatureSet layer_of(const std::vector<prep::Ring>& rings, bool polygon = true) {
  prep::FeatureSet fs;
  prep::SourceLayer layer;
  layer.spec.name = "l";
  layer.spec.kind = polygon ? prep::DecalKind::polygon : prep::DecalKind::line;
  layer.srs_wkt = epsg_wkt(4326);
  for (const prep::Ring& r : rings) {
    prep::SourceFeature f;
    f.is_polygon = polygon;
    f.rings.push_back(r);
    layer.features.push_back(f);
  }
  fs.layers.push_back(layer);
  return fs;
}

prep::Ring box(double w, double s, double e, double n) {
  return {{w, s}, {e, s}, {e, n}, {w, n}, {w, s}};
}

// The frame as the local TM has always been defined (project.cpp before the
// default frame learnt other projections): centred on the middle of the
// data's lon/lat box, rounded to 1e-7 degrees. The box is taken here from
// the vertices (a geographic source: GDAL's box of a lon/lat box is itself).
struct TmFrame {
  std::string description, wkt;
};
TmFrame expected_local_tm(const prep::FeatureSet& fs) {
  double w = kInf, s = kInf, e = -kInf, n = -kInf;
  for (const auto& l : fs.layers)
    for (const auto& f : l.features)
      for (const auto& r : f.rings)
        for (const auto& p : r) {
          w = std::min(w, p.x), e = std::max(e, p.x);
          s = std::min(s, p.y), n = std::max(n, p.y);
        }
  const double lon0 = std::round((w + e) * 0.5 * 1e7) / 1e7;
  const double lat0 = std::round((s + n) * 0.5 * 1e7) / 1e7;
  char def[256];
  std::snprintf(def, sizeof def,
                "+proj=tmerc +lat_0=%.7f +lon_0=%.7f +k=1 +x_0=0 +y_0=0 +datum=WGS84 +units=m "
                "+no_defs +type=crs",
                lat0, lon0);
  OGRSpatialReference srs;
  srs.SetFromUserInput(def);
  const char* opts[] = {"FORMAT=WKT2_2019", "MULTILINE=NO", nullptr};
  char* wkt = nullptr;
  srs.exportToWkt(&wkt, opts);
  TmFrame t{"", wkt};
  CPLFree(wkt);
  std::snprintf(def, sizeof def, "local TM lon0=%.7f lat0=%.7f (WGS84, k0=1)", lon0, lat0);
  t.description = def;
  return t;
}

// Every vertex of `fs` in the frame (absolute frame coordinates) through
// OGR/PROJ: the oracle for where the vertices land.
struct Projected {
  std::vector<double> x, y;
  double xmin = kInf, xmax = -kInf, ymin = kInf, ymax = -kInf;
};
Projected ogr_project(const prep::FeatureSet& fs, const std::string& frame_wkt) {
  OGRSpatialReference src, dst;
  src.SetFromUserInput(fs.layers[0].srs_wkt.c_str());
  src.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  dst.SetFromUserInput(frame_wkt.c_str());
  dst.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> t(OGRCreateCoordinateTransformation(&src, &dst));
  Projected p;
  for (const auto& l : fs.layers)
    for (const auto& f : l.features)
      for (const auto& r : f.rings)
        for (const auto& v : r) {
          double x = v.x, y = v.y;
          if (!t || !t->Transform(1, &x, &y)) x = y = std::nan("");
          p.x.push_back(x), p.y.push_back(y);
          p.xmin = std::min(p.xmin, x), p.xmax = std::max(p.xmax, x);
          p.ymin = std::min(p.ymin, y), p.ymax = std::max(p.ymax, y);
        }
  return p;
}

// ------------------------------------------------ (a) the local TM stays --

TEST(DefaultFrame, MonacoSampleKeepsItsLocalTransverseMercatorExactly) {
  prep::BuildSpec scene = prep::load_scene_file(prep::test::monaco_sample("scene.toml"));
  const prep::FeatureSet fs = prep::read_scene(scene);
  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  const TmFrame want = expected_local_tm(fs);
  EXPECT_EQ(frame.description, want.description);
  EXPECT_EQ(frame.crs_wkt, want.wkt);
  // The frame the documentation (docs/build.md) has always shown for the sample.
  EXPECT_EQ(frame.description, "local TM lon0=7.4199727 lat0=43.7425030 (WGS84, k0=1)");
  EXPECT_EQ(frame.origin_x, 0.0);
  EXPECT_EQ(frame.origin_y, 0.0);
}

// Small and not so small scenes, and the polar ones the TM has always held:
// the same frame as before, to the byte.
TEST(DefaultFrame, EveryExtentTheTransverseMercatorHoldsKeepsItExactly) {
  const std::vector<std::vector<prep::Ring>> scenes = {
      {box(7.40, 43.72, 7.45, 43.76)},                          // a town
      {box(9.47, 47.04, 9.64, 47.27)},                          // Liechtenstein's box
      {box(-10.0, 35.0, 30.0, 60.0)},                           // Western Europe
      {box(0.0, 60.0, 60.0, 70.0)},                             // 60 degrees wide at 60 N
      {box(-29.0, -5.0, 29.0, 5.0)},                            // 58 degrees at the equator
      {{{0, 89.99}, {120, 89.99}, {-120, 89.99}, {0, 89.99}}},  // around the pole
      {box(-180.0, 62.0, 180.0, 85.0)},                         // the Arctic above 62 N
  };
  for (const auto& rings : scenes) {
    const prep::FeatureSet fs = layer_of(rings);
    const prep::SceneFrame frame = prep::choose_frame(fs, "");
    const TmFrame want = expected_local_tm(fs);
    EXPECT_EQ(frame.description, want.description);
    EXPECT_EQ(frame.crs_wkt, want.wkt) << want.description;
    EXPECT_TRUE(std::isfinite(frame.tm_lon0)) << want.description;
  }
}

// ------------------------------------------------ (b) the antimeridian --

// Fiji-like: 177.2 E .. 178.5 W, 16..17 S, once as rings that cross the
// antimeridian and once split there (RFC 7946).
TEST(DefaultFrame, PacificDataAcrossTheAntimeridianIsCentredNear180AndStaysSmall) {
  const std::vector<prep::Ring> crossing = {
      {{177.2, -17.0}, {-178.5, -17.0}, {-178.5, -16.0}, {177.2, -16.0}, {177.2, -17.0}},
      {{179.5, -16.8}, {-179.5, -16.8}, {-179.5, -16.2}, {179.5, -16.8}}};
  const std::vector<prep::Ring> split = {box(177.2, -17.0, 180.0, -16.0),
                                         box(-180.0, -17.0, -178.5, -16.0)};
  for (const auto& rings : {crossing, split}) {
    prep::FeatureSet fs = layer_of(rings);
    const prep::FeatureSet original = fs;
    const prep::SceneFrame frame = prep::choose_frame(fs, "");
    ASSERT_TRUE(std::isfinite(frame.tm_lon0)) << frame.description;
    // The arc 177.2 .. 181.5 has its centre at 179.35.
    EXPECT_NEAR(frame.tm_lon0, 179.35, 0.1) << frame.description;
    EXPECT_NEAR(frame.tm_lat0, -16.5, 1e-9);
    const prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});
    // Oracle: Karney's exact TM on the frame's central meridian.
    const GeographicLib::TransverseMercatorExact tm(GeographicLib::Constants::WGS84_a(),
                                                    GeographicLib::Constants::WGS84_f(), 1.0);
    double x0 = 0, y0 = 0;
    tm.Forward(frame.tm_lon0, frame.tm_lat0, frame.tm_lon0, x0, y0);
    double xmin = kInf, xmax = -kInf, ymin = kInf, ymax = -kInf, worst = 0;
    for (size_t f = 0; f < original.layers[0].features.size(); ++f) {
      const auto& in = original.layers[0].features[f].rings[0];
      const auto& out = p.features.layers[0].features[f].rings[0];
      ASSERT_EQ(in.size(), out.size());
      for (size_t i = 0; i < in.size(); ++i) {
        double x = 0, y = 0;
        tm.Forward(frame.tm_lon0, in[i].y, in[i].x, x, y);
        worst = std::max({worst, std::fabs(out[i].x + frame.origin_x - x),
                          std::fabs(out[i].y + frame.origin_y - (y - y0))});
        xmin = std::min(xmin, out[i].x), xmax = std::max(xmax, out[i].x);
        ymin = std::min(ymin, out[i].y), ymax = std::max(ymax, out[i].y);
      }
    }
    EXPECT_LT(worst, 1e-6);
    // 4.3 degrees of longitude at 16.5 S: about 460 km, not 40,000.
    EXPECT_LT(xmax - xmin, 500e3);
    EXPECT_GT(xmax - xmin, 400e3);
    EXPECT_LT(ymax - ymin, 120e3);
  }
  // The split halves meet: 180 and -180 land on the same frame easting.
  prep::FeatureSet fs = layer_of(split);
  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  const prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});
  const auto& west_half = p.features.layers[0].features[0].rings[0];  // 177.2 .. 180
  const auto& east_half = p.features.layers[0].features[1].rings[0];  // -180 .. -178.5
  EXPECT_NEAR(west_half[1].x, east_half[0].x, 1e-6);                  // (180, -17), (-180, -17)
  EXPECT_NEAR(west_half[1].y, east_half[0].y, 1e-6);
}

// 50,000 lon/lat vertices across the antimeridian (enough for project() to
// fit its verified approximation, over longitudes it first brings within
// 180 degrees of the frame's centre): vertex by vertex where PROJ puts the
// original coordinates.
TEST(DefaultFrame, ManyVerticesAcrossTheAntimeridianMatchProjPerVertex) {
  prep::test::Rng rng(12345);
  auto next = [&] { return rng.uniform(); };
  std::vector<prep::Ring> rings;
  for (int f = 0; f < 2000; ++f) {
    prep::Ring& r = rings.emplace_back();
    for (int i = 0; i < 25; ++i) {
      const double lon = 178.0 + 4.0 * next();
      r.push_back({lon > 180.0 ? lon - 360.0 : lon, -18.0 + 3.0 * next()});
    }
  }
  prep::FeatureSet fs = layer_of(rings, false);
  const prep::FeatureSet original = fs;
  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  ASSERT_TRUE(std::isfinite(frame.tm_lon0)) << frame.description;
  EXPECT_NEAR(frame.tm_lon0, 180.0, 0.01) << frame.description;
  const prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});
  const Projected want = ogr_project(original, frame.crs_wkt);
  size_t k = 0;
  double worst = 0;
  for (const auto& f : p.features.layers[0].features)
    for (const auto& v : f.rings[0]) {
      worst = std::max({worst, std::fabs(v.x + frame.origin_x - want.x[k]),
                        std::fabs(v.y + frame.origin_y - want.y[k])});
      ++k;
    }
  EXPECT_EQ(k, want.x.size());
  EXPECT_LT(worst, 1e-7) << "largest deviation from PROJ per vertex, metres";
  EXPECT_LT(want.xmax - want.xmin, 450e3);
}

// A projected source across the antimeridian (GDAL reports its lon/lat box
// with xmin > xmax): the same frame as the lon/lat data.
TEST(DefaultFrame, ProjectedSourceAcrossTheAntimeridianIsCentredNear180) {
  prep::FeatureSet fs =
      layer_of({box(177.2, -17.0, 180.0, -16.0), box(-180.0, -17.0, -178.5, -16.0)});
  OGRSpatialReference geo, pdc;
  geo.importFromEPSG(4326);
  geo.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  pdc.importFromEPSG(3832);  // PDC Mercator, centred on 150 E
  pdc.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> t(OGRCreateCoordinateTransformation(&geo, &pdc));
  for (auto& f : fs.layers[0].features)
    for (auto& v : f.rings[0]) ASSERT_TRUE(t->Transform(1, &v.x, &v.y));
  char* wkt = nullptr;
  pdc.exportToWkt(&wkt);
  fs.layers[0].srs_wkt = wkt;
  CPLFree(wkt);
  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  ASSERT_TRUE(std::isfinite(frame.tm_lon0)) << frame.description;
  EXPECT_NEAR(std::fabs(frame.tm_lon0), 179.35, 0.1) << frame.description;
}

// ------------------------------------------------ continental extents --

// 70 degrees of longitude at the equator: 4166 km from the central meridian
// (GeographicLib), past the TM's 3900 km; within 90 degrees of the centre,
// so the oblique stereographic, centred on the data.
TEST(DefaultFrame, ContinentalExtentGetsAnObliqueStereographicCentredOnTheData) {
  prep::FeatureSet fs = layer_of({box(-35.0, -5.0, 35.0, 5.0)});
  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  EXPECT_FALSE(std::isfinite(frame.tm_lon0));
  EXPECT_EQ(frame.description,
            "local oblique stereographic lon0=0.0000000 lat0=0.0000000 (WGS84, k0=1)");
  OGRSpatialReference srs;
  ASSERT_EQ(srs.importFromWkt(frame.crs_wkt.c_str()), OGRERR_NONE);
  EXPECT_STREQ(srs.GetAttrValue("PROJECTION"), "Oblique_Stereographic");
  // 60 degrees there: 3505 km, still the TM.
  EXPECT_TRUE(
      std::isfinite(prep::choose_frame(layer_of({box(-30.0, -5.0, 30.0, 5.0)}), "").tm_lon0));

  // Asia and the Russian Far East across the antimeridian: centred on the
  // arc 40 E .. 170 W (centre 115 E), not on the Atlantic.
  const prep::SceneFrame asia = prep::choose_frame(
      layer_of({box(40.0, 40.0, 180.0, 75.0), box(-180.0, 60.0, -170.0, 70.0)}), "");
  EXPECT_EQ(asia.description,
            "local oblique stereographic lon0=115.0000000 lat0=57.5000000 (WGS84, k0=1)");

  // The northern hemisphere above 30 N all round: centred on the pole.
  const prep::SceneFrame north = prep::choose_frame(layer_of({box(-180.0, 30.0, 180.0, 85.0)}), "");
  EXPECT_EQ(north.description,
            "local oblique stereographic lon0=0.0000000 lat0=90.0000000 (WGS84, k0=1)");
}

// ------------------------------------------------ (c) the world --

// Features, parts and vertices of world.gpkg as ogrinfo counts them (the
// independent oracle of what the reader read).
long long ogr_sql(const std::string& path, const std::string& sql) {
  prep::test::TempDir dir;
  return prep::test::ogrinfo_count_sql(path, sql, "SQLITE", dir);
}

TEST(DefaultFrame, WorldLayerGetsEqualEarthAndEveryVertexProjectsFinite) {
  const std::string path = prep::test::spdata_dir() + "/shapes/world.gpkg";
  if (!prep::test::exists(path))
    GTEST_SKIP() << path << " is missing: run scripts/fetch-data (it unpacks r-cran-spdata)";
  prep::FeatureSet fs = prep::read_scene(prep::test::one_layer("world", path));
  ASSERT_EQ(fs.layers.size(), 1u);
  // 177 countries in 289 polygons (ogrinfo's count of features; parts from
  // SpatiaLite's NumGeometries).
  EXPECT_EQ(ogr_sql(path, "SELECT COUNT(*) FROM world"), 177);
  EXPECT_EQ(ogr_sql(path, "SELECT SUM(ST_NumGeometries(geom)) FROM world"),
            static_cast<long long>(fs.layers[0].features.size()));
  const prep::FeatureSet original = fs;

  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  EXPECT_EQ(frame.description, "Equal Earth lon0=0.0000000 (WGS84; EPSG:8857)");
  // The frame CRS round-trips through OGR and is EPSG:8857.
  OGRSpatialReference srs, epsg;
  ASSERT_EQ(srs.importFromWkt(frame.crs_wkt.c_str()), OGRERR_NONE);
  epsg.importFromEPSG(8857);
  EXPECT_TRUE(srs.IsSame(&epsg));
  EXPECT_STREQ(srs.GetAuthorityCode(nullptr), "8857");
  char* again = nullptr;
  const char* opts[] = {"FORMAT=WKT2_2019", "MULTILINE=NO", nullptr};
  srs.exportToWkt(&again, opts);
  EXPECT_EQ(frame.crs_wkt, again);
  CPLFree(again);

  // Every vertex projects (project() throws on the first that does not)
  // to a finite point, where OGR puts it.
  const prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});
  const Projected want = ogr_project(original, frame.crs_wkt);
  size_t k = 0;
  double worst = 0;
  for (const auto& f : p.features.layers[0].features) {
    ASSERT_TRUE(f.drop_reason.empty()) << f.drop_reason;
    for (const auto& r : f.rings)
      for (const auto& v : r) {
        ASSERT_TRUE(std::isfinite(v.x) && std::isfinite(v.y));
        ASSERT_LT(k, want.x.size());
        worst = std::max({worst, std::fabs(v.x + frame.origin_x - want.x[k]),
                          std::fabs(v.y + frame.origin_y - want.y[k])});
        ++k;
      }
  }
  EXPECT_EQ(k, want.x.size());
  EXPECT_LT(worst, 1e-6);
  // Equal Earth's own extent: +-17,243,959 m along the equator (Savric et
  // al. 2018: x = 2 sqrt(3) lon / (3 A1) times the authalic radius).
  EXPECT_GT(want.xmin, -17.25e6);
  EXPECT_LT(want.xmax, 17.25e6);
  EXPECT_LT(want.xmax - want.xmin, 34.5e6);
  EXPECT_GT(want.xmax - want.xmin, 33.0e6);
  // Widths need no factor on an equal-area frame (below; central
  // differences of 5 m steps leave ~1e-9).
  for (double s : p.scale[0]) EXPECT_NEAR(s, 1.0, 1e-8);
}

// A world ring with vertices at exactly -180 and +180 (an ocean or a world
// box as RFC 7946 writes them), lopsided so that the Equal Earth frame's
// origin (the centre of the data's box) lies far west of its central
// meridian: every vertex still lands where PROJ puts it. Longitudes were
// once brought within 180 degrees of the origin instead of the central
// meridian, which moved the +180 vertices to the -180 edge, across the map.
TEST(DefaultFrame, WorldRingAtBothEdgesKeepsItsSidesWhenTheOriginIsOffTheCentralMeridian) {
  prep::FeatureSet fs = layer_of({{{-180.0, 0.0}, {180.0, -60.0}, {180.0, 70.0}, {-180.0, 70.0}}});
  const prep::FeatureSet original = fs;
  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  EXPECT_EQ(frame.description, "Equal Earth lon0=0.0000000 (WGS84; EPSG:8857)");
  EXPECT_LT(frame.origin_x, -1e6) << "the origin should lie west of the central meridian";
  const prep::ProjectedFeatures p = prep::project(fs, frame, prep::BuildSpec{});
  const Projected want = ogr_project(original, frame.crs_wkt);
  size_t k = 0;
  double worst = 0;
  for (const auto& f : p.features.layers[0].features)
    for (const auto& r : f.rings)
      for (const auto& v : r) {
        ASSERT_LT(k, want.x.size());
        worst = std::max({worst, std::fabs(v.x + frame.origin_x - want.x[k]),
                          std::fabs(v.y + frame.origin_y - want.y[k])});
        ++k;
      }
  EXPECT_EQ(k, want.x.size());
  EXPECT_LT(worst, 1e-6) << "largest deviation from PROJ per vertex, metres";
}

TEST(DefaultFrame, FijiFromTheWorldLayerGetsASmallFrameNear180) {
  const std::string path = prep::test::spdata_dir() + "/shapes/world.gpkg";
  if (!prep::test::exists(path))
    GTEST_SKIP() << path << " is missing: run scripts/fetch-data (it unpacks r-cran-spdata)";
  prep::BuildSpec scene = prep::test::one_layer("fiji", path);
  scene.layers[0].where = "name_long = 'Fiji'";
  prep::FeatureSet fs = prep::read_scene(scene);
  const prep::SceneFrame frame = prep::choose_frame(fs, "");
  ASSERT_TRUE(std::isfinite(frame.tm_lon0)) << frame.description;
  EXPECT_GT(std::fabs(frame.tm_lon0), 178.0) << frame.description;
  const Projected p = ogr_project(fs, frame.crs_wkt);
  EXPECT_LT(p.xmax - p.xmin, 600e3);
  EXPECT_LT(p.ymax - p.ymin, 400e3);
}

// ------------------------------------------------ (d) the width factor --

struct Pj {
  PJ_CONTEXT* ctx = proj_context_create();
  PJ* pj = nullptr;
  explicit Pj(const std::string& def) { pj = proj_create(ctx, def.c_str()); }
  ~Pj() {
    proj_destroy(pj);
    proj_context_destroy(ctx);
  }
  Pj(const Pj&) = delete;
  Pj& operator=(const Pj&) = delete;
  PJ_FACTORS at(double lon, double lat) const {
    return proj_factors(pj, proj_coord(proj_torad(lon), proj_torad(lat), 0, 0));
  }
};

// Frame coordinates (relative to the origin) of a lon/lat point.
std::pair<double, double> in_frame(const prep::SceneFrame& frame, double lon, double lat) {
  OGRSpatialReference geo, dst;
  geo.importFromEPSG(4326);
  geo.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  dst.importFromWkt(frame.crs_wkt.c_str());
  dst.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> t(OGRCreateCoordinateTransformation(&geo, &dst));
  double x = lon, y = lat;
  EXPECT_TRUE(t && t->Transform(1, &x, &y));
  return {x - frame.origin_x, y - frame.origin_y};
}

// The oblique stereographic is conformal: its factor is PROJ's scale along
// the meridian (the same along the parallel).
TEST(DefaultFrame, StereographicWidthFactorIsProjsPointScale) {
  const prep::SceneFrame frame = prep::choose_frame(
      layer_of({box(40.0, 40.0, 180.0, 75.0), box(-180.0, 60.0, -170.0, 70.0)}), "");
  ASSERT_EQ(frame.description,
            "local oblique stereographic lon0=115.0000000 lat0=57.5000000 (WGS84, k0=1)");
  Pj pj("+proj=sterea +lat_0=57.5 +lon_0=115 +k=1 +x_0=0 +y_0=0 +ellps=WGS84");
  ASSERT_TRUE(pj.pj);
  for (const auto& [lon, lat] : std::vector<std::pair<double, double>>{
           {115.0, 57.5}, {40.0, 40.0}, {175.0, 75.0}, {-170.0, 65.0}, {120.0, 45.0}}) {
    const PJ_FACTORS f = pj.at(lon, lat);
    EXPECT_NEAR(f.meridional_scale, f.parallel_scale, 1e-8);
    const auto [x, y] = in_frame(frame, lon, lat);
    EXPECT_NEAR(prep::frame_scale_factor(frame, x, y), f.meridional_scale,
                1e-6 * f.meridional_scale)
        << lon << ", " << lat;
  }
  // Analytic on the sphere, k = 1 / cos^2(c / 2): about 1.22 at the far
  // corner (40 E, 40 N), c = 49.6 degrees from the centre.
  const auto [x, y] = in_frame(frame, 40.0, 40.0);
  EXPECT_NEAR(prep::frame_scale_factor(frame, x, y), 1.0 / std::pow(std::cos(49.6 * M_PI / 360), 2),
              0.02);
}

// Equal Earth: the factor is sqrt(a b), the square root of the areal scale,
// which is 1 on an equal-area projection (analytic), and PROJ's Tissot
// semi-axes agree; the east-west scale alone (what a conformal frame would
// use) is far from it there.
TEST(DefaultFrame, EqualEarthWidthFactorIsTheGeometricMeanOfTissotsAxes) {
  const prep::SceneFrame frame =
      prep::choose_frame(layer_of({box(-180.0, -80.0, 180.0, 80.0)}), "");
  ASSERT_EQ(frame.description, "Equal Earth lon0=0.0000000 (WGS84; EPSG:8857)");
  Pj pj("+proj=eqearth +lon_0=0 +ellps=WGS84");
  ASSERT_TRUE(pj.pj);
  for (const auto& [lon, lat] : std::vector<std::pair<double, double>>{
           {0.0, 0.0}, {30.0, 45.0}, {-120.0, 60.0}, {170.0, -75.0}, {90.0, 10.0}}) {
    const PJ_FACTORS f = pj.at(lon, lat);
    const double mean = std::sqrt(f.tissot_semimajor * f.tissot_semiminor);
    EXPECT_NEAR(mean, 1.0, 1e-6) << lon << ", " << lat;
    EXPECT_NEAR(f.areal_scale, 1.0, 1e-6);
    const auto [x, y] = in_frame(frame, lon, lat);
    EXPECT_NEAR(prep::frame_scale_factor(frame, x, y), mean, 1e-6) << lon << ", " << lat;
    if (lat >= 45.0) {
      EXPECT_GT(std::fabs(f.parallel_scale - 1.0), 0.04);
    }
  }
}

// The same rule for an equal-area --crs (LAEA Europe, EPSG:3035): 1, where
// the east-west scale that a conformal --crs gets is 0.5% off (and Tissot's
// axes 3% apart).
TEST(DefaultFrame, EqualAreaCrsWidthFactorIsTheGeometricMeanToo) {
  const prep::SceneFrame frame =
      prep::choose_frame(layer_of({box(5.0, 45.0, 35.0, 65.0)}), "EPSG:3035");
  Pj pj("+proj=laea +lat_0=52 +lon_0=10 +x_0=4321000 +y_0=3210000 +ellps=GRS80");
  ASSERT_TRUE(pj.pj);
  for (const auto& [lon, lat] :
       std::vector<std::pair<double, double>>{{10.0, 52.0}, {35.0, 65.0}, {5.0, 45.0}}) {
    const PJ_FACTORS f = pj.at(lon, lat);
    const auto [x, y] = in_frame(frame, lon, lat);
    EXPECT_NEAR(prep::frame_scale_factor(frame, x, y),
                std::sqrt(f.tissot_semimajor * f.tissot_semiminor), 1e-6)
        << lon << ", " << lat;
  }
  EXPECT_GT(std::fabs(pj.at(35.0, 65.0).parallel_scale - 1.0), 1e-3);
  EXPECT_GT(pj.at(35.0, 65.0).tissot_semimajor / pj.at(35.0, 65.0).tissot_semiminor, 1.02);
}

// A longitude that is not one (a broken vertex, or a layer in the wrong CRS)
// gets the clear error that names the layer and the value.
TEST(DefaultFrame, LongitudesThatAreNotLongitudesAreRefusedNamingThem) {
  prep::FeatureSet fs = layer_of({{{7.0, 43.0}, {1e300, 43.0}}}, false);
  fs.layers[0].spec.source = "broken.geojson";
  try {
    prep::choose_frame(fs, "");
    ADD_FAILURE() << "no error";
  } catch (const prep::input_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("broken.geojson"), std::string::npos) << what;
    EXPECT_NE(what.find("1e+300"), std::string::npos) << what;
  }
}

}  // namespace
