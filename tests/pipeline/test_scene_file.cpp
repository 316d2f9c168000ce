// Scene file parsing: keys, defaults, path resolution, and errors that name
// the key and the line.
#include <gtest/gtest.h>

#include "prep/error.hpp"
#include "prep/pipeline.hpp"

namespace {

std::string error_of(const std::string& text) {
  try {
    prep::parse_scene(text, "/data/city/scene.toml");
  } catch (const prep::scene_error& e) {
    return e.what();
  }
  return "";
}

TEST(SceneFile, ParsesLayersStylesAndSceneKeys) {
  const char* text = R"(
source = "city.gpkg"
crs = "EPSG:32632"
resolution = 0.5
extent = [1.0, 2.0, 3.0, 4.0]
extent_crs = "EPSG:4326"
dem = "/vsizip/dem.zip/dem.tif"
[build]
grid = [500, 400]
leaf_capacity = 4
max_depth = 6
threads = 2
[[layer]]
name = "roads"
layer = "roads"
where = "class = 'A'"
kind = "line"
width = 4.5
corner = "miter"
color = "#ff000080"
[[layer]]
name = "parks"
sql = "SELECT * FROM parks"
source = "/abs/parks.shp"
kind = "outline"
corner = "miter"
outline_mode = "inset"
color_attribute = "age"
color_ramp = [[0, "#000000"], [10, "#ffffff"]]
order_attribute = "rank"
[[layer]]
name = "hw"
kind = "line"
dynamic = true
)";
  prep::BuildSpec s = prep::parse_scene(text, "/data/city/scene.toml");
  ASSERT_EQ(s.layers.size(), 3u);
  EXPECT_EQ(s.crs, "EPSG:32632");
  EXPECT_DOUBLE_EQ(s.resolution, 0.5);
  ASSERT_TRUE(s.extent.has_value());
  EXPECT_DOUBLE_EQ(s.extent->xmax, 3.0);
  EXPECT_EQ(s.dem, "/vsizip//data/city/dem.zip/dem.tif");
  EXPECT_EQ(s.model.grid_nx, 500u);
  EXPECT_EQ(s.model.grid_ny, 400u);
  EXPECT_EQ(s.model.qt_leaf_capacity, 4u);
  EXPECT_EQ(s.model.qt_max_depth, 6u);
  EXPECT_EQ(s.model.threads, 2u);
  const prep::LayerSpec& roads = s.layers[0];
  EXPECT_EQ(roads.source, "/data/city/city.gpkg");
  EXPECT_EQ(roads.kind, prep::DecalKind::line);
  EXPECT_EQ(roads.style.corner, decal::CornerStyle::miter);
  EXPECT_EQ(roads.style.color.rgba, 0x800000ffu);
  EXPECT_DOUBLE_EQ(roads.style.width, 4.5);
  EXPECT_EQ(roads.scene_line, 13);
  const prep::LayerSpec& parks = s.layers[1];
  EXPECT_EQ(parks.source, "/abs/parks.shp");
  EXPECT_EQ(parks.style.outline, decal::OutlineMode::inset);
  ASSERT_EQ(parks.style.color.ramp.size(), 2u);
  EXPECT_EQ(parks.style.color.ramp[1].rgba, 0xffffffffu);
  EXPECT_EQ(parks.style.order_attribute, "rank");
  EXPECT_TRUE(s.layers[2].dynamic);
  EXPECT_DOUBLE_EQ(s.layers[2].style.width, 3.0);  // pixels by default
}

