// Clean on synthetic GeoJSON written to a temp dir
// and read through GDAL. Each case ends valid (GEOS isValid) with the area
// GEOS MakeValid gives the original geometry (1e-9 relative), or dropped with
// a reason.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "../read/fixtures.hpp"
#include "../read/scene_fixtures.hpp"
#include "geos_oracle.hpp"
#include "prep/error.hpp"
#include "prep/pipeline.hpp"

namespace {

using prep::test::Geos;
using prep::test::TempDir;

// Coordinates are UTM 32N metres around (500000, 4800000); the scene frame is
// the same CRS, so project is a pure translation and areas compare directly.
// x = 500000 is zone 32's central meridian, where the UTM scale is k0.
constexpr double kX0 = 500000, kY0 = 4800000;
constexpr double kUtmK0 = 0.9996;

struct Case {
  int fid;
  const char* name;
  std::string geojson;  // geometry member
  std::string wkt;      // the same geometry, rings closed, for the oracle
};

std::string ring_json(const std::vector<std::pair<double, double>>& pts) {
  std::ostringstream s;
  s.precision(17);
  s << "[";
  for (size_t i = 0; i < pts.size(); ++i)
    s << (i ? "," : "") << "[" << kX0 + pts[i].first << "," << kY0 + pts[i].second << "]";
  return s.str() + "]";
}

std::string ring_wkt(std::vector<std::pair<double, double>> pts) {
  if (pts.front() != pts.back()) pts.push_back(pts.front());
  std::ostringstream s;
  s.precision(17);
  s << "(";
  for (size_t i = 0; i < pts.size(); ++i)
    s << (i ? ", " : "") << kX0 + pts[i].first << " " << kY0 + pts[i].second;
  return s.str() + ")";
}

using Pts = std::vector<std::pair<double, double>>;

Case polygon_case(int fid, const char* name, const std::vector<Pts>& rings) {
  std::string j = R"({"type":"Polygon","coordinates":[)";
  std::string w = "POLYGON (";
  for (size_t i = 0; i < rings.size(); ++i) {
    j += (i ? "," : "") + ring_json(rings[i]);
    w += (i ? ", " : "") + ring_wkt(rings[i]);
  }
  return {fid, name, j + "]}", w + ")"};
}

std::vector<Case> cases() {
  const Pts square = {{0, 0}, {100, 0}, {100, 100}, {0, 100}, {0, 0}};
  std::vector<Case> c;
  c.push_back(polygon_case(1, "bow-tie", {{{0, 0}, {100, 100}, {100, 0}, {0, 100}, {0, 0}}}));
  c.push_back(polygon_case(
      2, "spike",
      {{{0, 0}, {100, 0}, {100, 100}, {50, 100}, {50, 180}, {50, 100}, {0, 100}, {0, 0}}}));
  c.push_back(
      polygon_case(3, "duplicate points",
                   {{{0, 0}, {0, 0}, {100, 0}, {100, 0}, {100, 0}, {100, 100}, {0, 100}, {0, 0}}}));
  c.push_back(polygon_case(4, "unclosed ring", {{{0, 0}, {100, 0}, {100, 100}, {0, 100}}}));
  c.push_back(polygon_case(5, "hole touching shell at a point",
                           {square, {{0, 50}, {40, 30}, {40, 70}, {0, 50}}}));
  c.push_back(polygon_case(6, "hole touching shell along an edge",
                           {square, {{0, 20}, {40, 20}, {40, 60}, {0, 60}, {0, 20}}}));
  c.push_back(polygon_case(7, "hole outside shell",
                           {square, {{200, 0}, {200, 50}, {250, 50}, {250, 0}, {200, 0}}}));
  c.push_back(polygon_case(8, "three-level nesting in one polygon",
                           {{{0, 0}, {300, 0}, {300, 300}, {0, 300}, {0, 0}},
                            {{100, 100}, {100, 200}, {200, 200}, {200, 100}, {100, 100}},
                            {{130, 130}, {170, 130}, {170, 170}, {130, 170}, {130, 130}}}));
  {
    // Three-level nesting as OGC wants it: polygon with hole, island apart.
    Case m{9, "three-level nesting as a multipolygon", "", ""};
    m.geojson = R"({"type":"MultiPolygon","coordinates":[[)" +
                ring_json({{0, 0}, {300, 0}, {300, 300}, {0, 300}, {0, 0}}) + "," +
                ring_json({{100, 100}, {100, 200}, {200, 200}, {200, 100}, {100, 100}}) + "],[" +
                ring_json({{130, 130}, {170, 130}, {170, 170}, {130, 170}, {130, 130}}) + "]]}";
    m.wkt = "MULTIPOLYGON ((" + ring_wkt({{0, 0}, {300, 0}, {300, 300}, {0, 300}}) + ", " +
            ring_wkt({{100, 100}, {100, 200}, {200, 200}, {200, 100}}) + "), (" +
            ring_wkt({{130, 130}, {170, 130}, {170, 170}, {130, 170}}) + "))";
    c.push_back(m);
  }
  c.push_back(polygon_case(10, "zero area (collinear)", {{{0, 0}, {50, 0}, {100, 0}, {0, 0}}}));
  c.push_back(
      polygon_case(11, "zero area (two distinct points)", {{{0, 0}, {50, 0}, {50, 0}, {0, 0}}}));
  c.push_back(polygon_case(12, "clockwise shell, counter-clockwise hole",
                           {{{0, 0}, {0, 100}, {100, 100}, {100, 0}, {0, 0}},
                            {{20, 20}, {80, 20}, {80, 80}, {20, 80}, {20, 20}}}));
  return c;
}

std::string collection(const std::vector<Case>& cs) {
  std::string s =
      R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},"features":[)";
  for (size_t i = 0; i < cs.size(); ++i) {
    s += (i ? "," : "") + std::string(R"({"type":"Feature","id":)") + std::to_string(cs[i].fid) +
         R"(,"properties":{},"geometry":)" + cs[i].geojson + "}";
  }
  return s + "]}";
}

