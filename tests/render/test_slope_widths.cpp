// Slope widths (scene key slope_widths, render --slope-widths; formats/SPEC.md
// "Slope widths"): a static line's width measured along the terrain, not in
// plan. Synthetic DEMs written here as GeoTIFF (inclined planes at 30° and
// 60°, a 45° cone), top-down CPU and GL renders at 2 cm per pixel; the width
// is the distance between the rendered band's two edges, taken on the
// analytic surface (the oracle) and measured perpendicular to the line's
// lifted centre line, never from the code under test. With the option on it
// is within 2% of the nominal width; off, the plan width stretched by the
// slope, the larger error. Then CPU and GL agree on a perspective view of
// the cone with round, miter and bevel lines.
#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "decal/reader.hpp"
#include "dem_tiff.hpp"
#include "epsg_wkt.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_slope_widths {

namespace fs = std::filesystem;
namespace R = prep::render;
using prep::test::run_tool;

namespace {

constexpr double kX0 = 500000, kY0 = 4800000;  // EPSG:32632
constexpr double kWidth = 8;                   // the roads' nominal width, ground metres
constexpr double kPi = 3.14159265358979323846;
// The cone: apex at (kConeX, kConeY), 100 m high, flanks at 45°. The contour
// line y = kY0 touches the circle r = 40 m at x = kConeX.
constexpr double kConeX = kX0 + 100, kConeY = kY0 + 40;

using Height = std::function<double(double x, double y)>;  // absolute EPSG:32632

Height plane(double deg) {
  const double s = std::tan(deg * kPi / 180);
  return [s](double, double y) { return 50 + s * (y - kY0); };
}
double cone(double x, double y) {
  return 100 - std::hypot(x - kConeX, y - kConeY);
}

// A north-up GeoTIFF of `h` at its cell centres, cells of `cell` metres,
// its upper-left corner at (x0, y0).
void write_dem(const std::string& path, const Height& h, double x0, double y0, int w, int ht,
               double cell) {
  GDALDatasetUniquePtr ds =
      create_dem_tiff(path, w, ht, GDT_Float64, x0, y0, cell, epsg_wkt(32632));
  ASSERT_TRUE(ds);
  std::vector<double> z(size_t(w) * ht);
  for (int j = 0; j < ht; ++j)
    for (int i = 0; i < w; ++i)
      z[size_t(j) * w + i] = h(x0 + (i + 0.5) * cell, y0 - (j + 0.5) * cell);
  ASSERT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w, ht, z.data(), w, ht, GDT_Float64, 0,
                                           0, nullptr),
            CE_None);
}

std::string feature(const std::vector<std::array<double, 2>>& pts) {
  std::string c;
  for (const auto& p : pts)
    c += (c.empty() ? "[" : ",[") + std::to_string(p[0]) + "," + std::to_string(p[1]) + "]";
  return R"({"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[)" +
         c + "]}}";
}

std::string collection(const std::vector<std::string>& features) {
  std::string s =
      R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},"features":[)";
  for (size_t k = 0; k < features.size(); ++k) s += (k ? "," : "") + features[k];
  return s + "]}";
}

