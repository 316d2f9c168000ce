// Dashed lines (scene file `dash`, formats/SPEC.md "Dashed lines"): static
// dashes in ground metres, dynamic dashes in screen pixels, both measured
// along the line from its start and continuous across corners.
//  - the CPU evaluator (and dynamic_cpu) and GL agree on the pixels of a
//    scene of cased, dashed lines at every corner style, static and
//    dynamic, top-down and in perspective;
//  - the on/off transitions along an L-shaped line whose dash period does
//    not divide its first leg lie where the analytic cumulative length
//    puts them (CPU and GL);
//  - the layer table records the pattern (the casing copy stays solid),
//    and bad patterns are refused naming the file, the key and the value.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_dashes {

namespace fs = std::filesystem;
namespace R = prep::render;
using prep::test::run_tool;

namespace {

constexpr double kX0 = 500000, kY0 = 4800000;

std::string linestring(const std::vector<std::array<double, 2>>& pts) {
  std::string s =
      R"({"type":"Feature","properties":{},"geometry":{"type":"LineString","coordinates":[)";
  for (size_t i = 0; i < pts.size(); ++i)
    s += (i ? ",[" : "[") + std::to_string(kX0 + pts[i][0]) + "," +
         std::to_string(kY0 + pts[i][1]) + "]";
  return s + "]}}";
}

std::string collection(const std::vector<std::string>& features) {
  std::string s =
      R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},"features":[)";
  for (size_t i = 0; i < features.size(); ++i) s += (i ? "," : "") + features[i];
  return s + "]}";
}

std::string build(const fs::path& dir, const std::string& scene, std::string& why) {
  std::ofstream(dir / "scene.toml") << scene;
  const std::string pkg = (dir / "dashes.decals").string();
  const auto r = run_tool("build " + (dir / "scene.toml").string() + " -o " + pkg + " -q");
  if (r.rc != 0) why = r.output;
  return r.rc == 0 ? pkg : "";
}

// A zigzag with corners turning both ways at 90, 60, 120 and 30 degrees.
std::vector<std::array<double, 2>> zigzag(double x, double y) {
  return {{x, y},           {x + 23, y},      {x + 23, y + 17}, {x + 37, y + 41},
          {x + 51, y + 17}, {x + 78, y + 21}, {x + 60, y + 30}, {x + 75, y + 48}};
}

struct Shot {
  R::Image img;
  prep::Extent view;  // absolute
  double ppm;         // pixels per metre
};

std::optional<R::Image> render(const R::DecalSource& src, const prep::Extent& rel,
                               const R::RenderOptions& opt, bool cpu) {
  try {
    return cpu ? R::render_cpu(src, R::flat_heightfield(rel), opt)
               : R::render_gl(src, R::flat_heightfield(rel), opt);
  } catch (const prep::render_error&) {
    return std::nullopt;
  }
}

// Top-down at `ppm` pixels per metre over `abs`.
std::optional<Shot> shoot(const R::DecalSource& src, const prep::Extent& abs, double ppm, bool cpu,
                          R::AntiAliasing aa = R::AntiAliasing::none) {
  const prep::Extent rel{abs.xmin - src.frame.origin_x, abs.ymin - src.frame.origin_y,
                         abs.xmax - src.frame.origin_x, abs.ymax - src.frame.origin_y};
  R::RenderOptions opt;
  opt.width = uint32_t(std::lround((abs.xmax - abs.xmin) * ppm));
  opt.height = uint32_t(std::lround((abs.ymax - abs.ymin) * ppm));
  opt.camera = R::topdown_camera(rel, 0, 0);
  opt.aa = aa;
  auto img = render(src, rel, opt, cpu);
  if (!img) return std::nullopt;
  return Shot{std::move(*img), abs, ppm};
}

// Straight-alpha RGBA of a layer at absolute (x, y).
std::array<float, 4> at(const Shot& s, const std::vector<float>& layer, double x, double y) {
  const size_t i = size_t((x - s.view.xmin) * s.ppm), j = size_t((s.view.ymax - y) * s.ppm);
  const float* p = &layer[(j * s.img.width + i) * 4];
  return {p[0], p[1], p[2], p[3]};
}

// The analytic rule: s in an "on" interval of [on, off, ...] repeated.
bool analytic_on(const std::vector<double>& pattern, double s) {
  double period = 0;
  for (double x : pattern) period += x;
  double r = std::fmod(s, period), a = 0;
  for (size_t i = 0; i < pattern.size(); ++i) {
    if (r < a + pattern[i]) return i % 2 == 0;
    a += pattern[i];
  }
  return false;
}

