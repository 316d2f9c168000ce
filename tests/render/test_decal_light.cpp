// Lit decals (render --decal-light, formats/SPEC.md "Lit decals"): the
// static decal layer times the terrain pass's Lambert shade.
//  - Over an inclined plane (normal known in closed form), a pixel of an
//    opaque polygon is rgb x shade(normal) within 2/255: the CPU image, GL
//    and GL's volume and texture methods; off, it is rgb; the decal layer
//    (Image::decals) is the same unlit colour either way.
//  - A layer flagged unlit (scene key light = false) keeps its colour over
//    the plane while a lit layer over it is shaded: the CPU image, GL and
//    GL's volume method, each pixel against the analytic mix; the texture
//    method lights its whole texture.
//  - Over Monaco's SRTM terrain (the sample package, oblique view), GL and
//    the CPU image agree on the lit decal pixels.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "decal/reader.hpp"
#include "hand_model.hpp"
#include "prep/dem.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_decal_light {

namespace R = prep::render;

namespace {

// z = kA x + kB y over [-20, 120]², 5 m cells: every interior vertex normal
// (central differences) is the plane's.
constexpr double kA = 0.6, kB = -0.35;

R::Heightfield plane() {
  R::Heightfield t;
  t.x0 = -20, t.y0 = -20, t.dx = 5, t.dy = 5, t.nx = 29, t.ny = 29;
  t.z.resize(size_t(t.nx) * t.ny);
  for (uint32_t j = 0; j < t.ny; ++j)
    for (uint32_t i = 0; i < t.nx; ++i)
      t.z[i + size_t(t.nx) * j] = 100 + kA * (t.x0 + i * t.dx) + kB * (t.y0 + j * t.dy);
  t.zmin = *std::min_element(t.z.begin(), t.z.end());
  t.zmax = *std::max_element(t.z.begin(), t.z.end());
  t.surface_error_bound = 0;
  return t;
}

// The analytic shade: 0.35 + 0.65 max(n . l, 0), n the plane's unit normal,
// l the renderer's light direction (-0.4, -0.5, 0.75) normalised.
double analytic_shade() {
  const double n[3] = {-kA, -kB, 1}, l[3] = {-0.4, -0.5, 0.75};
  const double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  const double ll = std::sqrt(l[0] * l[0] + l[1] * l[1] + l[2] * l[2]);
  const double d = (n[0] * l[0] + n[1] * l[1] + n[2] * l[2]) / (nn * ll);
  return 0.35 + 0.65 * std::max(d, 0.0);
}

std::optional<R::Image> draw(const R::DecalSource& src, bool cpu, bool light,
                             R::Method method = R::Method::decal,
                             R::AntiAliasing aa = R::AntiAliasing::none) {
  R::RenderOptions opt;
  opt.method = method;
  opt.aa = aa;
  opt.width = opt.height = 100;
  // Top-down over the model's [0, 100]² (the camera looks straight down at
  // the inclined plane).
  opt.camera = R::topdown_camera({0, 0, 100, 100}, 0, 300);
  opt.decal_light = light;
  try {
    return cpu ? R::render_cpu(src, plane(), opt) : R::render_gl(src, plane(), opt);
  } catch (const prep::render_error&) {
    return std::nullopt;
  }
}

}  // namespace

