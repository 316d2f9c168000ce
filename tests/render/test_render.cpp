// GL renderer against analytic coverage of a hand-written model.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "hand_model.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"

namespace {

namespace R = prep::render;
using render_test::HandShapes;

std::filesystem::path out_dir() {
  auto p = std::filesystem::current_path() / "render-out";
  std::filesystem::create_directories(p);
  return p;
}

// Expected straight-alpha colour: line (alpha 0x80) over the polygon layer.
std::array<double, 4> expected(double x, double y) {
  auto unpack = [](uint32_t c) {
    return std::array<double, 4>{(c & 0xff) / 255.0, ((c >> 8) & 0xff) / 255.0, ((c >> 16) & 0xff) / 255.0, (c >> 24) / 255.0};
  };
  std::array<double, 4> acc{0, 0, 0, 0};  // premultiplied
  auto under = [&](uint32_t rgba) {
    auto c = unpack(rgba);
    double w = (1 - acc[3]) * c[3];
    for (int k = 0; k < 3; ++k) acc[k] += w * c[k];
    acc[3] += w;
  };
  if (HandShapes::in_line(x, y)) under(HandShapes::kLineRgba);
  auto in = [&](double a, double b) { return x > a && x < b && y > a && y < b; };
  if (in(20, 80) && !in(40, 60)) under(HandShapes::kPolyRgba);
  else if (in(45, 55)) under(HandShapes::kIslandRgba);
  if (acc[3] > 0)
    for (int k = 0; k < 3; ++k) acc[k] /= acc[3];
  return acc;
}

TEST(RenderGl, TopDownDecalLayerMatchesAnalyticCoverageOfHandModel) {
  prep::DecalModel model = render_test::hand_model();
  R::DecalSource src = R::source_of(model);
  R::RenderOptions opt;
  opt.width = 160;
  opt.height = 120;
  // A view that crosses grid cells and leaves margins outside the grid.
  prep::Extent view{-10, 0, 110, 90};
  R::Heightfield terrain = R::flat_heightfield(view);
  opt.camera = R::topdown_camera(view, 0, 0);
  R::Image img;
  try {
    img = R::render_gl(src, terrain, opt);
  } catch (const prep::render_error& e) {
    GTEST_SKIP() << "no headless GL here: " << e.what();
  }
  R::write_png((out_dir() / "hand_topdown.png").string(), img.rgba, img.width, img.height);
  size_t covered = 0, bad = 0;
  for (uint32_t j = 0; j < opt.height; ++j)
    for (uint32_t i = 0; i < opt.width; ++i) {
      double x = view.xmin + (i + 0.5) * (view.xmax - view.xmin) / opt.width;
      double y = view.ymax - (j + 0.5) * (view.ymax - view.ymin) / opt.height;
      auto e = expected(x, y);
      const float* g = &img.decals[4 * (i + size_t(opt.width) * j)];
      if (e[3] > 0) ++covered;
      bool ok = std::abs(g[3] - e[3]) <= 2.0 / 255;
      for (int k = 0; k < 3 && e[3] > 0; ++k) ok = ok && std::abs(g[k] - e[k]) <= 2.0 / 255;
      if (!ok) {
        ++bad;
        if (bad < 5) ADD_FAILURE() << "pixel " << i << "," << j << " at (" << x << ", " << y << ") GL rgba " << g[0]
                                   << " " << g[1] << " " << g[2] << " " << g[3] << " expected " << e[0] << " " << e[1]
                                   << " " << e[2] << " " << e[3];
      }
    }
  EXPECT_GT(covered, 3000u);
  EXPECT_EQ(bad, 0u);
}

}  // namespace