constexpr const char* kCorners[3] = {"round", "miter", "bevel"};

TEST(Dashes, CpuAndGlAgreeOnCasedDashedLinesAtEveryCornerStyle) {
  const fs::path dir = fs::current_path() / "render-out" / "dashes_agree";
  fs::create_directories(dir);
  // Per corner style a static zigzag (4 m wide, 1 m casing, dash 5 m on,
  // 2.5 m off) and a dynamic one (9 px, 2 px casing, dash 24 px on, 12 off),
  // moved off the pixel grid so that no band edge passes through a row of
  // pixel centres (a tie there is decided by float rounding).
  std::string scene = "crs = \"EPSG:32632\"\nresolution = 0\n";
  for (int c = 0; c < 3; ++c) {
    const std::string st = std::string("s_") + kCorners[c], dy = std::string("d_") + kCorners[c];
    std::ofstream(dir / (st + ".geojson")) << collection({linestring(zigzag(0, 60.0 * c))});
    std::ofstream(dir / (dy + ".geojson"))
        << collection({linestring(zigzag(100.37, 60.0 * c + 0.21))});
    scene += "[[layer]]\nname = \"" + st + "\"\nsource = \"" + st +
             ".geojson\"\nkind = \"line\"\nwidth = 4\ncolor = \"#ffffff\"\ncasing_width = 1\n"
             "casing_color = \"#202020\"\ndash = [5, 2.5]\ncorner = \"" +
             kCorners[c] + "\"\n";
    scene += "[[layer]]\nname = \"" + dy + "\"\nsource = \"" + dy +
             ".geojson\"\nkind = \"line\"\ndynamic = true\nwidth = 9\ncolor = \"#ffcc00\"\n"
             "casing_width = 2\ndash = [24, 12]\ncorner = \"" +
             kCorners[c] + "\"\n";
  }
  // A wave of 1200 vertices, static and dynamic, dashed: the dynamic
  // pass's scan of screen lengths runs over several blocks of 256 kept
  // vertices, with lines starting inside a block.
  std::vector<std::array<double, 2>> wave;
  for (int k = 0; k < 1200; ++k)
    wave.push_back({2 + 0.15 * k, 178 + 3 * std::sin(0.05 * k) + 0.013});
  std::ofstream(dir / "wave.geojson") << collection({linestring(wave)});
  scene +=
      "[[layer]]\nname = \"wave\"\nsource = \"wave.geojson\"\nkind = \"line\"\nwidth = 1.5\n"
      "color = \"#80ffff\"\ndash = [3, 1, 0.5, 1]\n";
  scene +=
      "[[layer]]\nname = \"dwave\"\nsource = \"wave.geojson\"\nkind = \"line\"\n"
      "dynamic = true\nwidth = 3\ncolor = \"#ff80ff\"\ndash = [10, 6]\n";
  std::string why;
  const std::string path = build(dir, scene, why);
  ASSERT_FALSE(path.empty()) << why;
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path, pkg));
  const R::DecalSource src = R::source_of(pkg);
  const prep::Extent abs{kX0 - 5, kY0 - 5, kX0 + 185, kY0 + 185};
  const prep::Extent rel{abs.xmin - src.frame.origin_x, abs.ymin - src.frame.origin_y,
                         abs.xmax - src.frame.origin_x, abs.ymax - src.frame.origin_y};
  // Top-down at 4 px/m, then an oblique perspective view of the same.
  std::vector<std::pair<std::string, R::RenderOptions>> views;
  R::RenderOptions top;
  top.width = 760;
  top.height = 760;
  top.camera = R::topdown_camera(rel, 0, 0);
  views.emplace_back("top-down", top);
  R::RenderOptions tex = top;  // the blobs as buffer textures
  tex.binding = R::Binding::texture;
  views.emplace_back("top-down, buffer textures", tex);
  R::RenderOptions persp;
  persp.width = 800;
  persp.height = 600;
  persp.camera =
      R::fit_camera(rel, 0, 0, persp.width, persp.height, R::Projection::perspective, 40);
  views.emplace_back("perspective", persp);
  for (const auto& [name, opt] : views) {
    SCOPED_TRACE(name);
    const auto cpu = render(src, rel, opt, true);
    const auto gl = render(src, rel, opt, false);
    ASSERT_TRUE(cpu);
    if (!gl) GTEST_SKIP() << "no headless GL";
    const auto st = render_test::agreement(cpu->decals, gl->decals);
    const auto dy = render_test::agreement(cpu->dynamic, gl->dynamic);
    std::cout << name << ": static " << st.agree << "/" << st.considered << ", dynamic " << dy.agree
              << "/" << dy.considered << "\n";
    EXPECT_GT(st.considered, 20000u);
    EXPECT_GT(dy.considered, 5000u);
    EXPECT_GE(st.ratio(), 0.999);
    EXPECT_GE(dy.ratio(), 0.999);
    // The dashes show: a good share of each line's band is off (the casing
    // shows through), so the agreement is not that of solid lines.
    size_t white = 0, dark = 0;
    for (size_t p = 0; p + 3 < cpu->decals.size(); p += 4) {
      if (cpu->decals[p + 3] < 0.99) continue;
      (cpu->decals[p] > 0.9 ? white : dark) += 1;
    }
    EXPECT_GT(dark, white / 4) << "casing pixels " << dark << ", fill pixels " << white;
    // The volume method (static lines as prisms over their pieces, cut to
    // their dashes) against the evaluator: rasterisation differs from the
    // pixel-centre test only on band edges.
    R::RenderOptions vol = opt;
    vol.method = R::Method::volume;
    vol.draw_dynamic = false;
    const auto v = render(src, rel, vol, false);
    ASSERT_TRUE(v);
    const auto va = render_test::agreement(cpu->decals, v->decals);
    std::cout << name << ": volume static " << va.agree << "/" << va.considered << "\n";
    EXPECT_GE(va.ratio(), 0.99);
  }
}