prep::SceneFeatures run(const std::string& source, prep::DecalKind kind, double resolution = 0,
                        std::optional<prep::Extent> extent = std::nullopt, unsigned threads = 0,
                        prep::RepairMethod repair = prep::RepairMethod::linework) {
  prep::BuildSpec s = prep::test::one_layer("cases", source, kind);
  s.crs = "EPSG:32632";
  s.resolution = resolution;
  s.extent = extent;
  s.model.threads = threads;
  s.repair = repair;
  return prep::test::dry_run(s);
}

TEST(Clean, EveryBrokenPolygonEndsValidWithMakeValidsAreaOrIsDroppedWithAReason) {
  TempDir dir;
  const std::vector<Case> cs = cases();
  prep::test::write_text(dir.file("cases.geojson"), collection(cs));
  prep::SceneFeatures sf = run(dir.file("cases.geojson"), prep::DecalKind::polygon);
  Geos geos;

  std::map<int64_t, std::vector<const prep::ScenePolygon*>> by_fid;
  for (const auto& p : sf.polygons) by_fid[p.fid].push_back(&p);
  std::map<int64_t, std::string> dropped;
  for (const auto& e : sf.manifest.entries)
    if (e.action == prep::ManifestAction::dropped) dropped[e.fid] = e.reason;

  for (const Case& c : cs) {
    SCOPED_TRACE(c.name);
    const double oracle = prep::test::make_valid_area(geos.h, c.wkt);
    if (by_fid.count(c.fid) == 0) {
      ASSERT_TRUE(dropped.count(c.fid)) << "neither kept nor dropped";
      EXPECT_FALSE(dropped[c.fid].empty());
      EXPECT_EQ(oracle, 0.0) << "dropped a polygon with area";
      continue;
    }
    double area = 0;
    for (const prep::ScenePolygon* p : by_fid[c.fid]) {
      EXPECT_TRUE(prep::test::is_valid(geos.h, *p));
      EXPECT_GT(prep::test::ring_area(p->shell), 0) << "shell not counter-clockwise";
      for (const auto& h : p->holes) EXPECT_LT(prep::test::ring_area(h), 0) << "hole not clockwise";
      for (size_t i = 0; i < p->shell.size(); ++i) {
        const auto& a = p->shell[i];
        const auto& b = p->shell[(i + 1) % p->shell.size()];
        EXPECT_FALSE(a.x == b.x && a.y == b.y) << "zero-length segment";
      }
      area += prep::test::polygon_area(*p);
    }
    EXPECT_NEAR(area, oracle, 1e-9 * oracle);
  }
  // The specific outcomes the cases are about.
  EXPECT_EQ(by_fid[1].size(), 2u);  // bow-tie: two triangles
  ASSERT_EQ(by_fid[3].size(), 1u);
  EXPECT_EQ(by_fid[3][0]->shell.size(), 4u);  // duplicates removed
  ASSERT_EQ(by_fid[5].size(), 1u);
  EXPECT_EQ(by_fid[5][0]->holes.size(), 1u);  // touching hole kept, attached
  ASSERT_EQ(by_fid[8].size(), 2u);            // outer-with-hole + island
  ASSERT_EQ(by_fid[9].size(), 2u);
  for (int fid : {8, 9}) {
    size_t with_hole = 0;
    for (const auto* p : by_fid[fid]) with_hole += p->holes.size();
    EXPECT_EQ(with_hole, 1u) << fid;
  }
  EXPECT_TRUE(dropped.count(10));
  EXPECT_TRUE(dropped.count(11));
  EXPECT_NE(dropped[11].find("zero area"), std::string::npos) << dropped[11];
  ASSERT_EQ(by_fid[12].size(), 1u);
  EXPECT_EQ(by_fid[12][0]->holes.size(), 1u);

  // Accounting and repair records.
  ASSERT_EQ(sf.manifest.layers.size(), 1u);
  const prep::LayerCounts& n = sf.manifest.layers[0];
  EXPECT_EQ(n.read, cs.size());
  EXPECT_EQ(n.read, n.kept + n.clipped_away + n.dropped);
  EXPECT_EQ(n.dropped, 2u);
  std::map<int64_t, const prep::ManifestEntry*> repaired;
  for (const auto& e : sf.manifest.entries)
    if (e.action == prep::ManifestAction::repaired) repaired[e.fid] = &e;
  for (int fid : {1, 2, 3, 4, 6, 7, 8}) EXPECT_TRUE(repaired.count(fid)) << fid;
  EXPECT_FALSE(repaired.count(9));
  // The outside hole becomes its own area: the repair changed the area, so
  // before/after are recorded.
  ASSERT_TRUE(repaired.count(7));
  EXPECT_NEAR(repaired[7]->area_before, 10000 - 2500, 1e-6);
  EXPECT_NEAR(repaired[7]->area_after, prep::test::make_valid_area(geos.h, cs[6].wkt), 1e-6);
}

