// The library side of `decalprep build`: prep::scene_spec (one scene as the
// command line asks for it) and prep::run_batch (batch mode), called
// directly. The tool's own batch behaviour (messages, exit codes, verify of
// the packages) is tests/hostile/batch_test.py's job; here the result
// structure and the callbacks, on tiny scenes written by the test.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "prep/error.hpp"
#include "prep/pipeline.hpp"
#include "test_support.hpp"

namespace {

using prep::test::TempDir;
using prep::test::write_text;

// A GeoJSON square of 10 m near Monaco (one feature), and a scene file that
// reads it as polygons.
std::string square_scene(const TempDir& dir, const std::string& name, const std::string& source) {
  write_text(dir.file("square.geojson"),
             R"({"type": "FeatureCollection", "features": [{"type": "Feature", "id": 1,
                 "properties": {}, "geometry": {"type": "Polygon", "coordinates":
                 [[[7.42, 43.73], [7.4201, 43.73], [7.4201, 43.7301], [7.42, 43.7301], [7.42, 43.73]]]}}]})");
  const std::string scene = dir.file(name);
  write_text(scene,
             "source = \"" + source + "\"\n\n[[layer]]\nname = \"squares\"\nkind = \"polygon\"\n");
  return scene;
}

TEST(BuildSpec, TheFilelessFormIsOneLayerNamedAfterTheSourceLayerWithDynamicLinesThreePixelsWide) {
  prep::SceneRequest r;
  r.input = "roads.shp";
  r.layer.kind = "line";
  r.layer.dynamic = true;
  prep::BuildSpec s = prep::scene_spec(r);
  ASSERT_EQ(s.layers.size(), 1u);
  EXPECT_EQ(s.layers[0].source, "roads.shp");
  EXPECT_EQ(s.layers[0].name, "layer0");
  EXPECT_EQ(s.layers[0].kind, prep::DecalKind::line);
  EXPECT_EQ(s.layers[0].style.width, 3.0);
  r.layer.layer = "roads";
  EXPECT_EQ(prep::scene_spec(r).layers[0].name, "roads");
}

