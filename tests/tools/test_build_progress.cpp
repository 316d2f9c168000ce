// `decalprep build --progress json` with the real binary (DECALPREP_TOOL):
// on the shipped Monaco sample every stderr line is a JSON object, the stages
// come in pipeline order, each ends with done == total, and the read stage
// counts what the report says was read; the package is the same bytes with
// and without progress output; batch mode keeps each scene's progress in its
// log and prints JSON objects of its own.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using prep::test::read_text;
using prep::test::run_tool;
using prep::test::TempDir;
using prep::test::ToolRun;

// stdout in ToolRun::output, the progress lines (stderr) in ToolRun::err.
const prep::test::RunOptions kSplit{.split_stderr = true};

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

// Every line parsed; fails the test on a line that is not a JSON object.
std::vector<json> parse_lines(const std::string& text) {
  std::vector<json> out;
  for (const std::string& l : lines_of(text)) {
    const json j = json::parse(l, nullptr, false);
    EXPECT_TRUE(j.is_object()) << "not a JSON object: " << l;
    if (j.is_object()) out.push_back(j);
  }
  return out;
}

const fs::path kSource = DECALPREP_SOURCE_DIR;

TEST(BuildProgress, JsonStagesOfTheMonacoSampleComeInPipelineOrderAndEndWithDoneEqualTotal) {
  const fs::path scene = kSource / "samples/monaco/scene.toml";
  if (!fs::exists(scene.parent_path() / "monaco.osm.pbf"))
    GTEST_SKIP() << "Monaco sample data missing";
  TempDir dir("decalprep_progress_json");
  const ToolRun r =
      run_tool("build '" + scene.string() + "' -o '" + (dir.path() / "m.decals").string() +
                   "' --report '" + (dir.path() / "report.json").string() + "' --progress json",
               dir, kSplit);
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(r.output, "");
  const std::vector<json> objects = parse_lines(r.err);
  ASSERT_FALSE(objects.empty());

  // Stages in the order they first appear; each one's objects contiguous.
  std::vector<std::string> order;
  std::map<std::string, json> last;
  for (const json& j : objects) {
    if (!j.contains("stage") || j["event"] == "slow") continue;
    const std::string stage = j["stage"];
    if (order.empty() || order.back() != stage) {
      EXPECT_EQ(std::find(order.begin(), order.end(), stage), order.end())
          << stage << " came back after another stage started";
      order.push_back(stage);
      EXPECT_EQ(j["event"], "start") << j.dump();
    }
    for (const char* key : {"done", "total", "rate", "eta_s", "elapsed_s", "unit"})
      EXPECT_TRUE(j.contains(key)) << key << " missing: " << j.dump();
    if (!j["total"].is_null()) {
      EXPECT_LE(j["done"].get<uint64_t>(), j["total"].get<uint64_t>()) << j.dump();
    }
    last[stage] = j;
  }
  std::vector<std::string> expected = {"read",        "project",         "clean",
                                       "build.lines", "build.quadtrees", "build.grid",
                                       "build.cells", "build.dynamic",   "write"};
  if (!last.count("build.dynamic"))  // a tool built without prep_model_terrain
    expected.erase(std::find(expected.begin(), expected.end(), "build.dynamic"));
  EXPECT_EQ(order, expected);
  for (const auto& [stage, j] : last) {
    EXPECT_EQ(j["event"], "end") << stage;
    ASSERT_TRUE(j["total"].is_number()) << stage << ": " << j.dump();
    EXPECT_EQ(j["done"], j["total"]) << stage << ": " << j.dump();
    EXPECT_EQ(j["eta_s"], 0) << stage;
  }

  // The read stage counted what the report says was read; write counts the
  // blobs' uncompressed bytes.
  const json report = json::parse(read_text(dir.path() / "report.json"));
  EXPECT_EQ(last["read"]["done"], report["manifest"]["totals"]["read"]);
  EXPECT_EQ(last["build.lines"]["unit"], "lines");
  EXPECT_EQ(last["write"]["unit"], "bytes");
  EXPECT_GT(last["write"]["done"].get<uint64_t>(), 0u);

  // The summary is the last object.
  const json& summary = objects.back();
  EXPECT_EQ(summary["event"], "summary");
  EXPECT_EQ(summary["package_written"], true);
  EXPECT_EQ(summary["features"]["read"], report["manifest"]["totals"]["read"]);
  // Durations of the stages, for the record (ctest --output-on-failure -V).
  for (const std::string& stage : order)
    std::printf("%-16s %8.3f s  %llu %s\n", stage.c_str(), last[stage]["elapsed_s"].get<double>(),
                static_cast<unsigned long long>(last[stage]["done"].get<uint64_t>()),
                last[stage]["unit"].get<std::string>().c_str());
}

// The small Monaco window of the golden test, with its source made absolute
// so the scene file can live anywhere.
std::string golden_scene_text() {
  std::string text = read_text(kSource / "tests/tools/golden/scene.toml");
  const std::string rel = "../../../samples/monaco/monaco.osm.pbf";
  const size_t at = text.find(rel);
  EXPECT_NE(at, std::string::npos);
  if (at != std::string::npos)
    text.replace(at, rel.size(), (kSource / "samples/monaco/monaco.osm.pbf").string());
  return text;
}