// repair = "structure": the same cases plus overlapping holes and a hole
// crossing the shell, each against GEOS MakeValid's structure method. Where
// the two methods differ (a hole along the shell's edge, overlapping holes),
// structure subtracts every hole: the covered area is shell minus holes.
TEST(Clean, StructureRepairMatchesGeosStructureMethodAndSubtractsEveryHole) {
  TempDir dir;
  std::vector<Case> cs = cases();
  const Pts square = {{0, 0}, {100, 0}, {100, 100}, {0, 100}, {0, 0}};
  cs.push_back(polygon_case(13, "overlapping holes",
                            {square,
                             {{10, 10}, {10, 60}, {60, 60}, {60, 10}, {10, 10}},
                             {{40, 40}, {40, 90}, {90, 90}, {90, 40}, {40, 40}}}));
  cs.push_back(polygon_case(14, "hole crossing the shell",
                            {square, {{60, 20}, {60, 80}, {140, 80}, {140, 20}, {60, 20}}}));
  prep::test::write_text(dir.file("cases.geojson"), collection(cs));
  prep::SceneFeatures sf = run(dir.file("cases.geojson"), prep::DecalKind::polygon, 0, std::nullopt,
                               0, prep::RepairMethod::structure);
  Geos geos;
  std::map<int64_t, double> area;
  for (const auto& p : sf.polygons) {
    EXPECT_TRUE(prep::test::is_valid(geos.h, p)) << p.fid;
    area[p.fid] += prep::test::polygon_area(p);
  }
  for (const Case& c : cs) {
    SCOPED_TRACE(c.name);
    const double oracle = prep::test::make_valid_area(geos.h, c.wkt, /*structure=*/true);
    if (oracle == 0) {
      EXPECT_EQ(area.count(c.fid), 0u);
      continue;
    }
    EXPECT_NEAR(area[c.fid], oracle, 1e-9 * oracle);
  }
  // Shell minus holes, analytically: 10000 - 2500 - 2500 + 400 (the overlap
  // counted once); 10000 - 40 x 40 for the hole along an edge; 10000 - 40 x 60
  // for the crossing hole.
  EXPECT_NEAR(area[13], 10000 - 2500 - 2500 + 400, 1e-6);
  EXPECT_NEAR(area[6], 10000 - 40 * 40, 1e-6);
  EXPECT_NEAR(area[14], 10000 - 40 * 60, 1e-6);
  bool named = false;
  for (const auto& e : sf.manifest.entries)
    if (e.fid == 13 && e.action == prep::ManifestAction::repaired)
      named = e.reason.find("structure method") != std::string::npos;
  EXPECT_TRUE(named) << "the manifest names the repair method";
}