TEST(DecalLight, AnOpaquePolygonOverAPlaneIsItsColourTimesTheAnalyticShade) {
  const prep::DecalModel model = render_test::hand_model();
  const R::DecalSource src = R::source_of(model);
  const double s = analytic_shade();
  ASSERT_GT(s, 0.4);
  ASSERT_LT(s, 0.99);
  const uint32_t rgba = render_test::HandShapes::kPolyRgba;
  const double rgb[3] = {double(rgba & 0xff) / 255, double((rgba >> 8) & 0xff) / 255,
                         double((rgba >> 16) & 0xff) / 255};
  struct Case {
    const char* name;
    bool cpu;
    R::Method method;
  };
  for (const Case& m : {Case{"cpu", true, R::Method::decal}, Case{"gl", false, R::Method::decal},
                        Case{"gl volume", false, R::Method::volume},
                        Case{"gl texture", false, R::Method::texture}}) {
    SCOPED_TRACE(m.name);
    const bool cpu = m.cpu;
    const auto lit = draw(src, cpu, true, m.method), flat = draw(src, cpu, false, m.method);
    if (!lit || !flat) {
      ASSERT_FALSE(cpu);
      GTEST_SKIP() << "no headless GL";
    }
    // Pixels whose centres lie in the exterior ring [20, 80]² off the hole
    // [40, 60]² and the two diagonal lines: (x, y) = (25..35, 62..78).
    size_t checked = 0;
    for (uint32_t j = 22; j <= 37; ++j)
      for (uint32_t i = 25; i <= 35; ++i) {
        const double x = i + 0.5, y = 100 - (j + 0.5);
        if (!render_test::HandShapes::in_polygon(x, y) || render_test::HandShapes::in_line(x, y) ||
            render_test::HandShapes::in_line2(x, y))
          continue;
        const size_t k = size_t(j) * 100 + i;
        for (int c = 0; c < 3; ++c) {
          EXPECT_NEAR(lit->rgba[4 * k + c], 255 * rgb[c] * s, 2.0) << i << "," << j << " ch " << c;
          EXPECT_NEAR(flat->rgba[4 * k + c], 255 * rgb[c], 2.0) << i << "," << j << " ch " << c;
          EXPECT_EQ(lit->decals[4 * k + c], flat->decals[4 * k + c]);
          EXPECT_NEAR(lit->decals[4 * k + c], rgb[c], 1e-4);  // the texture: filtered
        }
        ++checked;
      }
    EXPECT_GT(checked, 60u);
  }
}

TEST(DecalLight, AnUnlitLayerKeepsItsColourWhileALitLineOverItIsShaded) {
  prep::DecalModel model = render_test::hand_model();
  for (auto& p : model.poly_props) p.layer = 1;  // the polygons: layer 1, the lines: layer 0
  R::DecalSource src = R::source_of(model);
  src.unlit_layers = {0, 1, 0};
  const double s = analytic_shade();
  auto rgb = [](uint32_t rgba, int c) { return double((rgba >> (8 * c)) & 0xff) / 255; };
  const uint32_t poly = render_test::HandShapes::kPolyRgba;
  const uint32_t line = render_test::HandShapes::kLineRgba;
  const double a_line = double(line >> 24) / 255;
  struct Case {
    const char* name;
    bool cpu;
    R::Method method;
    R::AntiAliasing aa;
  };
  for (const Case& m : {Case{"cpu", true, R::Method::decal, R::AntiAliasing::none},
                        Case{"gl", false, R::Method::decal, R::AntiAliasing::none},
                        Case{"gl msaa4", false, R::Method::decal, R::AntiAliasing::msaa4},
                        Case{"gl coverage", false, R::Method::decal, R::AntiAliasing::coverage},
                        Case{"gl volume", false, R::Method::volume, R::AntiAliasing::none},
                        Case{"gl texture", false, R::Method::texture, R::AntiAliasing::none}}) {
    SCOPED_TRACE(m.name);
    const auto img = draw(src, m.cpu, true, m.method, m.aa);
    if (!img) {
      ASSERT_FALSE(m.cpu);
      GTEST_SKIP() << "no headless GL";
    }
    // The texture method lights its whole texture, unlit layers too.
    const double poly_light = m.method == R::Method::texture ? s : 1.0;
    size_t plain = 0, mixed = 0;
    for (uint32_t j = 0; j < 100; ++j)
      for (uint32_t i = 0; i < 100; ++i) {
        const double x = i + 0.5, y = 100 - (j + 0.5);
        // Whole pixels only: none within a pixel of an edge or a line side.
        bool whole = true;
        for (double dx : {-1.0, 0.0, 1.0})
          for (double dy : {-1.0, 0.0, 1.0})
            whole = whole &&
                    render_test::HandShapes::in_polygon(x + dx, y + dy) ==
                        render_test::HandShapes::in_polygon(x, y) &&
                    render_test::HandShapes::in_line(x + dx, y + dy) ==
                        render_test::HandShapes::in_line(x, y) &&
                    !render_test::HandShapes::in_line2(x + dx, y + dy);
        if (!whole || !render_test::HandShapes::in_polygon(x, y)) continue;
        if (x > 39 && x < 61 && y > 39 && y < 61) continue;  // the hole and the green island
        const bool on_line = render_test::HandShapes::in_line(x, y);
        const size_t k = size_t(j) * 100 + i;
        for (int c = 0; c < 3; ++c) {
          // The lit line over the unlit polygon: a_line rgb_line s + (1 - a_line) rgb_poly.
          const double want =
              on_line ? a_line * rgb(line, c) * s + (1 - a_line) * rgb(poly, c) * poly_light
                      : rgb(poly, c) * poly_light;
          EXPECT_NEAR(img->rgba[4 * k + c], 255 * want, 2.0) << i << "," << j << " ch " << c;
          // The decal layer (--decals) stays the unlit colour.
          if (!on_line) {
            EXPECT_NEAR(img->decals[4 * k + c], rgb(poly, c), 1e-3);
          }
        }
        (on_line ? mixed : plain) += 1;
      }
    EXPECT_GT(plain, 500u);
    EXPECT_GT(mixed, 30u);
  }
}

