// Line casing (scene file casing_width, casing_color): a cased layer is
// drawn over a copy of itself, casing_width wider on each side in the casing
// colour, so that at a crossing of two roads of the layer both fills lie
// over both casings (the crossing merges cleanly). Checked top-down against
// the geometry this test wrote, for static lines (ground metres) and dynamic
// lines (pixels), on the CPU and in GL.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_casing {

namespace fs = std::filesystem;
namespace R = prep::render;
using prep::test::run_tool;

namespace {

constexpr double kX0 = 500000, kY0 = 4800000;

std::string line(double x0, double y0, double x1, double y1) {
  return R"({"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[[)" +
         std::to_string(x0) + "," + std::to_string(y0) + "],[" + std::to_string(x1) + "," +
         std::to_string(y1) + "]]}}";
}

std::string collection(const std::string& a, const std::string& b) {
  return R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},"features":[)" +
         a + "," + b + "]}";
}

// A cross of two static roads (6 m wide, 2 m casing) centred on (kX0 + 100,
// kY0), and a cross of two dynamic roads (5 px, 2 px casing) centred on
// (kX0 + 300, kY0).
std::string build(const fs::path& dir, std::string& why) {
  std::ofstream(dir / "roads.geojson") << collection(
      line(kX0, kY0, kX0 + 200, kY0), line(kX0 + 100, kY0 - 100, kX0 + 100, kY0 + 100));
  std::ofstream(dir / "dyn.geojson") << collection(line(kX0 + 220, kY0, kX0 + 380, kY0),
                                                   line(kX0 + 300, kY0 - 80, kX0 + 300, kY0 + 80));
  return render_test::build_utm_scene(
      dir, "casing.decals",
      {{"roads", "line",
        "width = 6\ncolor = \"#ffffff\"\ncasing_width = 2\ncasing_color = \"#000000\"\n"},
       {"dyn", "line", "dynamic = true\nwidth = 5\ncolor = \"#ffcc00\"\ncasing_width = 2\n"}},
      why);
}

struct Shot {
  R::Image img;
  prep::Extent view;
};

// Top-down at 0.25 m per pixel over `view` (absolute coordinates).
std::optional<Shot> shoot(const R::DecalSource& src, const prep::Extent& abs, bool cpu) {
  const prep::Extent view{abs.xmin - src.frame.origin_x, abs.ymin - src.frame.origin_y,
                          abs.xmax - src.frame.origin_x, abs.ymax - src.frame.origin_y};
  R::RenderOptions opt;
  opt.width = uint32_t(std::lround((abs.xmax - abs.xmin) * 4));
  opt.height = uint32_t(std::lround((abs.ymax - abs.ymin) * 4));
  opt.camera = R::topdown_camera(view, 0, 0);
  Shot s{{}, abs};
  try {
    s.img = cpu ? R::render_cpu(src, R::flat_heightfield(view), opt)
                : R::render_gl(src, R::flat_heightfield(view), opt);
  } catch (const prep::render_error&) {
    return std::nullopt;
  }
  return s;
}

// The straight-alpha colour at absolute (x, y) of a layer, 0..255.
std::array<int, 4> at(const Shot& s, const std::vector<float>& layer, double x, double y) {
  const size_t i = size_t((x - s.view.xmin) * 4), j = size_t((s.view.ymax - y) * 4);
  const float* p = &layer[(j * s.img.width + i) * 4];
  return {int(std::lround(p[0] * 255)), int(std::lround(p[1] * 255)), int(std::lround(p[2] * 255)),
          int(std::lround(p[3] * 255))};
}

constexpr std::array<int, 4> kWhite{255, 255, 255, 255}, kBlack{0, 0, 0, 255}, kNone{0, 0, 0, 0};

TEST(Casing, CrossingRoadsOfACasedLayerMergeWithTheirFillsOverBothCasings) {
  const fs::path dir = fs::current_path() / "render-out" / "casing";
  fs::create_directories(dir);
  std::string why;
  const std::string path = build(dir, why);
  ASSERT_FALSE(path.empty()) << why;
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path, pkg));
  // The layer table: each cased layer preceded by its casing.
  const auto meta = nlohmann::json::parse(pkg.metadata_json());
  ASSERT_EQ(meta.at("layers").size(), 4u);
  EXPECT_EQ(meta["layers"][0]["name"], "roads.casing");
  EXPECT_EQ(meta["layers"][0]["casing_of"], "roads");
  EXPECT_EQ(meta["layers"][0]["width"], 10.0);
  EXPECT_EQ(meta["layers"][1]["name"], "roads");
  EXPECT_EQ(meta["layers"][2]["name"], "dyn.casing");
  EXPECT_EQ(meta["layers"][2]["width"], 9.0);
  const R::DecalSource src = R::source_of(pkg);
  struct Probe {
    double x, y;  // from the crossing centre, metres
    std::array<int, 4> want;
    const char* what;
  };
  // Probes `layer` of a 40 m (static) or 10 m (dynamic) view around the
  // crossing at (cx, cy), on the CPU and in GL.
  auto probe = [&](double cx, double cy, double half, bool dynamic,
                   std::initializer_list<Probe> probes) {
    for (bool cpu : {true, false}) {
      const auto s = shoot(src, {cx - half, cy - half, cx + half, cy + half}, cpu);
      if (!s) return false;
      SCOPED_TRACE(std::string(cpu ? "cpu" : "gl") + (dynamic ? " dynamic" : " static"));
      for (const Probe& p : probes)
        EXPECT_EQ(at(*s, dynamic ? s->img.dynamic : s->img.decals, cx + p.x, cy + p.y), p.want)
            << p.what;
    }
    return true;
  };
  // Static: pixel centres at quarter-metre offsets + 0.125 m; the probes stay
  // 0.5 m or more from every band edge (fill |d| < 3 m, casing 3..5 m).
  const bool gl = probe(kX0 + 100, kY0, 20, false,
                        {{0.1, 0.1, kWhite, "crossing centre"},
                         {-12, 1.1, kWhite, "horizontal fill"},
                         {-12, 4.1, kBlack, "horizontal casing"},
                         {-12, 6.1, kNone, "beside the casing"},
                         // one road's casing band in the other's fill: the fill, both ways
                         {4.1, 1.1, kWhite, "vertical casing under horizontal fill"},
                         {-1.1, -4.1, kWhite, "horizontal casing under vertical fill"},
                         {4.1, -4.1, kBlack, "both casings, neither fill"}});
  if (!gl) GTEST_SKIP() << "no headless GL";
  // Dynamic: 5 px fill, 2 px casing each side (0.25 m pixels: 0.625 m and
  // 1.125 m half widths), default casing colour: 60% of #ffcc00.
  const std::array<int, 4> yellow{255, 204, 0, 255}, dark{153, 122, 0, 255};
  probe(kX0 + 300, kY0, 5, true,
        {{0.01, 0.01, yellow, "crossing centre"},
         {-3, 0.2, yellow, "fill"},
         {-3, 0.9, dark, "casing"},
         {-3, 1.6, kNone, "beside"},
         {0.9, 0.2, yellow, "vertical casing under horizontal fill"},
         {0.9, 0.9, dark, "both casings"}});
}

TEST(Casing, ScenesThatCannotBeCasedAreRefusedNamingTheKey) {
  const fs::path dir = fs::current_path() / "render-out" / "casing_bad";
  fs::create_directories(dir);
  std::ofstream(dir / "a.geojson")
      << collection(line(kX0, kY0, kX0 + 10, kY0), line(kX0, kY0 + 5, kX0 + 10, kY0 + 5));
  auto scene = [&](const std::string& extra) { return render_test::build_layer_a(dir, extra); };
  auto r = scene("kind = \"polygon\"\ncasing_width = 1\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("casing_width needs kind"), std::string::npos) << r.output;
  r = scene("kind = \"line\"\ncasing_color = \"#000000\"\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("casing_color needs a casing_width"), std::string::npos) << r.output;
  r = scene("kind = \"line\"\ncasing_width = -1\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("layer[0].casing_width"), std::string::npos) << r.output;
}

}  // namespace

}  // namespace render_casing