TEST(Clean, ClipKeepsTheInsideAndRecordsFeaturesEntirelyOutside) {
  TempDir dir;
  std::vector<Case> cs = {
      polygon_case(1, "crossing", {{{0, 0}, {100, 0}, {100, 100}, {0, 100}, {0, 0}}}),
      polygon_case(2, "outside", {{{1000, 0}, {1100, 0}, {1100, 100}, {1000, 100}, {1000, 0}}}),
      polygon_case(3, "inside", {{{10, 10}, {20, 10}, {20, 20}, {10, 20}, {10, 10}}})};
  prep::test::write_text(dir.file("clip.geojson"), collection(cs));
  // Extent in the frame CRS (absolute UTM coordinates): x < kX0 + 50.
  prep::Extent e{kX0 - 500, kY0 - 500, kX0 + 50, kY0 + 500};
  prep::SceneFeatures sf = run(dir.file("clip.geojson"), prep::DecalKind::polygon, 0, e);
  Geos geos;
  ASSERT_EQ(sf.polygons.size(), 2u);
  EXPECT_NEAR(prep::test::polygon_area(sf.polygons[0]), 5000.0, 1e-6);
  EXPECT_NEAR(prep::test::polygon_area(sf.polygons[1]), 100.0, 1e-9);
  const prep::LayerCounts& n = sf.manifest.layers[0];
  EXPECT_EQ(n.kept, 2u);
  EXPECT_EQ(n.clipped_away, 1u);
  EXPECT_TRUE(prep::test::has_entry(sf.manifest, 2, prep::ManifestAction::clipped_away));
}

TEST(Clean, LinesLoseDuplicatesAreClippedIntoPiecesAndDegenerateOnesAreDropped) {
  TempDir dir;
  const std::string fc =
      std::string(
          R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},"features":[)") +
      R"({"type":"Feature","id":1,"properties":{},"geometry":{"type":"LineString","coordinates":)" +
      ring_json({{0, 0}, {0, 0}, {10, 0}, {10, 0}, {20, 0}}) + "}}," +
      R"({"type":"Feature","id":2,"properties":{},"geometry":{"type":"LineString","coordinates":)" +
      ring_json({{5, 5}, {5, 5}}) + "}}," +
      // A U that leaves the extent and comes back: two pieces.
      R"({"type":"Feature","id":3,"properties":{},"geometry":{"type":"LineString","coordinates":)" +
      ring_json({{0, 50}, {100, 50}, {100, 60}, {0, 60}}) + "}}]}";
  prep::test::write_text(dir.file("lines.geojson"), fc);
  prep::Extent e{kX0 - 500, kY0 - 500, kX0 + 50, kY0 + 500};
  prep::SceneFeatures sf = run(dir.file("lines.geojson"), prep::DecalKind::line, 0, e);
  std::map<int64_t, std::vector<const prep::SceneLine*>> by_fid;
  for (const auto& l : sf.lines) by_fid[l.fid].push_back(&l);
  ASSERT_EQ(by_fid[1].size(), 1u);
  EXPECT_EQ(by_fid[1][0]->points.size(), 3u);
  EXPECT_EQ(by_fid.count(2), 0u);
  ASSERT_EQ(by_fid[3].size(), 2u);
  // Lengths are ground metres: UTM's scale on its central meridian is 0.9996.
  EXPECT_NEAR(by_fid[3][0]->length + by_fid[3][1]->length, 100.0 / kUtmK0, 1e-6);
  const prep::LayerCounts& n = sf.manifest.layers[0];
  EXPECT_EQ(n.read, 3u);
  EXPECT_EQ(n.kept, 2u);
  EXPECT_EQ(n.dropped, 1u);
}