TEST(DecalLight, TheLayerTableRecordsLightFalseAndTheRendererReadsIt) {
  const std::filesystem::path dir = render_test::process_dir("decal_light");
  std::ofstream(dir / "fields.geojson")
      << R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},)"
         R"("features":[{"type":"Feature","properties":{},)"
         R"("geometry":{"type":"Polygon","coordinates":[[[500000,5000000],[500050,5000000],)"
         R"([500050,5000050],[500000,5000000]]]}}]})";
  std::ofstream(dir / "paths.geojson")
      << R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},)"
         R"("features":[{"type":"Feature","properties":{},)"
         R"("geometry":{"type":"LineString","coordinates":[[500000,5000010],[500050,5000010]]}}]})";
  std::string why;
  const std::string path =
      render_test::build_utm_scene(dir, "light.decals",
                                   {{"paths", "line", "width = 4\ncolor = \"#ffffff\"\n"},
                                    {"fields", "polygon", "color = \"#40a040\"\nlight = false\n"}},
                                   why);
  ASSERT_FALSE(path.empty()) << why;
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path, pkg));
  const auto meta = nlohmann::json::parse(pkg.metadata_json());
  ASSERT_EQ(meta.at("layers").size(), 2u);
  EXPECT_FALSE(meta["layers"][0].contains("light"));
  EXPECT_EQ(meta["layers"][1]["light"], false);
  EXPECT_EQ(R::source_of(pkg).unlit_layers, (std::vector<uint8_t>{0, 1, 0}));
  render_test::remove_process_dir(dir);
}

TEST(DecalLight, GlAndCpuAgreeOnLitDecalPixelsOverMonacoTerrain) {
  std::string why;
  const std::string path = render_test::monaco_package(&why);
  if (path.empty()) GTEST_SKIP() << why;
  decal::Package package;
  ASSERT_TRUE(decal::Package::open(path, package));
  const R::DecalSource src = R::source_of(package);
  prep::DemSpec dem;
  dem.path = "/vsizip/" + prep::test::monaco_sample("N43E007.hgt.zip") + "/N43E007.hgt";
  const R::Heightfield terrain = R::load_heightfield(dem, src.frame, src.extent);
  R::RenderOptions opt;
  opt.width = 640, opt.height = 360;
  opt.camera = R::fit_camera(src.extent, terrain.zmin, terrain.zmax, opt.width, opt.height,
                             R::Projection::perspective, 35);
  opt.draw_dynamic = false;
  std::optional<R::Image> gl;
  try {
    gl = R::render_gl(src, terrain, opt);
  } catch (const prep::render_error& e) {
    GTEST_SKIP() << "no headless GL: " << e.what();
  }
  const R::Image cpu = R::render_cpu(src, terrain, opt);
  size_t decal = 0, agree = 0, lit = 0;
  for (size_t k = 0; k < size_t(opt.width) * opt.height; ++k) {
    // Opaque decal pixels of both layers (edges aside: GL and CPU may put
    // an edge pixel on either side).
    if (cpu.decals[4 * k + 3] < 0.999f || gl->decals[4 * k + 3] < 0.999f) continue;
    ++decal;
    bool ok = true;
    for (int c = 0; c < 3; ++c)
      ok = ok && std::abs(int(gl->rgba[4 * k + c]) - int(cpu.rgba[4 * k + c])) <= 2;
    agree += ok;
    // Lit: darker than the layer's own colour somewhere (the shade < 1).
    lit += double(cpu.rgba[4 * k]) < 255.0 * cpu.decals[4 * k] - 8;
  }
  std::printf(
      "Monaco, lit decals: %zu of %zu opaque decal pixels agree within 2/255 (GL, CPU); %zu "
      "darker than their unlit colour\n",
      agree, decal, lit);
  EXPECT_GT(decal, 20000u);
  EXPECT_GT(lit, decal / 2);
  EXPECT_GE(double(agree), 0.999 * double(decal));
}

}  // namespace render_decal_light