TEST(SceneFile, RelativePathsResolveAgainstTheSceneDirectoryAlsoInsideVsizip) {
  EXPECT_EQ(prep::resolve_scene_path("a.pbf", "/d"), "/d/a.pbf");
  EXPECT_EQ(prep::resolve_scene_path("sub/a.pbf", "/d"), "/d/sub/a.pbf");
  EXPECT_EQ(prep::resolve_scene_path("/abs/a.pbf", "/d"), "/abs/a.pbf");
  EXPECT_EQ(prep::resolve_scene_path("/vsizip/x.zip/y.hgt", "/d"), "/vsizip//d/x.zip/y.hgt");
  EXPECT_EQ(prep::resolve_scene_path("/vsizip//abs/x.zip/y", "/d"), "/vsizip//abs/x.zip/y");
  EXPECT_EQ(prep::resolve_scene_path("/vsicurl/https://h/x.tif", "/d"), "/vsicurl/https://h/x.tif");
  EXPECT_EQ(prep::resolve_scene_path("https://h/x.json", "/d"), "https://h/x.json");
}

TEST(SceneFile, UnknownKeyIsAnErrorNamingKeyAndLine) {
  std::string e = error_of("[[layer]]\nsource = \"a.shp\"\nwidht = 3\n");
  EXPECT_NE(e.find("scene.toml:3"), std::string::npos) << e;
  EXPECT_NE(e.find("layer[0].widht"), std::string::npos) << e;
}

// Six problems on six lines, written so that toml++'s alphabetical key
// order differs from the file's: one run reports them all, each with its
// line, in line order, the two misspelt keys with the key they meant.
TEST(SceneFile, EveryProblemIsReportedInOneRunInLineOrderWithDidYouMean) {
  const std::string e = error_of(
      "resolution = \"fine\"\n"  // 1: wrong type
      "[build]\n"
      "max_cels = 10\n"  // 3: misspelt (max_cells)
      "[[layer]]\n"
      "source = \"a.shp\"\n"
      "widht = 3\n"            // 6: misspelt (width)
      "kind = \"poly\"\n"      // 7: bad enum value
      "color = \"#12345\"\n"   // 8: bad colour
      "frobnicate = true\n");  // 9: unknown, nothing near
  EXPECT_NE(e.find("scene.toml: 6 problems:"), std::string::npos) << e;
  const char* in_order[] = {
      "scene.toml:1: resolution: expected a number",
      "scene.toml:3: build.max_cels: unknown key; did you mean \"max_cells\"?",
      "scene.toml:6: layer[0].widht: unknown key; did you mean \"width\"?",
      "scene.toml:7: layer[0].kind",
      "scene.toml:8: layer[0].color",
      "scene.toml:9: layer[0].frobnicate: unknown key (see"};
  size_t at = 0;
  for (const char* want : in_order) {
    const size_t found = e.find(want, at);
    ASSERT_NE(found, std::string::npos) << "missing or out of order: " << want << "\n" << e;
    at = found;
  }
  EXPECT_EQ(e.find("did you mean", e.find("frobnicate")), std::string::npos) << e;
}

TEST(SceneFile, WrongTypeIsAnErrorNamingKeyAndLine) {
  std::string e = error_of("resolution = \"fine\"\n[[layer]]\nsource = \"a.shp\"\n");
  EXPECT_NE(e.find("scene.toml:1: resolution"), std::string::npos) << e;
  EXPECT_NE(e.find("expected a number"), std::string::npos) << e;
}

// dem = [...]: a mosaic, each path resolved like a single dem; the first in
// `dem`, the rest in `dem_more`. A single string leaves dem_more empty.
TEST(SceneFile, DemListResolvesEachPathAgainstTheSceneDirectory) {
  const prep::BuildSpec s = prep::parse_scene(
      "dem = [\"a.hgt\", \"/abs/b.hgt\", \"/vsizip/c.zip/c.hgt\"]\n[[layer]]\nsource = "
      "\"a.shp\"\n",
      "/data/city/scene.toml");
  EXPECT_EQ(s.dem, "/data/city/a.hgt");
  EXPECT_EQ(s.dem_more, (std::vector<std::string>{"/abs/b.hgt", "/vsizip//data/city/c.zip/c.hgt"}));
  EXPECT_EQ(prep::dem_paths(s).size(), 3u);
  const prep::BuildSpec one =
      prep::parse_scene("dem = \"a.hgt\"\n[[layer]]\nsource = \"a.shp\"\n", "/d/scene.toml");
  EXPECT_EQ(one.dem, "/d/a.hgt");
  EXPECT_TRUE(one.dem_more.empty());
}

