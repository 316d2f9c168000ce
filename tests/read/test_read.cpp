// The read stage on synthetic sources written to a temp dir and read through
// GDAL (STYLE.md: no mock readers).
#include <gtest/gtest.h>

#include <cmath>
#include <mutex>
#include <nlohmann/json.hpp>

#include "fixtures.hpp"
#include "prep/error.hpp"
#include "prep/progress.hpp"
#include "prep/read.hpp"
#include "scene_fixtures.hpp"

namespace {

using prep::test::TempDir;
using prep::test::write_text;

prep::BuildSpec one_layer(const std::string& source, prep::DecalKind kind) {
  return prep::test::one_layer("l", source, kind);
}

const char* kMixed = R"({"type":"FeatureCollection","features":[
 {"type":"Feature","id":1,"properties":{},"geometry":{"type":"MultiPolygon","coordinates":[
   [[[0,0],[1,0],[1,1],[0,1],[0,0]]],
   [[[2,0],[3,0],[3,1],[2,1],[2,0]],[[2.2,0.2],[2.2,0.8],[2.8,0.8],[2.8,0.2],[2.2,0.2]]]]}},
 {"type":"Feature","id":2,"properties":{},"geometry":{"type":"GeometryCollection","geometries":[
   {"type":"Polygon","coordinates":[[[5,5],[6,5],[6,6],[5,5]]]},
   {"type":"Point","coordinates":[9,9]},
   {"type":"MultiPolygon","coordinates":[[[[7,7],[8,7],[8,8],[7,7]]]]}]}},
 {"type":"Feature","id":3,"properties":{},"geometry":{"type":"Point","coordinates":[1,1]}},
 {"type":"Feature","id":4,"properties":{},"geometry":null},
 {"type":"Feature","id":5,"properties":{},"geometry":{"type":"Polygon","coordinates":[[[0,0,10],[1,0,11],[1,1,12],[0,0,10]]]}}
]})";

TEST(Read, MultiGeometriesAndCollectionsAreSplitIntoParts) {
  TempDir dir;
  write_text(dir.file("mixed.geojson"), kMixed);
  prep::BuildSpec s = one_layer(dir.file("mixed.geojson"), prep::DecalKind::polygon);
  prep::FeatureSet fs = prep::read_scene(s);
  ASSERT_EQ(fs.layers.size(), 1u);
  const auto& f = fs.layers[0].features;
  // fid 1: two parts (the second with a hole); fid 2: two polygons (the point
  // part is reported); fid 3 and 4: placeholders with a reason; fid 5: one.
  ASSERT_EQ(f.size(), 7u);
  EXPECT_EQ(f[0].fid, 1);
  EXPECT_EQ(f[1].fid, 1);
  EXPECT_EQ(f[1].part, 1);
  EXPECT_EQ(f[1].rings.size(), 2u);
  EXPECT_EQ(f[1].rings[0].size(), 4u);  // closing point not repeated
  EXPECT_EQ(f[2].fid, 2);
  EXPECT_EQ(f[3].fid, 2);
  EXPECT_EQ(f[3].rings[0][0].x, 7.0);
  EXPECT_EQ(f[4].fid, 3);
  EXPECT_NE(f[4].drop_reason.find("Point"), std::string::npos) << f[4].drop_reason;
  EXPECT_EQ(f[5].fid, 4);
  EXPECT_EQ(f[5].drop_reason, "no geometry");
  EXPECT_EQ(f[6].fid, 5);
  EXPECT_EQ(fs.manifest.layers[0].read, 5u);
  EXPECT_TRUE(prep::test::has_entry(fs.manifest, 2, prep::ManifestAction::part_dropped));
}

TEST(Read, ZValuesAreDroppedAndTheManifestSaysSo) {
  TempDir dir;
  write_text(dir.file("mixed.geojson"), kMixed);
  prep::FeatureSet fs =
      prep::read_scene(one_layer(dir.file("mixed.geojson"), prep::DecalKind::polygon));
  EXPECT_TRUE(prep::test::has_note(fs.manifest, "Z/M values dropped from 1 features"));
}