// Transitions along a centreline: the positions (metres along `dir` from
// `from`) where the layer's coverage changes between probes `step` apart.
std::vector<double> transitions(const Shot& s, const std::vector<float>& layer,
                                std::array<double, 2> from, std::array<double, 2> dir, double t0,
                                double t1, double step) {
  std::vector<double> out;
  bool prev = false;
  for (double t = t0; t <= t1; t += step) {
    const bool on = at(s, layer, from[0] + dir[0] * t, from[1] + dir[1] * t)[3] > 0.5;
    if (t > t0 && on != prev) out.push_back(t - 0.5 * step);
    prev = on;
  }
  return out;
}

// The analytic transitions of `pattern` for s in (s0, s1).
std::vector<double> analytic_transitions(const std::vector<double>& pattern, double s0, double s1) {
  std::vector<double> out;
  double s = 0;
  for (size_t i = 0; s < s1; i = (i + 1) % pattern.size()) {
    s += pattern[i];
    if (s > s0 && s < s1) out.push_back(s);
  }
  return out;
}

TEST(Dashes, PhaseIsContinuousAcrossACorner) {
  const fs::path dir = fs::current_path() / "render-out" / "dashes_phase";
  fs::create_directories(dir);
  // An L: 13 m east, then 20 m north. Static dash [2, 1] m (period 3 does
  // not divide 13); dynamic the same at 10 px/m: [20, 10] px. Phase on the
  // second leg: s = 13 + y (metres), so its first transitions are at y = 1
  // (s = 14: off) and y = 2 (s = 15: on), not at y = 2 and 3 as a restart
  // at the corner would give.
  std::ofstream(dir / "st.geojson") << collection({linestring({{0, 0}, {13, 0}, {13, 20}})});
  std::ofstream(dir / "dy.geojson") << collection({linestring({{40, 0}, {53, 0}, {53, 20}})});
  std::string why;
  const std::string path = build(
      dir,
      render_test::utm_scene_toml(
          {{"st", "line", "width = 1\ncolor = \"#ffffff\"\ndash = [2, 1]\ncorner = \"miter\"\n"},
           {"dy", "line",
            "dynamic = true\nwidth = 5\ncolor = \"#ffffff\"\ndash = [20, 10]\n"
            "corner = \"miter\"\n"}}),
      why);
  ASSERT_FALSE(path.empty()) << why;
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path, pkg));
  const R::DecalSource src = R::source_of(pkg);
  const std::vector<double> pattern{2, 1};
  for (bool cpu : {true, false}) {
    SCOPED_TRACE(cpu ? "cpu" : "gl");
    const auto s = shoot(src, {kX0 - 2, kY0 - 2, kX0 + 56, kY0 + 22}, 10, cpu);
    if (!s) {
      ASSERT_FALSE(cpu);
      GTEST_SKIP() << "no headless GL";
    }
    for (bool dynamic : {false, true}) {
      SCOPED_TRACE(dynamic ? "dynamic" : "static");
      const auto& layer = dynamic ? s->img.dynamic : s->img.decals;
      const double x0 = kX0 + (dynamic ? 40 : 0), y0 = kY0;
      // Probes every 0.02 m along each leg's centreline, off the pixel
      // edges (0.1 m pixels: centres at .05), away from the corner's join
      // region (the other leg's band within 1 m of the corner).
      const auto leg1 = transitions(*s, layer, {x0, y0 + 0.03}, {1, 0}, 0.3, 11.5, 0.02);
      const auto leg2 = transitions(*s, layer, {x0 + 13.03, y0}, {0, 1}, 1.5, 19.7, 0.02);
      const auto want1 = analytic_transitions(pattern, 0.3, 11.5);
      auto want2 = analytic_transitions(pattern, 13 + 1.5, 13 + 19.7);
      for (double& w : want2) w -= 13;
      ASSERT_EQ(leg1.size(), want1.size());
      ASSERT_EQ(leg2.size(), want2.size());
      // Within one pixel (0.1 m): a pixel is on where its centre is.
      for (size_t k = 0; k < leg1.size(); ++k) EXPECT_NEAR(leg1[k], want1[k], 0.1) << k;
      for (size_t k = 0; k < leg2.size(); ++k) EXPECT_NEAR(leg2[k], want2[k], 0.1) << k;
      // And every probe a pixel or more from a transition matches the rule.
      size_t checked = 0;
      for (double y = 1.5; y <= 19.7; y += 0.1) {
        const double yc = std::floor(y * 10) / 10 + 0.05;  // pixel centre
        const double sv = 13 + yc;
        bool near_edge = false;
        for (double w : analytic_transitions(pattern, sv - 0.15, sv + 0.15))
          near_edge |= std::abs(w - sv) < 0.15;
        if (near_edge) continue;
        EXPECT_EQ(at(*s, layer, x0 + 13.03, y0 + yc)[3] > 0.5, analytic_on(pattern, sv))
            << "y " << yc;
        ++checked;
      }
      EXPECT_GT(checked, 100u);
    }
  }
}