TEST(Clean, OutlinesAreClosedRingsWithShellCounterClockwiseAndHolesClockwise) {
  TempDir dir;
  std::vector<Case> cs = {polygon_case(1, "cw shell",
                                       {{{0, 0}, {0, 100}, {100, 100}, {100, 0}, {0, 0}},
                                        {{20, 20}, {80, 20}, {80, 80}, {20, 80}, {20, 20}}})};
  prep::test::write_text(dir.file("o.geojson"), collection(cs));
  prep::SceneFeatures sf = run(dir.file("o.geojson"), prep::DecalKind::outline);
  ASSERT_EQ(sf.lines.size(), 2u);
  EXPECT_TRUE(sf.lines[0].closed);
  EXPECT_GT(prep::test::ring_area(sf.lines[0].points), 0);
  EXPECT_LT(prep::test::ring_area(sf.lines[1].points), 0);
  EXPECT_NEAR(sf.lines[0].length, 400.0 / kUtmK0, 1e-6);
  EXPECT_NEAR(sf.lines[0].width, 2.0 * kUtmK0, 1e-9);  // default 2 ground metres
  EXPECT_EQ(sf.manifest.layers[0].parts, 2u);
}

TEST(Clean, SimplificationStaysWithinTheResolutionAndValid) {
  TempDir dir;
  // A wiggly polygon: 400 vertices on a circle with 0.2 m noise.
  Pts ring;
  for (int i = 0; i < 400; ++i) {
    const double a = 2 * M_PI * i / 400, r = 100 + 0.2 * std::sin(37.0 * i);
    ring.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  ring.push_back(ring.front());
  std::vector<Case> cs = {polygon_case(1, "wiggly", {ring})};
  prep::test::write_text(dir.file("w.geojson"), collection(cs));
  Geos geos;
  prep::SceneFeatures full = run(dir.file("w.geojson"), prep::DecalKind::polygon, 0);
  prep::SceneFeatures simple = run(dir.file("w.geojson"), prep::DecalKind::polygon, 0.5);
  ASSERT_EQ(simple.polygons.size(), 1u);
  EXPECT_TRUE(prep::test::is_valid(geos.h, simple.polygons[0]));
  EXPECT_LT(simple.polygons[0].shell.size(), full.polygons[0].shell.size());
  EXPECT_EQ(simple.manifest.layers[0].vertices_in, 401u);
  EXPECT_EQ(simple.manifest.layers[0].vertices_out, simple.polygons[0].shell.size() + 1);
  const prep::test::G a = prep::test::polygon(geos.h, full.polygons[0]);
  const prep::test::G b = prep::test::polygon(geos.h, simple.polygons[0]);
  double d = 0;
  GEOSHausdorffDistanceDensify_r(geos.h, a.g, b.g, 0.01, &d);
  EXPECT_LE(d, 0.5 + 1e-9);
  EXPECT_GT(d, 0.0);
}

TEST(Clean, OutputDoesNotDependOnTheThreadCount) {
  TempDir dir;
  std::vector<Case> cs;
  for (int i = 0; i < 300; ++i) {
    const int row = i / 20;
    const double x = 200.0 * (i % 20), y = 200.0 * row;
    cs.push_back(polygon_case(i + 1, "sq",
                              {{{x, y}, {x + 100, y + 100}, {x + 100, y}, {x, y + 100}, {x, y}}}));
  }
  prep::test::write_text(dir.file("many.geojson"), collection(cs));
  prep::SceneFeatures one =
      run(dir.file("many.geojson"), prep::DecalKind::polygon, 0.1, std::nullopt, 1);
  prep::SceneFeatures two =
      run(dir.file("many.geojson"), prep::DecalKind::polygon, 0.1, std::nullopt, 2);
  ASSERT_EQ(one.polygons.size(), two.polygons.size());
  for (size_t i = 0; i < one.polygons.size(); ++i) {
    EXPECT_EQ(one.polygons[i].fid, two.polygons[i].fid);
    ASSERT_EQ(one.polygons[i].shell.size(), two.polygons[i].shell.size());
    for (size_t k = 0; k < one.polygons[i].shell.size(); ++k) {
      EXPECT_EQ(one.polygons[i].shell[k].x, two.polygons[i].shell[k].x);
      EXPECT_EQ(one.polygons[i].shell[k].y, two.polygons[i].shell[k].y);
    }
  }
  ASSERT_EQ(one.manifest.entries.size(), two.manifest.entries.size());
  for (size_t i = 0; i < one.manifest.entries.size(); ++i)
    EXPECT_EQ(one.manifest.entries[i].fid, two.manifest.entries[i].fid);
}

}  // namespace