TEST(Read, PolygonsInALineLayerBecomeClosedLines) {
  TempDir dir;
  write_text(dir.file("mixed.geojson"), kMixed);
  prep::FeatureSet fs =
      prep::read_scene(one_layer(dir.file("mixed.geojson"), prep::DecalKind::line));
  const auto& f = fs.layers[0].features;
  ASSERT_FALSE(f.empty());
  EXPECT_FALSE(f[0].is_polygon);
  ASSERT_EQ(f[0].rings.size(), 1u);
  EXPECT_EQ(f[0].rings[0].size(), 5u);  // closed line keeps its end point
}

TEST(Read, NanCoordinateFailsWithTheFeatureId) {
  TempDir dir;
  // GDAL's GeoJSON reader accepts NaN tokens (a shapefile writer refuses them).
  write_text(dir.file("nan.geojson"), R"({"type":"FeatureCollection","features":[
 {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[1,1],[2,2]]}},
 {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[1,1],[2,3]]}},
 {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[1,1],[NaN,2]]}}]})");
  prep::BuildSpec s = one_layer(dir.file("nan.geojson"), prep::DecalKind::line);
  try {
    prep::read_scene(s);
    FAIL() << "NaN accepted";
  } catch (const prep::input_error& e) {
    std::string m = e.what();
    EXPECT_NE(m.find("fid 2"), std::string::npos) << m;
    EXPECT_NE(m.find("nan.geojson"), std::string::npos) << m;
    EXPECT_NE(m.find("non-finite"), std::string::npos) << m;
  }
  // With skip_failures the feature is dropped with its reason instead.
  s.skip_failures = true;
  prep::FeatureSet fs = prep::read_scene(s);
  ASSERT_EQ(fs.layers[0].features.size(), 3u);
  EXPECT_NE(fs.layers[0].features[2].drop_reason.find("non-finite"), std::string::npos);
}

TEST(Read, OverpassOsmWithNonIncreasingIdsIsReadWithPlainIndexing) {
  TempDir dir;
  write_text(dir.file("overpass.osm"), R"(<?xml version="1.0" encoding="UTF-8"?>
<osm version="0.6" generator="Overpass API">
  <node id="30" lat="43.7300" lon="7.4200"/>
  <node id="20" lat="43.7310" lon="7.4210"/>
  <node id="10" lat="43.7320" lon="7.4200"/>
  <node id="5" lat="43.7330" lon="7.4230"/>
  <way id="100"><nd ref="30"/><nd ref="20"/><nd ref="10"/><nd ref="5"/>
    <tag k="highway" v="residential"/></way>
</osm>
)");
  prep::BuildSpec s = one_layer(dir.file("overpass.osm"), prep::DecalKind::line);
  s.layers[0].layer = "lines";
  prep::FeatureSet fs = prep::read_scene(s);
  ASSERT_EQ(fs.layers[0].features.size(), 1u);
  EXPECT_EQ(fs.layers[0].features[0].rings[0].size(), 4u);
  EXPECT_EQ(fs.layers[0].features[0].fid, 100);
  EXPECT_TRUE(prep::test::has_note(fs.manifest, "OSM_USE_CUSTOM_INDEXING=NO"));
}