TEST(SceneFile, DemListElementThatIsNotAStringNamesItsLine) {
  std::string e = error_of("dem = [\n  \"a.hgt\",\n  3,\n]\n[[layer]]\nsource = \"a.shp\"\n");
  EXPECT_NE(e.find("scene.toml:3: dem[1]: expected a string, got integer"), std::string::npos) << e;
  e = error_of("dem = []\n[[layer]]\nsource = \"a.shp\"\n");
  EXPECT_NE(e.find("scene.toml:1: dem: expected at least one DEM path"), std::string::npos) << e;
  e = error_of("dem = 4\n[[layer]]\nsource = \"a.shp\"\n");
  EXPECT_NE(e.find("scene.toml:1: dem: expected a string or an array of strings, got integer"),
            std::string::npos)
      << e;
}

TEST(SceneFile, BadEnumValueNamesTheAcceptedValues) {
  std::string e = error_of("[[layer]]\nsource = \"a.shp\"\n\nkind = \"poly\"\n");
  EXPECT_NE(e.find("scene.toml:4: layer[0].kind"), std::string::npos) << e;
  EXPECT_NE(e.find("polygon|line|outline"), std::string::npos) << e;
}

TEST(SceneFile, BadColourNamesKeyAndLine) {
  std::string e = error_of("[[layer]]\nsource = \"a.shp\"\ncolor = \"red\"\n");
  EXPECT_NE(e.find("scene.toml:3: layer[0].color"), std::string::npos) << e;
}

TEST(SceneFile, TomlSyntaxErrorNamesTheLine) {
  std::string e = error_of("[[layer]]\nsource = \"a.shp\"\nwidth = = 3\n");
  EXPECT_NE(e.find("scene.toml:3"), std::string::npos) << e;
}

TEST(SceneFile, LayerWithoutSourceIsAnError) {
  std::string e = error_of("[[layer]]\nkind = \"line\"\n");
  EXPECT_NE(e.find("no source"), std::string::npos) << e;
}

TEST(SceneFile, InsetWithoutMiterIsRejected) {
  std::string e =
      error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"outline\"\noutline_mode = \"inset\"\n");
  EXPECT_NE(e.find("miter"), std::string::npos) << e;
}

TEST(SceneFile, SharedEdgesOnceIsForNormalOutlinesOnly) {
  const prep::SceneSpec ok = prep::parse_scene(
      "[[layer]]\nsource = \"a.shp\"\nkind = \"outline\"\nshared_edges = \"once\"\n",
      "/data/city/scene.toml");
  EXPECT_TRUE(ok.layers.at(0).shared_edges_once);
  std::string e =
      error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"polygon\"\nshared_edges = \"once\"\n");
  EXPECT_NE(e.find("shared_edges = \"once\" needs kind = \"outline\""), std::string::npos) << e;
  e = error_of(
      "[[layer]]\nsource = \"a.shp\"\nkind = \"outline\"\ncorner = \"miter\"\n"
      "outline_mode = \"inset\"\nshared_edges = \"once\"\n");
  EXPECT_NE(e.find("outline_mode \"normal\""), std::string::npos) << e;
  e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"outline\"\nshared_edges = \"twice\"\n");
  EXPECT_NE(e.find("scene.toml:4: layer[0].shared_edges"), std::string::npos) << e;
  EXPECT_NE(e.find("\"all\" or \"once\""), std::string::npos) << e;
}

TEST(SceneFile, LightFalseIsForStaticLayers) {
  const prep::SceneSpec ok = prep::parse_scene(
      "[[layer]]\nsource = \"a.shp\"\nkind = \"polygon\"\nlight = false\n"
      "[[layer]]\nsource = \"b.shp\"\nkind = \"line\"\n",
      "/data/city/scene.toml");
  EXPECT_FALSE(ok.layers.at(0).light);
  EXPECT_TRUE(ok.layers.at(1).light);
  std::string e =
      error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"line\"\ndynamic = true\nlight = false\n");
  EXPECT_NE(e.find("light = false is for static layers"), std::string::npos) << e;
  e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"polygon\"\nlight = \"no\"\n");
  EXPECT_NE(e.find("scene.toml:4: layer[0].light"), std::string::npos) << e;
  e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"polygon\"\nligth = false\n");
  EXPECT_NE(e.find("did you mean \"light\""), std::string::npos) << e;
}