// The scene keys the file-less form takes as options (--name,
// --color-attribute, --color-ramp, --dash, --casing-width, --casing-color)
// give the layers the scene file gives for the same keys; a bad value or a
// combination the scene file refuses is a usage error naming the option.
TEST(BuildSpec, TheFilelessFormSetsNameRampDashAndCasingAsTheSceneFileDoes) {
  TempDir dir("decalprep_fileless_keys");
  const std::string scene = dir.file("keys.toml");
  write_text(scene,
             "source = \"roads.shp\"\n[[layer]]\nname = \"streets\"\nkind = \"line\"\n"
             "width = 6\ncolor_attribute = \"lanes\"\n"
             "color_ramp = [[1, \"#ff0000\"], [4, \"#00ff00cc\"]]\ndash = [8, 4]\n"
             "casing_width = 1.5\ncasing_color = \"#101010\"\n");
  prep::SceneRequest from_file;
  from_file.input = scene;
  const prep::BuildSpec want = prep::scene_spec(from_file);

  prep::SceneRequest r;
  r.input = dir.file("roads.shp");
  r.layer.kind = "line";
  r.layer.width = 6;
  r.layer.name = "streets";
  r.layer.color_attribute = "lanes";
  r.layer.color_ramp = "1:#ff0000,4:#00ff00cc";
  r.layer.dash = "8,4";
  r.layer.casing_width = 1.5;
  r.layer.casing_color = "#101010";
  const prep::BuildSpec got = prep::scene_spec(r);
  ASSERT_EQ(got.layers.size(), want.layers.size());
  ASSERT_EQ(got.layers.size(), 2u);  // the casing, then the layer
  for (size_t i = 0; i < got.layers.size(); ++i) {
    const prep::LayerSpec &g = got.layers[i], &w = want.layers[i];
    EXPECT_EQ(g.name, w.name) << i;
    EXPECT_EQ(g.casing_of, w.casing_of) << i;
    EXPECT_EQ(g.style.width, w.style.width) << i;
    EXPECT_EQ(g.style.color.rgba, w.style.color.rgba) << i;
    EXPECT_EQ(g.style.color.attribute, w.style.color.attribute) << i;
    ASSERT_EQ(g.style.color.ramp.size(), w.style.color.ramp.size()) << i;
    for (size_t k = 0; k < g.style.color.ramp.size(); ++k) {
      EXPECT_EQ(g.style.color.ramp[k].value, w.style.color.ramp[k].value) << i;
      EXPECT_EQ(g.style.color.ramp[k].rgba, w.style.color.ramp[k].rgba) << i;
    }
    EXPECT_EQ(g.dash, w.dash) << i;
    EXPECT_EQ(g.casing_width, w.casing_width) << i;
    EXPECT_EQ(g.casing_rgba, w.casing_rgba) << i;
  }
  EXPECT_EQ(got.layers[0].name, "streets.casing");

  auto refused = [&](auto change, const std::string& needle) {
    prep::SceneRequest bad = r;
    change(bad.layer);
    try {
      prep::scene_spec(bad);
      ADD_FAILURE() << "accepted; wanted an error with " << needle;
    } catch (const prep::usage_error& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  refused([](prep::FilelessLayer& l) { l.dash = "8"; }, "--dash '8': expected an even count");
  refused([](prep::FilelessLayer& l) { l.dash = "8,x"; }, "--dash '8,x': not a list of numbers");
  refused([](prep::FilelessLayer& l) { l.color_ramp = "4:#ff0000,1:#00ff00"; },
          "--color-ramp: stop values must increase");
  refused([](prep::FilelessLayer& l) { l.color_attribute.clear(); },
          "--color-attribute and --color-ramp go together");
  refused([](prep::FilelessLayer& l) { l.casing_width.reset(); },
          "--casing-color needs --casing-width");
  refused([](prep::FilelessLayer& l) { l.kind = "polygon"; }, "--dash needs --kind line");
}

TEST(BuildSpec, OverridesReplaceTheSceneFilesValuesAndABadOneNamesItsOption) {
  TempDir dir("decalprep_scene_spec");
  prep::SceneRequest r;
  r.input = square_scene(dir, "a.toml", dir.file("square.geojson"));
  r.overrides.resolution = 0.25;
  r.overrides.grid = "20x30";
  r.overrides.extent = "1,2,3,4";
  r.overrides.skip_failures = true;
  const prep::BuildSpec s = prep::scene_spec(r);
  EXPECT_EQ(s.resolution, 0.25);
  EXPECT_EQ(s.model.grid_nx, 20u);
  EXPECT_EQ(s.model.grid_ny, 30u);
  ASSERT_TRUE(s.extent);
  EXPECT_EQ(s.extent->xmin, 1.0);
  EXPECT_EQ(s.extent->ymax, 4.0);
  EXPECT_TRUE(s.skip_failures);

  r.overrides.resolution = -1;
  try {
    prep::scene_spec(r);
    FAIL() << "a negative --resolution was accepted";
  } catch (const prep::usage_error& e) {
    EXPECT_NE(std::string(e.what()).find("--resolution"), std::string::npos) << e.what();
  }
  r.overrides.resolution.reset();
  r.layer.kind = "line";  // the file-less form's option beside a scene file
  try {
    prep::scene_spec(r);
    FAIL() << "--kind beside a scene file was accepted";
  } catch (const prep::usage_error& e) {
    EXPECT_NE(std::string(e.what()).find(r.input), std::string::npos) << e.what();
  }
}

TEST(RunBatch, ReportsEachScenesStatusAndTheFirstFailuresExitCode) {
  TempDir dir("decalprep_run_batch");
  const std::string good = square_scene(dir, "a_good.toml", dir.file("square.geojson"));
  const std::string missing = dir.file("no_such_file.geojson");
  const std::string bad = square_scene(dir, "b_missing.toml", missing);

  prep::BatchRequest req;
  req.inputs = {bad, good};  // input order, not name order
  req.output_dir = dir.file("out");
  req.jobs = 2;
  req.scene_progress = prep::ProgressMode::none;
  std::vector<size_t> done;
  req.on_scene_done = [&](const prep::BatchScene& s, size_t n, size_t total) {
    EXPECT_EQ(total, 2u);
    EXPECT_NE(s.exit_code, -1) << s.scene;
    done.push_back(n);
  };
  const prep::BatchResult r = prep::run_batch(req);

  EXPECT_EQ(done, (std::vector<size_t>{1, 2}));
  ASSERT_EQ(r.scenes.size(), 2u);
  const prep::BatchScene& b = r.scenes[0];
  const prep::BatchScene& a = r.scenes[1];
  EXPECT_EQ(b.scene, bad);
  EXPECT_STREQ(b.status(), "failed");
  EXPECT_EQ(b.exit_code, static_cast<int>(prep::ExitCode::input));
  EXPECT_EQ(b.error.rfind("decalprep: ", 0), 0u) << b.error;
  EXPECT_NE(b.error.find("no_such_file.geojson"), std::string::npos) << b.error;
  EXPECT_FALSE(prep::test::exists(b.output));
  EXPECT_EQ(a.scene, good);
  EXPECT_STREQ(a.status(), "built");
  EXPECT_EQ(a.output, dir.file("out/a_good.decals"));
  EXPECT_TRUE(prep::test::exists(a.output));
  EXPECT_GT(a.peak_rss_kb, 0);
  EXPECT_EQ(r.failed, 1u);
  EXPECT_EQ(r.partial, 0u);
  EXPECT_EQ(r.exit_code, static_cast<int>(prep::ExitCode::input));

  // The summary says the same, with the good scene's one kept square.
  EXPECT_EQ(r.summary, dir.file("out/summary.json"));
  std::ifstream in(r.summary);
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_EQ(j["built"], 1);
  EXPECT_EQ(j["failed"], 1);
  EXPECT_EQ(j["packages"][0]["status"], "failed");
  EXPECT_EQ(j["packages"][0]["error"], b.error);
  EXPECT_EQ(j["packages"][1]["status"], "built");
  EXPECT_EQ(j["packages"][1]["counts"]["read"], 1);
  EXPECT_EQ(j["packages"][1]["counts"]["kept"], 1);
}

TEST(RunBatch, ABadOptionFailsEverySceneWithTheMessageOfASingleBuild) {
  TempDir dir("decalprep_run_batch_usage");
  prep::BatchRequest req;
  req.inputs = {square_scene(dir, "a.toml", dir.file("square.geojson")),
                square_scene(dir, "b.toml", dir.file("square.geojson"))};
  req.output_dir = dir.file("out");
  req.scene.overrides.grid = "5 by 5";
  req.scene_progress = prep::ProgressMode::none;
  const prep::BatchResult r = prep::run_batch(req);
  ASSERT_EQ(r.scenes.size(), 2u);
  for (const prep::BatchScene& s : r.scenes) {
    EXPECT_EQ(s.exit_code, static_cast<int>(prep::ExitCode::usage)) << s.scene;
    EXPECT_EQ(s.error, "decalprep: --grid: expected NXxNY (e.g. 500x500) or auto, got \"5 by 5\"");
  }
  EXPECT_EQ(r.exit_code, static_cast<int>(prep::ExitCode::usage));
}

TEST(RunBatch, RefusesTwoScenesThatWouldWriteTheSamePackage) {
  TempDir dir("decalprep_run_batch_stems");
  std::filesystem::create_directories(dir.path() / "x");
  const std::string a = square_scene(dir, "s.toml", dir.file("square.geojson"));
  const std::string b = dir.file("x/s.toml");
  std::filesystem::copy_file(a, b);
  prep::BatchRequest req;
  req.inputs = {a, b};
  req.output_dir = dir.file("out");
  EXPECT_THROW(prep::run_batch(req), prep::usage_error);
}

}  // namespace
