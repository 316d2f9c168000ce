// Dynamic lines on the CPU (`render --cpu`, libprep/render/dynamic_cpu.cpp)
// against the GL pass, on Monaco's OpenStreetMap roads (samples/monaco) built
// as terrain-matched dynamic lines over its SRTM hills, in three layers with
// the three corner styles and translucent colours, in perspective: the same vertices kept, the same
// segments and corners at each pixel's own scale, every covering line
// composited in drawing order. The two share no code (GLSL on the GPU, C++
// in double precision), so their agreement checks both; the analytic cases
// (pixel width, drawing order, twelve lines on one pixel, miter limit) are
// in test_dynamic.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_dynamic_cpu {

namespace fs = std::filesystem;
namespace R = prep::render;

namespace {

struct Compared {
  size_t pixels = 0, agree = 0, covered = 0;
};

// Pixels of the two dynamic layers equal within 2/255 (alpha, and straight
// colour where covered).
Compared compare(const R::Image& gl, const R::Image& cpu) {
  Compared c;
  c.pixels = size_t(gl.width) * gl.height;
  for (size_t k = 0; k < c.pixels; ++k) {
    const float* g = &gl.dynamic[4 * k];
    const float* p = &cpu.dynamic[4 * k];
    bool same = std::abs(g[3] - p[3]) <= 2.0f / 255;
    if (same && (g[3] > 0 || p[3] > 0))
      for (int ch = 0; ch < 3; ++ch) same = same && std::abs(g[ch] - p[ch]) <= 2.0f / 255;
    c.agree += same;
    c.covered += p[3] > 0;
  }
  return c;
}

R::Camera look(const prep::render::Vec3& eye, const prep::render::Vec3& target, double fov) {
  R::Camera c;
  c.eye = eye;
  c.target = target;
  c.fov_y_deg = fov;
  c.projection = R::Projection::perspective;
  const double dist = std::hypot(eye[0] - target[0], eye[1] - target[1], eye[2] - target[2]);
  c.near = std::max(0.1, dist * 1e-3);
  c.depth_range = 4 * dist;
  return c;
}

// The roads as three dynamic layers (miter, bevel, round; translucent, so
// crossings composite several lines).
std::string roads_package(std::string& why) {
  const std::string src = DECALPREP_SOURCE_DIR "/samples/monaco";
  if (!fs::exists(src + "/monaco.osm.pbf")) {
    why = "Monaco sample missing in " + src;
    return "";
  }
  const fs::path dir = fs::current_path() / "render-out" / "dynamic_cpu";
  fs::create_directories(dir);
  std::FILE* f = std::fopen((dir / "roads.toml").c_str(), "w");
  if (!f) {
    why = "cannot write " + (dir / "roads.toml").string();
    return "";
  }
  std::fprintf(f,
               "source = \"%s/monaco.osm.pbf\"\ndem = \"/vsizip/%s/N43E007.hgt.zip/N43E007.hgt\"\n"
               "extent = [7.405, 43.725, 7.440, 43.750]\nextent_crs = \"EPSG:4326\"\n"
               "resolution = 0.1\n[build]\nmiter_limit_deg = 30\n",
               src.c_str(), src.c_str());
  const char* layers[][4] = {
      {"primary", "highway IN ('primary', 'secondary', 'tertiary')", "miter", "#e4572ecc"},
      {"residential", "highway IN ('residential', 'unclassified', 'service')", "bevel",
       "#2e86e4aa"},
      {"paths", "highway IN ('footway', 'path', 'steps', 'pedestrian')", "round", "#30a050b0"}};
  for (const auto& l : layers)
    std::fprintf(f,
                 "[[layer]]\nname = \"%s\"\nlayer = \"lines\"\nwhere = \"%s\"\nkind = "
                 "\"line\"\ndynamic = true\nwidth = 3\ncorner = \"%s\"\ncolor = \"%s\"\n",
                 l[0], l[1], l[2], l[3]);
  std::fclose(f);
  const std::string pkg = (dir / "roads.decals").string();
  const auto r =
      prep::test::run_tool("build " + (dir / "roads.toml").string() + " -o " + pkg + " -q");
  if (r.rc != 0) {
    why = "build failed: " + r.output;
    return "";
  }
  return pkg;
}

TEST(DynamicLinesCpu, AgreeWithTheGlPassOnMonacoRoadsInPerspectiveOn999Permille) {
  std::string why;
  const std::string path = roads_package(why);
  ASSERT_FALSE(path.empty()) << why;
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path, pkg));
  const R::DecalSource src = R::source_of(pkg);
  const R::Heightfield terrain = R::load_heightfield(
      R::recorded_dem(std::string(pkg.metadata_json()), path), src.frame, src.extent);
  const fs::path out = fs::current_path() / "render-out" / "dynamic_cpu";
  fs::create_directories(out);
  struct View {
    const char* name;
    R::Camera camera;
  };
  const View views[] = {
      {"oblique", look({300, -2200, 900}, {0, 0, 60}, 40)},
      {"close", look({-200, -900, 300}, {0, 0, 40}, 35)},
  };
  for (const View& v : views) {
    R::RenderOptions opt;
    opt.width = 480;
    opt.height = 270;
    opt.camera = v.camera;
    opt.draw_polygons = opt.draw_lines = false;  // the dynamic layer alone
    R::Image gl;
    try {
      gl = R::render_gl(src, terrain, opt);
    } catch (const prep::render_error& e) {
      GTEST_SKIP() << "no headless GL: " << e.what();
    }
    const R::Image cpu = R::render_cpu(src, terrain, opt);
    prep::write_png_rgba((out / (std::string(v.name) + "_gl.png")).string(), gl.width, gl.height,
                         gl.rgba);
    prep::write_png_rgba((out / (std::string(v.name) + "_cpu.png")).string(), cpu.width, cpu.height,
                         cpu.rgba);
    ASSERT_EQ(gl.dynamic.size(), cpu.dynamic.size());
    const Compared c = compare(gl, cpu);
    std::printf("%s: %zu of %zu pixels agree (%.5f), %zu covered by dynamic lines (CPU)\n", v.name,
                c.agree, c.pixels, double(c.agree) / double(c.pixels), c.covered);
    EXPECT_GT(c.covered, c.pixels / 100) << v.name << ": too few dynamic-line pixels to compare";
    EXPECT_GE(double(c.agree) / double(c.pixels), 0.999) << v.name;
  }
}

}  // namespace

}  // namespace render_dynamic_cpu
