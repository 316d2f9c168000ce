// Minimum widths (scene file min_width_px; formats/SPEC.md "Minimum
// widths"): a static line of such a layer is drawn max(w, N pixels) wide
// while a pixel is at most the package's limit (here 2 x resolution 10 =
// 20 m; the extent's 2.2 km / 256 is less), N x limit wide beyond it.
// Checked top-down against the width this test wrote, column by column,
// at pixel sizes from 0.1 m to 50 m, on
// the CPU and in GL; a layer without the key keeps its width; GL and the
// CPU image agree on an oblique view of mitred and inset lines.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_min_widths {

namespace fs = std::filesystem;
namespace R = prep::render;

namespace {

constexpr double kX0 = 500000, kY0 = 4800000;
constexpr double kN = 3, kLimit = 20;  // min_width_px; 2 x the scene's resolution

std::string feature(std::initializer_list<std::array<double, 2>> pts) {
  std::string c;
  for (const auto& p : pts)
    c += (c.empty() ? "[" : ",[") + std::to_string(p[0]) + "," + std::to_string(p[1]) + "]";
  return R"({"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[)" +
         c + "]}}";
}

void write_layer(const fs::path& file, const std::string& features) {
  std::ofstream(file)
      << R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},"features":[)"
      << features << "]}";
}

// river: 1 m, min 3 px, along y = kY0; plain: 1 m, no minimum, along
// y = kY0 + 400; zig: 0.5 m mitred zigzag, min 3 px; ring: a 1 m inset
// outline, min 3 px (its visible band is N pixels).
std::string build(const fs::path& dir, std::string& why) {
  write_layer(dir / "river.geojson", feature({{kX0, kY0}, {kX0 + 2000, kY0}}));
  write_layer(dir / "plain.geojson", feature({{kX0, kY0 + 400}, {kX0 + 2000, kY0 + 400}}));
  write_layer(dir / "road.geojson", feature({{kX0, kY0 - 600}, {kX0 + 2000, kY0 - 600}}));
  write_layer(dir / "zig.geojson", feature({{kX0 + 200, kY0 - 300},
                                            {kX0 + 260, kY0 - 240},
                                            {kX0 + 320, kY0 - 300},
                                            {kX0 + 380, kY0 - 240},
                                            {kX0 + 440, kY0 - 300}}));
  std::ofstream(dir / "ring.geojson")
      << R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},)"
         R"("features":[{"type":"Feature","properties":{},"geometry":{"type":"Polygon",)"
         R"("coordinates":[[[500600,4799700],[500700,4799700],[500700,4799780],)"
         R"([500600,4799700]]]}}]})";
  std::string toml = render_test::utm_scene_toml(
      {{"river", "line", "width = 1\ncolor = \"#2060ff\"\nmin_width_px = 3\n"},
       {"plain", "line", "width = 1\ncolor = \"#ff2020\"\n"},
       {"zig", "line", "width = 0.5\ncolor = \"#20a020\"\ncorner = \"miter\"\nmin_width_px = 3\n"},
       {"ring", "outline",
        "width = 1\ncolor = \"#000000\"\ncorner = \"miter\"\noutline_mode = \"inset\"\n"
        "min_width_px = 3\n"},
       {"road", "line", "dynamic = true\nwidth = 4\ncolor = \"#ffcc00\"\nmin_width_m = 8\n"}});
  toml.replace(toml.find("resolution = 0"), 14, "resolution = 10");
  std::ofstream(dir / "scene.toml") << toml;
  const std::string pkg = (dir / "widths.decals").string();
  const auto r =
      prep::test::run_tool("build " + (dir / "scene.toml").string() + " -o " + pkg + " -q");
  if (r.rc != 0) why = r.output;
  return r.rc == 0 ? pkg : "";
}