namespace {

// A 1-band GeoTIFF in EPSG:32632 covering x in [kX0 - 100, kX0 + 50],
// y in [kY0 - 100, kY0 + 200], written with GDAL.
std::string write_dem(const TempDir& dir) {
  GDALAllRegister();
  const std::string path = dir.file("dem.tif");
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  std::unique_ptr<GDALDataset> ds(drv->Create(path.c_str(), 15, 30, 1, GDT_Float32, nullptr));
  double gt[6] = {kX0 - 100, 10, 0, kY0 + 200, 0, -10};
  ds->SetGeoTransform(gt);
  OGRSpatialReference srs;
  srs.importFromEPSG(32632);
  ds->SetSpatialRef(&srs);
  std::vector<float> z(15 * 30, 100.0f);
  if (ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 15, 30, z.data(), 15, 30, GDT_Float32, 0, 0) !=
      CE_None)
    throw std::runtime_error("RasterIO failed");
  return path;
}

TEST(Clean, WithADemTheSceneIsClippedToTheDemExtent) {
  TempDir dir;
  std::vector<Case> cs = {
      polygon_case(1, "crossing the DEM edge", {{{0, 0}, {100, 0}, {100, 100}, {0, 100}, {0, 0}}}),
      polygon_case(2, "beyond the DEM",
                   {{{1000, 0}, {1100, 0}, {1100, 100}, {1000, 100}, {1000, 0}}})};
  prep::test::write_text(dir.file("d.geojson"), collection(cs));
  prep::BuildSpec s = prep::test::one_layer("d", dir.file("d.geojson"));
  s.crs = "EPSG:32632";
  s.dem = write_dem(dir);
  prep::SceneFeatures sf = prep::test::dry_run(s);
  ASSERT_EQ(sf.polygons.size(), 1u);
  EXPECT_NEAR(prep::test::polygon_area(sf.polygons[0]), 50.0 * 100.0, 1e-6);
  EXPECT_EQ(sf.manifest.layers[0].clipped_away, 1u);

  s.dem = dir.file("missing.tif");
  try {
    prep::test::dry_run(s);
    FAIL() << "missing DEM accepted";
  } catch (const prep::error& e) {
    EXPECT_NE(std::string(e.what()).find("missing.tif"), std::string::npos) << e.what();
  }
}

TEST(Clean, ExtentGivenInLonLatIsTransformedIntoTheFrame) {
  TempDir dir;
  std::vector<Case> cs = {
      polygon_case(1, "near the origin", {{{0, 0}, {100, 0}, {100, 100}, {0, 100}, {0, 0}}}),
      polygon_case(2, "50 km east",
                   {{{50000, 0}, {50100, 0}, {50100, 100}, {50000, 100}, {50000, 0}}})};
  prep::test::write_text(dir.file("e.geojson"), collection(cs));
  // Zone 32's central meridian is 9°E; (500000, 4800000) is near 43.35°N.
  prep::BuildSpec s = prep::test::one_layer("e", dir.file("e.geojson"));
  s.crs = "EPSG:32632";
  s.extent = prep::Extent{8.9, 43.0, 9.1, 43.7};
  s.extent_crs = "EPSG:4326";
  prep::SceneFeatures sf = prep::test::dry_run(s);
  ASSERT_EQ(sf.polygons.size(), 1u);
  EXPECT_EQ(sf.polygons[0].fid, 1);
  EXPECT_EQ(sf.manifest.layers[0].clipped_away, 1u);
}