TEST(SceneFile, MinimumWidthsArePixelsForStaticLinesAndMetresForDynamicOnes) {
  const prep::SceneSpec ok = prep::parse_scene(
      "[[layer]]\nsource = \"a.shp\"\nkind = \"line\"\nwidth = 3\nmin_width_px = 2\n"
      "casing_width = 1\n"
      "[[layer]]\nsource = \"b.shp\"\nkind = \"line\"\ndynamic = true\nwidth = 4\n"
      "min_width_m = 8\ncasing_width = 1\n",
      "/data/city/scene.toml");
  // Each cased layer follows its casing copy.
  ASSERT_EQ(ok.layers.size(), 4u);
  EXPECT_EQ(ok.layers[0].min_width_px, 4);  // the casing: a pixel each side
  EXPECT_EQ(ok.layers[1].min_width_px, 2);
  EXPECT_EQ(ok.layers[2].min_width_m, 8.0 * 6 / 4);  // the casing: the same share
  EXPECT_EQ(ok.layers[3].min_width_m, 8);
  std::string e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"polygon\"\nmin_width_px = 2\n");
  EXPECT_NE(e.find("min_width_px needs a static line layer"), std::string::npos) << e;
  e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"line\"\nmin_width_m = 2\n");
  EXPECT_NE(e.find("min_width_m needs a dynamic line layer"), std::string::npos) << e;
  e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"line\"\nmin_width_px = 0\n");
  EXPECT_NE(e.find("scene.toml:4: layer[0].min_width_px"), std::string::npos) << e;
  EXPECT_NE(e.find("(0, 100]"), std::string::npos) << e;
}

TEST(SceneFile, PointLayersTakeRoundDotsOnly) {
  const prep::SceneSpec ok = prep::parse_scene(
      "[[layer]]\nsource = \"a.shp\"\nkind = \"point\"\nwidth = 5\ndynamic = true\n",
      "/data/city/scene.toml");
  EXPECT_EQ(ok.layers.at(0).kind, prep::DecalKind::point);
  std::string e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"point\"\ncorner = \"miter\"\n");
  EXPECT_NE(e.find("round dots"), std::string::npos) << e;
  e = error_of("[[layer]]\nsource = \"a.shp\"\nkind = \"point\"\ndash = [2, 1]\n");
  EXPECT_NE(e.find("takes no dash"), std::string::npos) << e;
}

TEST(SceneFile, DuplicateLayerNamesAreRejected) {
  std::string e =
      error_of("source = \"a.shp\"\n[[layer]]\nname = \"x\"\n[[layer]]\nname = \"x\"\n");
  EXPECT_NE(e.find("duplicate layer name"), std::string::npos) << e;
}

TEST(SceneFile, ShippedMonacoSampleParses) {
  prep::BuildSpec s =
      prep::load_scene_file(std::string(DECALPREP_SOURCE_DIR) + "/samples/monaco/scene.toml");
  ASSERT_GE(s.layers.size(), 5u);
  EXPECT_EQ(s.layers[0].source,
            std::string(DECALPREP_SOURCE_DIR) + "/samples/monaco/monaco.osm.pbf");
  EXPECT_EQ(s.dem, "/vsizip/" + std::string(DECALPREP_SOURCE_DIR) +
                       "/samples/monaco/N43E007.hgt.zip/N43E007.hgt");
  bool dynamic = false, outline = false;
  for (const auto& l : s.layers) {
    dynamic |= l.dynamic;
    outline |= l.kind == prep::DecalKind::outline;
  }
  EXPECT_TRUE(dynamic);
  EXPECT_TRUE(outline);
}

}  // namespace