// Top-down over the absolute box centred on (cx, cy + px / 4) (a line
// along y = cy is not on a pixel edge), 200 x 60 pixels of `px` metres.
std::optional<R::Image> shoot(const R::DecalSource& src, double cx, double cy, double px, bool cpu,
                              R::Method method = R::Method::decal) {
  cy += 0.25 * px;
  const prep::Extent view{cx - 100 * px - src.frame.origin_x, cy - 30 * px - src.frame.origin_y,
                          cx + 100 * px - src.frame.origin_x, cy + 30 * px - src.frame.origin_y};
  R::RenderOptions opt;
  opt.width = 200;
  opt.height = 60;
  opt.camera = R::topdown_camera(view, 0, 0);
  opt.aa = R::AntiAliasing::none;
  opt.method = method;
  opt.texture_resolution = px;  // the texture method: one texel a pixel
  try {
    return cpu ? R::render_cpu(src, R::flat_heightfield(view), opt)
               : R::render_gl(src, R::flat_heightfield(view), opt);
  } catch (const prep::render_error&) {
    return std::nullopt;
  }
}

// Per column, the covered pixels (alpha > 0.5 in the static decal layer,
// or the dynamic one) of the rows within `rows` of the middle (the other
// layers lie farther off).
std::vector<int> runs(const R::Image& img, int rows, bool dynamic = false) {
  const std::vector<float>& layer = dynamic ? img.dynamic : img.decals;
  std::vector<int> out(img.width, 0);
  const int mid = int(img.height) / 2;
  for (int j = std::max(0, mid - rows); j < std::min(int(img.height), mid + rows); ++j)
    for (uint32_t i = 0; i < img.width; ++i)
      out[i] += layer[(size_t(j) * img.width + i) * 4 + 3] > 0.5f;
  return out;
}

class MinWidths : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = render_test::process_dir("min_widths");
    path_ = build(dir_, why_);
  }
  static void TearDownTestSuite() { render_test::remove_process_dir(dir_); }
  void SetUp() override {
    ASSERT_FALSE(path_.empty()) << why_;
    ASSERT_TRUE(decal::Package::open(path_, pkg_));
    src_ = R::source_of(pkg_);
  }
  static inline fs::path dir_;
  static inline std::string path_, why_;
  decal::Package pkg_;
  R::DecalSource src_;
};

}  // namespace

TEST_F(MinWidths, ThePackageRecordsTheLayersAndTheLimit) {
  const auto meta = nlohmann::json::parse(pkg_.metadata_json());
  EXPECT_EQ(meta.at("layers").at(0).at("min_width_px"), kN);
  EXPECT_FALSE(meta.at("layers").at(1).contains("min_width_px"));
  EXPECT_DOUBLE_EQ(meta.at("min_width_pixel_m").get<double>(), kLimit);
  EXPECT_EQ(src_.min_width_px, (std::vector<float>{3, 0, 3, 3, 0, 0}));
  EXPECT_EQ(src_.min_width_m, (std::vector<float>{0, 0, 0, 0, 8, 0}));
  EXPECT_DOUBLE_EQ(src_.min_width_pixel_m, kLimit);
}

TEST_F(MinWidths, ALineIsAtLeastNPixelsWideUpToTheLimitAndItsWidthClose) {
  for (bool cpu : {true, false}) {
    for (double px : {0.1, 0.5, 2.0, 5.0, 10.0, 20.0, 50.0}) {
      SCOPED_TRACE(std::string(cpu ? "cpu" : "gl") + " at " + std::to_string(px) + " m/px");
      const auto img = shoot(src_, kX0 + 1000, kY0, px, cpu);
      if (!img) {
        ASSERT_FALSE(cpu);
        GTEST_SKIP() << "no headless GL";
      }
      // The drawn width: max(1 m, N min(px, limit)), in pixels.
      const double want = std::max(1.0, kN * std::min(px, kLimit)) / px;
      // The columns over the river (2000 m from x = kX0), a pixel off its
      // ends; the rows within the drawn width and 2 pixels of it.
      const std::vector<int> r = runs(*img, int(std::ceil(want / 2)) + 2);
      int lo = 1 << 30, hi = 0;
      for (int i = 0; i < int(r.size()); ++i) {
        const double x = kX0 + 1000 + (i + 0.5 - 100) * px;
        if (x < kX0 + px * (want + 1) || x > kX0 + 2000 - px * (want + 1)) continue;
        lo = std::min(lo, r[i]);
        hi = std::max(hi, r[i]);
      }
      std::printf("%s %5.1f m/px: river %d..%d px across, analytic %.2f\n", cpu ? "cpu" : "gl ", px,
                  lo, hi, want);
      EXPECT_GE(lo, int(std::floor(want - 1e-9)));
      EXPECT_LE(hi, int(std::ceil(want + 1e-9)));
      if (px <= kLimit) {
        EXPECT_GE(lo, int(kN));
      }
    }
    // Without the key a 1 m line stays 1 m: half a pixel at 2 m/px.
    const auto plain = shoot(src_, kX0 + 1000, kY0 + 400, 2.0, cpu);
    ASSERT_TRUE(plain.has_value());
    for (int n : runs(*plain, 5)) EXPECT_LE(n, 1);
  }
}