// clean proves plainly valid parts valid itself and skips GEOS for them
// (clean.cpp, certainly_valid); GEOS's isValid on the original geometry is
// the oracle. Random rings, half of them snapped to a 1 m grid so that
// vertices touch, edges overlap and points fall on edges exactly: every
// polygon GEOS calls invalid must be repaired ("made valid") or dropped;
// every valid one must come through untouched with GEOS's area.
TEST(Clean, ValidityShortcutAgreesWithGeosOnRandomPolygons) {
  TempDir dir;
  prep::test::Rng rng(7);
  auto next = [&] { return rng.uniform(); };
  std::vector<Case> cs;
  for (int k = 0; k < 400; ++k) {
    const bool snap = k % 2 == 0;
    const int row = k / 20;
    const double cx = 300.0 * (k % 20), cy = 300.0 * row, radius = 20 + 80 * next();
    auto make_ring = [&](double x0, double y0, double r, int n, bool reverse, double jitter) {
      Pts pts;
      for (int i = 0; i < n; ++i) {
        const double a = 2 * M_PI * (i + jitter * (next() - 0.5)) / n;
        const double rr = r * (0.5 + 0.5 * next());
        double x = x0 + rr * std::cos(a), y = y0 + rr * std::sin(a);
        if (snap) x = std::round(x), y = std::round(y);
        pts.push_back({x, y});
      }
      if (reverse) std::reverse(pts.begin(), pts.end());
      pts.push_back(pts.front());
      return pts;
    };
    // Jitter above 1 lets neighbouring vertices swap angles: self-crossings.
    std::vector<Pts> rings = {
        make_ring(cx, cy, radius, 4 + k % 29, k % 3 == 0, k % 4 == 0 ? 3.0 : 0.9)};
    for (int h = 0; h < k % 4; ++h) {
      // Holes near the centre (mostly inside), sometimes large (crossing).
      const double hr = radius * (h == 2 ? 0.9 : 0.2);
      rings.push_back(make_ring(cx + radius * 0.3 * (next() - 0.5),
                                cy + radius * 0.3 * (next() - 0.5), hr, 4 + k % 7, k % 5 != 0,
                                0.5));
    }
    cs.push_back(polygon_case(k + 1, "random", rings));
  }
  prep::test::write_text(dir.file("random.geojson"), collection(cs));
  const prep::SceneFeatures sf = run(dir.file("random.geojson"), prep::DecalKind::polygon);

  Geos geos;
  GEOSWKTReader* reader = GEOSWKTReader_create_r(geos.h);
  std::map<int64_t, std::string> repaired, dropped;
  for (const auto& e : sf.manifest.entries) {
    if (e.action == prep::ManifestAction::repaired ||
        e.action == prep::ManifestAction::part_dropped)
      repaired[e.fid] += e.reason + ";";
    if (e.action == prep::ManifestAction::dropped) dropped[e.fid] = e.reason;
  }
  std::map<int64_t, double> area;
  std::map<int64_t, int> parts;
  for (const auto& p : sf.polygons) {
    area[p.fid] += p.area;
    ++parts[p.fid];
  }
  int valid_count = 0, invalid_count = 0;
  for (const Case& c : cs) {
    SCOPED_TRACE(c.wkt);
    GEOSGeometry* g = GEOSWKTReader_read_r(geos.h, reader, c.wkt.c_str());
    ASSERT_NE(g, nullptr);
    const bool valid = GEOSisValid_r(geos.h, g) == 1;
    double a = 0;
    GEOSArea_r(geos.h, g, &a);
    GEOSGeom_destroy_r(geos.h, g);
    if (valid) {
      ++valid_count;
      // Snapped rings can repeat a vertex: removing it changes nothing GEOS sees.
      EXPECT_EQ(repaired[c.fid].find("made valid"), std::string::npos) << repaired[c.fid];
      EXPECT_EQ(dropped.count(c.fid), 0u) << dropped[c.fid];
      EXPECT_EQ(parts[c.fid], 1);
      EXPECT_NEAR(area[c.fid], a, 1e-9 * a);
    } else {
      ++invalid_count;
      EXPECT_TRUE(repaired[c.fid].find("made valid") != std::string::npos ||
                  dropped.count(c.fid) > 0)
          << "fid " << c.fid << " is invalid for GEOS but was kept untouched";
    }
  }
  GEOSWKTReader_destroy_r(geos.h, reader);
  // Both kinds must be well represented for the test to mean anything.
  EXPECT_GT(valid_count, 100);
  EXPECT_GT(invalid_count, 50);
}

}  // namespace