TEST(Read, OrderAndColourAttributesAreReadAsNumbers) {
  TempDir dir;
  write_text(dir.file("a.geojson"), R"({"type":"FeatureCollection","features":[
 {"type":"Feature","properties":{"rank":7,"temp":"2.5"},"geometry":{"type":"LineString","coordinates":[[0,0],[1,1]]}},
 {"type":"Feature","properties":{"rank":null,"temp":"1"},"geometry":{"type":"LineString","coordinates":[[0,0],[1,2]]}}]})");
  prep::BuildSpec s = one_layer(dir.file("a.geojson"), prep::DecalKind::line);
  s.layers[0].style.order_attribute = "rank";
  s.layers[0].style.color.attribute = "temp";
  prep::FeatureSet fs = prep::read_scene(s);
  ASSERT_EQ(fs.layers[0].features.size(), 2u);
  EXPECT_EQ(fs.layers[0].features[0].order_value, 7.0);
  EXPECT_EQ(fs.layers[0].features[0].color_value, 2.5);
  EXPECT_TRUE(std::isnan(fs.layers[0].features[1].order_value));
  s.layers[0].style.order_attribute = "rnak";
  try {
    prep::read_scene(s);
    FAIL() << "unknown attribute accepted";
  } catch (const prep::input_error& e) {
    EXPECT_NE(std::string(e.what()).find("'rnak' not found"), std::string::npos) << e.what();
  }
}

TEST(Read, CountsEveryFeatureReadIntoTheProgressStage) {
  // kMixed has 5 features (ogrinfo -so: Feature Count: 5). The stage counts
  // features taken by scene layers, as the manifest's `read` does: the layer
  // and a copy of it (same query: one read of the file serves both, 5
  // features each) and, read concurrently, the layer with a filter that
  // keeps every feature (5 more): done == total == 15.
  TempDir dir;
  write_text(dir.file("mixed.geojson"), kMixed);
  prep::BuildSpec s = one_layer(dir.file("mixed.geojson"), prep::DecalKind::polygon);
  s.layers.push_back(s.layers[0]);
  s.layers[1].name = "again";
  s.layers.push_back(s.layers[0]);
  s.layers[2].name = "filtered";
  s.layers[2].where = "1 = 1";
  std::vector<std::string> lines;
  std::mutex mu;
  prep::ProgressOptions po;
  po.mode = prep::ProgressMode::json;
  po.write = [&](std::string_view line) {
    std::lock_guard<std::mutex> lock(mu);
    lines.emplace_back(line);
  };
  {
    prep::Progress progress(po);
    prep::ReadOptions ro;
    ro.progress = &progress;
    prep::read_scene(s, ro);
  }
  ASSERT_FALSE(lines.empty());
  const nlohmann::json end = nlohmann::json::parse(lines.back());
  EXPECT_EQ(end["event"], "end") << lines.back();
  EXPECT_EQ(end["stage"], "read");
  EXPECT_EQ(end["done"], 15);
  EXPECT_EQ(end["total"], 15);
}

}  // namespace

#include <cpl_vsi.h>

#include "prep/pipeline.hpp"

namespace {

TEST(Read, SceneFileWithRelativeVsizipSourceReadsFromTheArchiveNextToIt) {
  prep::test::TempDir dir;
  // GDAL writes the archive itself (/vsizip/ supports creation).
  const std::string inner = "/vsizip/" + dir.file("data.zip") + "/roads.geojson";
  const std::string json = R"({"type":"FeatureCollection","features":[
 {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[7.42,43.73],[7.43,43.74]]}},
 {"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[7.43,43.73],[7.44,43.74]]}}]})";
  VSILFILE* f = VSIFOpenL(inner.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  ASSERT_EQ(VSIFWriteL(json.data(), 1, json.size(), f), json.size());
  VSIFCloseL(f);
  prep::test::write_text(
      dir.file("scene.toml"),
      "[[layer]]\nname = \"roads\"\nsource = \"/vsizip/data.zip/roads.geojson\"\n"
      "kind = \"line\"\nwidth = 4\n");
  prep::BuildSpec s = prep::load_scene_file(dir.file("scene.toml"));
  prep::BuildRequest req;
  req.dry_run = true;
  prep::BuildResult r = prep::run_build(s, req);
  ASSERT_EQ(r.scene.lines.size(), 2u);
  EXPECT_EQ(r.scene.manifest.layers[0].read, 2u);
}

}  // namespace