// Layers: roads (8 m, round, slope widths): a contour line y = kY0 and a
// line at 45° to the contours through (kX0 + 320, kY0); plan (8 m, no slope
// widths): y = kY0 - 30; zig (5 m, miter) and bev (5 m, bevel): zigzags
// over the cone's south flank, slope widths.
std::string build(const fs::path& dir, std::string& why) {
  std::ofstream(dir / "roads.geojson")
      << collection({feature({{kX0, kY0}, {kX0 + 200, kY0}}),
                     feature({{kX0 + 260, kY0 - 60}, {kX0 + 380, kY0 + 60}})});
  std::ofstream(dir / "plan.geojson")
      << collection({feature({{kX0, kY0 - 30}, {kX0 + 200, kY0 - 30}})});
  std::ofstream(dir / "zig.geojson") << collection({feature({{kConeX - 45, kConeY - 20},
                                                             {kConeX - 25, kConeY - 5},
                                                             {kConeX - 5, kConeY - 25},
                                                             {kConeX + 15, kConeY - 8},
                                                             {kConeX + 35, kConeY - 28}})});
  std::ofstream(dir / "bev.geojson") << collection({feature({{kConeX - 40, kConeY + 12},
                                                             {kConeX - 15, kConeY + 25},
                                                             {kConeX + 5, kConeY + 8},
                                                             {kConeX + 30, kConeY + 22}})});
  return render_test::build_utm_scene(
      dir, "slope.decals",
      {{"roads", "line", "width = 8\ncolor = \"#ffffff\"\nslope_widths = true\n"},
       {"plan", "line", "width = 8\ncolor = \"#ff0000\"\n"},
       {"zig", "line", "width = 5\ncolor = \"#00ff00\"\ncorner = \"miter\"\nslope_widths = true\n"},
       {"bev", "line",
        "width = 5\ncolor = \"#0000ff\"\ncorner = \"bevel\"\nslope_widths = true\n"}},
      why);
}

struct Terrain {
  std::string name;
  std::string dem;
  Height h;
};

// Top-down render of the absolute box `abs` at 2 cm per pixel.
std::optional<R::Image> shoot(const R::DecalSource& src, const R::Heightfield& t,
                              const prep::Extent& abs, bool cpu, R::SlopeWidths mode) {
  const prep::Extent view{abs.xmin - src.frame.origin_x, abs.ymin - src.frame.origin_y,
                          abs.xmax - src.frame.origin_x, abs.ymax - src.frame.origin_y};
  R::RenderOptions opt;
  opt.width = uint32_t(std::lround((abs.xmax - abs.xmin) * 50));
  opt.height = uint32_t(std::lround((abs.ymax - abs.ymin) * 50));
  opt.camera = R::topdown_camera(view, t.zmin, t.zmax);
  opt.slope_widths = mode;
  try {
    return cpu ? R::render_cpu(src, t, opt) : R::render_gl(src, t, opt);
  } catch (const prep::render_error&) {
    return std::nullopt;
  }
}

// The band's ground width in every pixel column of a top-down image of
// `abs`: the two edges (half-way between the last pixel centre outside and
// the first inside) lifted onto the analytic surface `h`, and the distance
// between the lifted edges perpendicular to the lifted centre line, whose
// plan direction is `t` (unit). Columns where the band is cut off are left
// out.
std::vector<double> widths(const R::Image& img, const prep::Extent& abs, const Height& h,
                           std::array<double, 2> t) {
  const double px = (abs.xmax - abs.xmin) / img.width, py = (abs.ymax - abs.ymin) / img.height;
  std::vector<double> out;
  for (uint32_t i = 0; i < img.width; ++i) {
    int first = -1, last = -1;
    for (uint32_t j = 0; j < img.height; ++j)
      if (img.decals[(size_t(j) * img.width + i) * 4 + 3] > 0.5f) {
        if (first < 0) first = int(j);
        last = int(j);
      }
    if (first <= 0 || last < 0 || last + 1 >= int(img.height)) continue;
    const double x = abs.xmin + (i + 0.5) * px;
    const double ya = abs.ymax - first * py, yb = abs.ymax - (last + 1) * py;
    const std::array<double, 3> a{x, ya, h(x, ya)}, b{x, yb, h(x, yb)};
    // The centre line's direction on the surface: (t, dh along t).
    const double eps = 1e-3, xm = x, ym = 0.5 * (ya + yb);
    std::array<double, 3> T{
        t[0], t[1],
        (h(xm + eps * t[0], ym + eps * t[1]) - h(xm - eps * t[0], ym - eps * t[1])) / (2 * eps)};
    const double tl = std::hypot(T[0], T[1], T[2]);
    for (double& c : T) c /= tl;
    std::array<double, 3> d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    const double along = d[0] * T[0] + d[1] * T[1] + d[2] * T[2];
    for (int k = 0; k < 3; ++k) d[k] -= along * T[k];
    out.push_back(std::hypot(d[0], d[1], d[2]));
  }
  return out;
}