// shared_edges = "once" (formats/SPEC.md "Dashed lines"): two squares of
// one dashed outline layer share the edge x = 10. Drawn once, the samples
// along it every 0.1 m fit the analytic rule of one line, on where
// (phase +- y) mod 5 < 3 for dash [3, 2], for some phase and direction (the
// ring's start is clean's); drawn by both rings ("all", as before), they
// are the union of two phases and fit none.
TEST(Dashes, SharedEdgesOnceDrawABoundaryWithOnePhase) {
  const std::vector<double> pattern{3, 2};
  auto square = [](double x0) {
    std::string s =
        R"({"type":"Feature","properties":{},"geometry":{"type":"Polygon","coordinates":[[)";
    const double c[5][2] = {{x0, 0}, {x0 + 10, 0}, {x0 + 10, 10}, {x0, 10}, {x0, 0}};
    for (int i = 0; i < 5; ++i)
      s += (i ? ",[" : "[") + std::to_string(kX0 + c[i][0]) + "," + std::to_string(kY0 + c[i][1]) +
           "]";
    return s + "]]}}";
  };
  // The fewest samples a phase leaves unexplained (those within 0.06 m of
  // one of its transitions do not count), over phases every 0.01 m and
  // both directions; -1 without GL or CPU image.
  auto fit = [&](const std::string& mode, bool cpu, size_t& samples) -> long {
    const fs::path dir = fs::current_path() / "render-out" / ("dashes_shared_" + mode);
    fs::create_directories(dir);
    std::ofstream(dir / "sq.geojson") << collection({square(0), square(10)});
    std::string why;
    const std::string keys =
        "width = 0.5\ncolor = \"#ffffff\"\ndash = [3, 2]\nshared_edges = \"" + mode + "\"\n";
    const std::string path =
        build(dir, render_test::utm_scene_toml({{"sq", "outline", keys.c_str()}}), why);
    EXPECT_FALSE(path.empty()) << why;
    if (path.empty()) return -1;
    decal::Package pkg;
    EXPECT_TRUE(decal::Package::open(path, pkg));
    const R::DecalSource src = R::source_of(pkg);
    const auto shot = shoot(src, {kX0 - 2, kY0 - 2, kX0 + 22, kY0 + 12}, 10, cpu);
    if (!shot) return -1;
    std::vector<std::pair<double, bool>> on;
    for (double y = 1.05; y < 9.0; y += 0.1)
      on.emplace_back(y, at(*shot, shot->img.decals, kX0 + 10.03, kY0 + y)[3] > 0.5);
    samples = on.size();
    long best = long(on.size());
    for (int d : {1, -1})
      for (int k = 0; k < 500; ++k) {
        const double phase = 0.01 * k;
        long miss = 0;
        for (const auto& [y, lit] : on) {
          const double sv = phase + d * y + 100;
          const double r = std::fmod(sv, 5.0);
          if (std::min({r, std::abs(r - 3), 5 - r}) < 0.06) continue;
          miss += lit != analytic_on(pattern, sv);
        }
        best = std::min(best, miss);
      }
    return best;
  };
  size_t samples = 0;
  for (bool cpu : {true, false}) {
    SCOPED_TRACE(cpu ? "cpu" : "gl");
    const long once = fit("once", cpu, samples);
    if (once < 0 && !cpu) GTEST_SKIP() << "no headless GL";
    ASSERT_GE(once, 0);
    EXPECT_EQ(once, 0) << "of " << samples << " samples";
    const long all = fit("all", cpu, samples);
    EXPECT_GT(all, 10) << "of " << samples << " samples: two phases should fit no single line";
    std::printf("%s, shared edge, %zu samples: once leaves %ld unexplained, all %ld\n",
                cpu ? "cpu" : "gl", samples, once, all);
  }
}