TEST(BuildProgress, PackageBytesAreTheSameWithAndWithoutProgressOutput) {
  if (!fs::exists(kSource / "samples/monaco/monaco.osm.pbf"))
    GTEST_SKIP() << "Monaco sample data missing";
  TempDir dir("decalprep_progress_bytes");
  std::ofstream(dir.path() / "window.toml") << golden_scene_text();
  const std::string scene = "'" + (dir.path() / "window.toml").string() + "'";
  const ToolRun quiet = run_tool(
      "build " + scene + " -o '" + (dir.path() / "quiet.decals").string() + "' -q", dir, kSplit);
  ASSERT_EQ(quiet.rc, 0) << quiet.err;
  EXPECT_EQ(quiet.err, "") << "-q printed something";
  const ToolRun json_run = run_tool(
      "build " + scene + " -o '" + (dir.path() / "json.decals").string() + "' --progress json", dir,
      kSplit);
  ASSERT_EQ(json_run.rc, 0) << json_run.err;
  const ToolRun plain = run_tool(
      "build " + scene + " -o '" + (dir.path() / "plain.decals").string() + "' --progress plain",
      dir, kSplit);
  ASSERT_EQ(plain.rc, 0) << plain.err;
  EXPECT_NE(plain.err.find("write: "), std::string::npos) << plain.err;
  const std::string a = read_text(dir.path() / "quiet.decals");
  ASSERT_FALSE(a.empty());
  EXPECT_TRUE(a == read_text(dir.path() / "json.decals")) << "--progress json changed the package";
  EXPECT_TRUE(a == read_text(dir.path() / "plain.decals"))
      << "--progress plain changed the package";
}

TEST(BuildProgress, BatchModeKeepsEachScenesProgressInItsLogAndPrintsJsonObjects) {
  if (!fs::exists(kSource / "samples/monaco/monaco.osm.pbf"))
    GTEST_SKIP() << "Monaco sample data missing";
  TempDir dir("decalprep_progress_batch");
  std::ofstream(dir.path() / "a.toml") << golden_scene_text();
  std::ofstream(dir.path() / "b.toml") << golden_scene_text();
  const ToolRun r = run_tool("build '" + (dir.path() / "a.toml").string() + "' '" +
                                 (dir.path() / "b.toml").string() + "' -o '" +
                                 (dir.path() / "out").string() + "' --jobs 2 --progress json",
                             dir, kSplit);
  ASSERT_EQ(r.rc, 0) << r.err;
  const std::vector<json> objects = parse_lines(r.err);
  size_t scenes = 0;
  for (const json& j : objects)
    if (j["event"] == "scene") {
      ++scenes;
      EXPECT_EQ(j["status"], "built") << j.dump();
    }
  EXPECT_EQ(scenes, 2u);
  ASSERT_FALSE(objects.empty());
  EXPECT_EQ(objects.back()["event"], "summary");
  EXPECT_EQ(objects.back()["built"], 2);
  for (const char* name : {"a", "b"}) {
    const std::vector<json> log =
        parse_lines(read_text(dir.path() / "out" / (std::string(name) + ".log")));
    ASSERT_FALSE(log.empty()) << name;
    const json& end = log.back();
    EXPECT_EQ(end["stage"], "write") << name << ": " << end.dump();
    EXPECT_EQ(end["done"], end["total"]) << name;
  }
  // summary.json is unchanged in shape: status per package.
  const json summary = json::parse(read_text(dir.path() / "out" / "summary.json"));
  EXPECT_EQ(summary["built"], 2);
}

// A scene that fails: its batch line says why (the scene's error line,
// naming the missing source) and where its log is, in plain and json.
TEST(BuildProgress, AFailedScenesBatchLineSaysWhyAndNamesItsLog) {
  TempDir dir("decalprep_progress_batch_failed");
  const fs::path scenes = dir.path() / "scenes";
  fs::create_directories(scenes);
  std::ofstream(scenes / "bad.toml")
      << "crs = \"EPSG:32632\"\n[[layer]]\nname = \"a\"\nsource = \"nope.geojson\"\n"
         "kind = \"polygon\"\n";
  auto batch = [&](const char* out, const char* mode) {
    return run_tool("build '" + scenes.string() + "' -o '" + (dir.path() / out).string() +
                        "' --progress " + mode,
                    dir, kSplit);
  };
  ToolRun r = batch("plain", "plain");
  EXPECT_EQ(r.rc, 3) << r.err;  // the scene's own exit code: input
  const size_t at = r.err.find("bad.toml: FAILED, exit 3");
  ASSERT_NE(at, std::string::npos) << r.err;
  const std::string line = r.err.substr(at, r.err.find('\n', at) - at);
  EXPECT_NE(line.find("nope.geojson"), std::string::npos) << line;
  EXPECT_NE(line.find("; log " + (dir.path() / "plain" / "bad.log").string()), std::string::npos)
      << line;

  r = batch("json", "json");
  EXPECT_EQ(r.rc, 3) << r.err;
  size_t failed = 0;
  for (const json& j : parse_lines(r.err))
    if (j["event"] == "scene") {
      ++failed;
      EXPECT_EQ(j["status"], "failed") << j.dump();
      EXPECT_NE(j["error"].get<std::string>().find("nope.geojson"), std::string::npos) << j.dump();
    }
  EXPECT_EQ(failed, 1u);
}

}  // namespace