// A dynamic road 4 px wide with min_width_m = 8: max(4 px, 8 m) across.
TEST_F(MinWidths, ADynamicLineIsAtLeastItsMetresWideCloseUp) {
  for (bool cpu : {true, false}) {
    for (double px : {0.25, 0.5, 1.0, 2.0, 4.0}) {
      SCOPED_TRACE(std::string(cpu ? "cpu" : "gl") + " at " + std::to_string(px) + " m/px");
      const auto img = shoot(src_, kX0 + 1000, kY0 - 600, px, cpu);
      if (!img) {
        ASSERT_FALSE(cpu);
        GTEST_SKIP() << "no headless GL";
      }
      const double want = std::max(4.0, 8.0 / px);
      const std::vector<int> r = runs(*img, int(want / 2) + 3, true);
      int lo = 1 << 30, hi = 0;
      for (int i = 10; i < int(r.size()) - 10; ++i)
        lo = std::min(lo, r[i]), hi = std::max(hi, r[i]);
      std::printf("%s %4.2f m/px: road %d..%d px across, analytic %.2f\n", cpu ? "cpu" : "gl ", px,
                  lo, hi, want);
      EXPECT_GE(lo, int(std::floor(want - 1e-9)));
      EXPECT_LE(hi, int(std::ceil(want + 1e-9)));
    }
  }
}

// The volume method widens for the view's pixel (exact top-down), the
// texture method for its texel.
TEST_F(MinWidths, TheVolumeAndTextureMethodsDrawTheSameWidths) {
  for (R::Method m : {R::Method::volume, R::Method::texture}) {
    for (double px : {2.0, 5.0}) {
      SCOPED_TRACE(std::string(m == R::Method::volume ? "volume" : "texture") + " at " +
                   std::to_string(px));
      const auto img = shoot(src_, kX0 + 1000, kY0, px, false, m);
      if (!img) GTEST_SKIP() << "no headless GL";
      const std::vector<int> r = runs(*img, 4);
      int lo = 1 << 30, hi = 0;
      for (int i = 10; i < int(r.size()) - 10; ++i)
        lo = std::min(lo, r[i]), hi = std::max(hi, r[i]);
      EXPECT_GE(lo, 3);
      EXPECT_LE(hi, 4);
    }
  }
}

TEST_F(MinWidths, GlAndCpuAgreeOnAnObliqueViewOfMitredAndInsetLines) {
  R::RenderOptions opt;
  opt.width = 640, opt.height = 360;
  const prep::Extent view{200 + kX0 - src_.frame.origin_x, -320 + kY0 - src_.frame.origin_y,
                          720 + kX0 - src_.frame.origin_x, -200 + kY0 - src_.frame.origin_y};
  opt.camera = R::fit_camera(view, 0, 0, opt.width, opt.height, R::Projection::perspective, 40);
  opt.aa = R::AntiAliasing::none;
  const R::Heightfield flat = R::flat_heightfield(view);
  std::optional<R::Image> gl;
  try {
    gl = R::render_gl(src_, flat, opt);
  } catch (const prep::render_error& e) {
    GTEST_SKIP() << "no headless GL: " << e.what();
  }
  const R::Image cpu = R::render_cpu(src_, flat, opt);
  const render_test::Agreement a = render_test::agreement(cpu.decals, gl->decals);
  size_t covered = 0;
  for (size_t k = 3; k < cpu.decals.size(); k += 4) covered += cpu.decals[k] > 0.5f;
  std::printf("oblique: %zu of %zu decal pixels agree (GL, CPU); %zu covered\n", a.agree,
              a.considered, covered);
  EXPECT_GT(covered, 1000u);
  EXPECT_GE(a.ratio(), 0.999);
}

}  // namespace render_min_widths