TEST(Dashes, LayerTableRecordsThePatternAndTheCasingStaysSolid) {
  const fs::path dir = fs::current_path() / "render-out" / "dashes_table";
  fs::create_directories(dir);
  std::ofstream(dir / "a.geojson") << collection({linestring({{0, 0}, {30, 0}})});
  std::string why;
  const std::string path = build(
      dir,
      render_test::utm_scene_toml(
          {{"a", "line",
            "width = 2\ncolor = \"#ffffff\"\ndash = [3, 1.5, 0.5, 1.5]\ncasing_width = 1\n"}}),
      why);
  ASSERT_FALSE(path.empty()) << why;
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path, pkg));
  const auto meta = nlohmann::json::parse(pkg.metadata_json());
  ASSERT_EQ(meta.at("layers").size(), 2u);
  EXPECT_EQ(meta["layers"][0]["name"], "a.casing");
  EXPECT_FALSE(meta["layers"][0].contains("dash"));
  EXPECT_EQ(meta["layers"][1]["dash"], nlohmann::json::parse("[3, 1.5, 0.5, 1.5]"));
  // Probes along the centreline: the casing is there all along, the fill
  // (white over the casing) only in the dashes.
  const R::DecalSource src = R::source_of(pkg);
  const auto s = shoot(src, {kX0 - 2, kY0 - 4, kX0 + 32, kY0 + 4}, 10, true);
  ASSERT_TRUE(s);
  const std::vector<double> pattern{3, 1.5, 0.5, 1.5};
  for (double x = 0.35; x < 28; x += 0.1) {
    const auto c = at(*s, s->img.decals, kX0 + x, kY0 + 0.05);
    bool near_edge = false;
    for (double w : analytic_transitions(pattern, x - 0.1, x + 0.1))
      near_edge |= std::abs(w - x) < 0.1;
    if (near_edge) continue;
    EXPECT_NEAR(c[3], 1.0, 1e-3) << x;
    EXPECT_EQ(c[0] > 0.9, analytic_on(pattern, x)) << x;
  }
}

TEST(Dashes, BadPatternsAreRefusedNamingTheKeyAndValue) {
  const fs::path dir = fs::current_path() / "render-out" / "dashes_bad";
  fs::create_directories(dir);
  std::ofstream(dir / "a.geojson") << collection({linestring({{0, 0}, {10, 0}})});
  auto scene = [&](const std::string& extra) { return render_test::build_layer_a(dir, extra); };
  auto r = scene("kind = \"line\"\ndash = [2]\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("s.toml:6: layer[0].dash: expected an even count"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("[2.000000]"), std::string::npos) << r.output;
  r = scene("kind = \"line\"\ndash = [2, 1, 3]\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("(3 values)"), std::string::npos) << r.output;
  r = scene("kind = \"line\"\ndash = [2, -1]\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("layer[0].dash[1]: expected a dash length > 0, got -1"),
            std::string::npos)
      << r.output;
  r = scene("kind = \"line\"\ndash = [2, \"x\"]\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("layer[0].dash[1]: expected a number, got string"), std::string::npos)
      << r.output;
  r = scene("kind = \"polygon\"\ndash = [2, 1]\n");
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("dash needs kind"), std::string::npos) << r.output;
}

}  // namespace

}  // namespace render_dashes