// The largest relative error of `w` against `nominal`.
double worst(const std::vector<double>& w, double nominal) {
  double e = 0;
  for (double v : w) e = std::max(e, std::abs(v - nominal) / nominal);
  return e;
}

class SlopeWidths : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = render_test::process_dir("slope_widths");
    std::string why;
    path_ = build(dir_, why);
    why_ = why;
    for (double deg : {30.0, 60.0})
      write_dem((dir_ / ("plane" + std::to_string(int(deg)) + ".tif")).string(), plane(deg),
                kX0 - 20, kY0 + 80, 440, 160, 1.0);
    write_dem((dir_ / "cone.tif").string(), cone, kConeX - 60, kConeY + 60, 240, 240, 0.5);
  }
  static void TearDownTestSuite() { render_test::remove_process_dir(dir_); }
  void SetUp() override {
    ASSERT_FALSE(path_.empty()) << why_;
    ASSERT_TRUE(decal::Package::open(path_, pkg_));
    src_ = R::source_of(pkg_);
  }
  R::Heightfield terrain(const std::string& dem, const prep::Extent& abs) const {
    prep::DemSpec spec;
    spec.path = (dir_ / dem).string();
    const prep::Extent rel{abs.xmin - src_.frame.origin_x, abs.ymin - src_.frame.origin_y,
                           abs.xmax - src_.frame.origin_x, abs.ymax - src_.frame.origin_y};
    return R::load_heightfield(spec, src_.frame, rel);
  }
  // Worst relative width error of the band through the top-down view
  // `abs` on `dem` (surface `h`, line direction `t`), on and off, CPU and
  // GL; false when there is no GL.
  bool check(const char* what, const std::string& dem, const Height& h, const prep::Extent& abs,
             std::array<double, 2> t, double nominal, bool expect_slope) {
    const R::Heightfield ter = terrain(dem, abs);
    for (bool cpu : {true, false}) {
      SCOPED_TRACE(std::string(what) + (cpu ? " cpu" : " gl"));
      const auto on = shoot(src_, ter, abs, cpu, R::SlopeWidths::package);
      const auto off = shoot(src_, ter, abs, cpu, R::SlopeWidths::off);
      if (!on || !off) return false;
      const std::vector<double> w_on = widths(*on, abs, h, t), w_off = widths(*off, abs, h, t);
      EXPECT_GE(w_on.size(), 150u);
      EXPECT_GE(w_off.size(), 150u);
      const double e_on = worst(w_on, nominal), e_off = worst(w_off, nominal);
      std::printf("%-34s %s: ground width error %6.2f%% with slope widths, %6.2f%% without\n", what,
                  cpu ? "cpu" : "gl ", 100 * e_on, 100 * e_off);
      if (expect_slope) {
        EXPECT_LE(e_on, 0.02);
        EXPECT_GT(e_off, e_on + 0.05);
      } else {
        EXPECT_EQ(on->decals, off->decals);  // a layer without slope_widths stays in plan
      }
    }
    return true;
  }

  static inline fs::path dir_;
  static inline std::string path_, why_;
  decal::Package pkg_;
  R::DecalSource src_;
};

TEST_F(SlopeWidths, TheLayerTableRecordsTheKey) {
  const auto meta = nlohmann::json::parse(pkg_.metadata_json());
  ASSERT_EQ(meta.at("layers").size(), 4u);
  EXPECT_EQ(meta["layers"][0]["slope_widths"], true);
  EXPECT_FALSE(meta["layers"][1].contains("slope_widths"));
  EXPECT_EQ(src_.slope_layers, (std::vector<uint8_t>{1, 0, 1, 1, 0}));
  EXPECT_EQ(R::slope_layers(src_, R::SlopeWidths::off), std::vector<uint8_t>{});
  EXPECT_EQ(R::slope_layers(src_, R::SlopeWidths::on), std::vector<uint8_t>{1});
}

// A line along the contours: the plan band is 8 cos(slope) wide, 8 m on the
// ground (without: 8 / cos(slope), 15.5% too wide at 30°, 100% at 60°).
TEST_F(SlopeWidths, AContourLineIsItsWidthOnTheGroundOnPlanes) {
  const prep::Extent abs{kX0 + 98, kY0 - 6, kX0 + 102, kY0 + 6};
  if (!check("plane 30°, contour line", "plane30.tif", plane(30), abs, {1, 0}, kWidth, true) ||
      !check("plane 60°, contour line", "plane60.tif", plane(60), abs, {1, 0}, kWidth, true))
    GTEST_SKIP() << "no headless GL";
}

// 45° to the contours on the 60° plane: the ground distance from the line
// is |v| sqrt(1 + (g.n)^2 / (1 + (g.t)^2)) (evaluate.cpp step 6b); the band
// is 8 m wide measured perpendicular to the line on the surface (without:
// 26.5% too wide).
TEST_F(SlopeWidths, AnObliqueLineIsItsWidthPerpendicularToItOnTheGround) {
  const prep::Extent abs{kX0 + 318, kY0 - 8, kX0 + 322, kY0 + 8};
  if (!check("plane 60°, line at 45°", "plane60.tif", plane(60), abs,
             {std::sqrt(0.5), std::sqrt(0.5)}, kWidth, true))
    GTEST_SKIP() << "no headless GL";
}

// The contour line where it touches the circle r = 40 m of the 45° cone
// (without: 41% too wide).
TEST_F(SlopeWidths, AContourLineIsItsWidthOnTheGroundOnACone) {
  const prep::Extent abs{kConeX - 2, kY0 - 6, kConeX + 2, kY0 + 6};
  if (!check("cone 45°, contour line", "cone.tif", cone, abs, {1, 0}, kWidth, true))
    GTEST_SKIP() << "no headless GL";
}

// The layer without slope_widths keeps its plan width under `auto`.
TEST_F(SlopeWidths, ALayerWithoutTheKeyStaysInPlan) {
  const prep::Extent abs{kX0 + 98, kY0 - 36, kX0 + 102, kY0 - 24};
  const Height level = [](double, double) { return 0.0; };  // plan widths
  if (!check("plane 60°, layer without the key", "plane60.tif", level, abs, {1, 0}, kWidth, false))
    GTEST_SKIP() << "no headless GL";
  const R::Heightfield ter = terrain("plane60.tif", abs);
  const auto cpu = shoot(src_, ter, abs, true, R::SlopeWidths::package);
  ASSERT_TRUE(cpu);
  EXPECT_LE(worst(widths(*cpu, abs, level, {1, 0}), kWidth), 0.01);
}

// CPU and GL on a perspective view of the cone: round, miter and bevel
// lines (corners and ends) with slope widths, pixel by pixel.
TEST_F(SlopeWidths, CpuAndGlAgreeOnTheCone) {
  const prep::Extent abs{kConeX - 55, kY0 - 15, kConeX + 55, kConeY + 40};
  const prep::Extent rel{abs.xmin - src_.frame.origin_x, abs.ymin - src_.frame.origin_y,
                         abs.xmax - src_.frame.origin_x, abs.ymax - src_.frame.origin_y};
  const R::Heightfield ter = terrain("cone.tif", abs);
  R::RenderOptions opt;
  opt.width = 640;
  opt.height = 360;
  opt.camera =
      R::fit_camera(rel, ter.zmin, ter.zmax, opt.width, opt.height, R::Projection::perspective, 40);
  std::optional<R::Image> gl;
  try {
    gl = R::render_gl(src_, ter, opt);
  } catch (const prep::render_error&) {
    GTEST_SKIP() << "no headless GL";
  }
  const R::Image cpu = R::render_cpu(src_, ter, opt);
  const render_test::Agreement a = render_test::agreement(cpu.decals, gl->decals);
  std::printf("cone, perspective 640x360: CPU and GL agree on %zu of %zu pixels (%.3f%%)\n",
              a.agree, a.considered, 100 * a.ratio());
  EXPECT_GE(a.considered, 5000u);
  EXPECT_GE(a.ratio(), 0.999);
  {  // the blobs as buffer textures (the layer of a line read from its texel)
    R::RenderOptions o = opt;
    o.binding = R::Binding::texture;
    const render_test::Agreement t =
        render_test::agreement(cpu.decals, R::render_gl(src_, ter, o).decals);
    std::printf("  --binding texture: %zu of %zu pixels (%.3f%%)\n", t.agree, t.considered,
                100 * t.ratio());
    EXPECT_GE(t.ratio(), 0.999);
  }
  for (R::AntiAliasing aa : {R::AntiAliasing::coverage, R::AntiAliasing::msaa4}) {
    // The anti-aliased passes draw the same bands (coverage: within a pixel).
    R::RenderOptions o = opt;
    o.aa = aa;
    const R::Image img = R::render_gl(src_, ter, o);
    size_t far = 0;
    for (size_t k = 3; k < img.decals.size(); k += 4)
      far += (img.decals[k] > 0.5f) != (cpu.decals[k] > 0.5f);
    EXPECT_LT(far, a.considered / 10) << (aa == R::AntiAliasing::coverage ? "coverage" : "msaa4");
  }
  // The slope changes this view: off, the bands are wider.
  opt.slope_widths = R::SlopeWidths::off;
  const R::Image plan = R::render_cpu(src_, ter, opt);
  size_t wider = 0, narrower = 0;
  for (size_t k = 3; k < plan.decals.size(); k += 4) {
    wider += plan.decals[k] > 0.5f && cpu.decals[k] <= 0.5f;
    narrower += plan.decals[k] <= 0.5f && cpu.decals[k] > 0.5f;
  }
  EXPECT_GT(wider, a.considered / 10);
  EXPECT_EQ(narrower, 0u);  // the ground band lies inside the plan band
}

TEST(SlopeWidthsScene, LayersWithoutAStaticWidthAreRefusedNamingTheKey) {
  const fs::path dir = fs::current_path() / "render-out" / "slope_widths_bad";
  fs::create_directories(dir);
  std::ofstream(dir / "a.geojson") << collection({feature({{kX0, kY0}, {kX0 + 10, kY0}})});
  auto scene = [&](const std::string& extra) {
    return render_test::build_layer_a(dir, "slope_widths = true\n" + extra);
  };
  for (const char* extra : {"kind = \"polygon\"\n", "kind = \"line\"\ndynamic = true\n"}) {
    const auto r = scene(extra);
    EXPECT_EQ(r.rc, 3) << r.output;
    EXPECT_NE(r.output.find("slope_widths needs a static line layer"), std::string::npos)
        << r.output;
  }
}

TEST_F(SlopeWidths, RenderRefusesBadOptionValues) {
  const std::string out = (dir_ / "x.png").string();
  auto r = run_tool("render " + path_ + " --cpu --flat --slope-widths sometimes -o " + out);
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("--slope-widths 'sometimes' must be auto, on or off"), std::string::npos)
      << r.output;
  r = run_tool("render " + path_ + " --flat --method volume --slope-widths on -o " + out);
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("--slope-widths on needs --method decal"), std::string::npos) << r.output;
  r = run_tool("render " + path_ + " --cpu --dem " + (dir_ / "cone.tif").string() +
               " --slope-widths on --size 64x36 -o " + out);
  EXPECT_EQ(r.rc, 0) << r.output;
}

}  // namespace

}  // namespace render_slope_widths
