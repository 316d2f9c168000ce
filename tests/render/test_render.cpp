// GL renderer against analytic coverage of a hand-written model.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <optional>

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

struct Vec3Basis {
  R::Vec3 r, u, f;
};
Vec3Basis basis(const R::Camera& c) {
  auto norm = [](R::Vec3 v) {
    double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return R::Vec3{v[0] / l, v[1] / l, v[2] / l};
  };
  auto cross = [](R::Vec3 a, R::Vec3 b) {
    return R::Vec3{a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  R::Vec3 f = norm({c.target[0] - c.eye[0], c.target[1] - c.eye[1], c.target[2] - c.eye[2]});
  R::Vec3 r = norm(cross(f, c.up));
  return {r, cross(r, f), f};
}

// The ray of pixel (i, j), exactly as render_cpu builds it.
R::Vec3 pixel_ray(const R::RenderOptions& opt, uint32_t i, uint32_t j) {
  const double aspect = double(opt.width) / opt.height;
  const Vec3Basis b = basis(opt.camera);
  const double t = std::tan(opt.camera.fov_y_deg * 3.14159265358979323846 / 360);
  const double nx = (i + 0.5) / opt.width * 2 - 1, ny = 1 - (j + 0.5) / opt.height * 2;
  R::Vec3 d;
  for (int k = 0; k < 3; ++k) d[k] = b.f[k] + nx * t * aspect * b.r[k] + ny * t * b.u[k];
  return d;
}

// The ground point (x, y) where the ray of pixel (i, j), cast in double
// precision, first meets `terrain`; none when it misses.
std::optional<std::array<double, 2>> ground_at(const R::RenderOptions& opt,
                                               const R::Heightfield& terrain, uint32_t i,
                                               uint32_t j) {
  const R::Vec3& eye = opt.camera.eye;
  const R::Vec3 d = pixel_ray(opt, i, j);
  const std::optional<double> hit = terrain.intersect(eye, d);
  if (!hit) return std::nullopt;
  return std::array<double, 2>{eye[0] + *hit * d[0], eye[1] + *hit * d[1]};
}

// Expected straight-alpha colour: line (alpha 0x80) over the polygon layer.
std::array<double, 4> expected(double x, double y) {
  auto unpack = [](uint32_t c) {
    return std::array<double, 4>{(c & 0xff) / 255.0, ((c >> 8) & 0xff) / 255.0,
                                 ((c >> 16) & 0xff) / 255.0, (c >> 24) / 255.0};
  };
  std::array<double, 4> acc{0, 0, 0, 0};  // premultiplied
  auto under = [&](uint32_t rgba) {
    auto c = unpack(rgba);
    double w = (1 - acc[3]) * c[3];
    for (int k = 0; k < 3; ++k) acc[k] += w * c[k];
    acc[3] += w;
  };
  if (HandShapes::in_line(x, y)) under(HandShapes::kLineRgba);
  if (HandShapes::in_line2(x, y)) under(HandShapes::kLine2Rgba);
  auto in = [&](double a, double b) { return x > a && x < b && y > a && y < b; };
  if (in(20, 80) && !in(40, 60))
    under(HandShapes::kPolyRgba);
  else if (in(45, 55))
    under(HandShapes::kIslandRgba);
  if (acc[3] > 0)
    for (int k = 0; k < 3; ++k) acc[k] /= acc[3];
  return acc;
}

class RenderGlBinding : public ::testing::TestWithParam<R::Binding> {};

TEST_P(RenderGlBinding, TopDownDecalLayerMatchesAnalyticCoverageOfHandModel) {
  prep::DecalModel model = render_test::hand_model();
  R::DecalSource src = R::source_of(model);
  R::RenderOptions opt;
  opt.width = 160;
  opt.height = 120;
  opt.binding = GetParam();
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
  prep::write_png_rgba((out_dir() / (GetParam() == R::Binding::ssbo ? "hand_topdown_ssbo.png"
                                                                    : "hand_topdown_texture.png"))
                           .string(),
                       img.width, img.height, img.rgba);
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
        if (bad < 5)
          ADD_FAILURE() << "pixel " << i << "," << j << " at (" << x << ", " << y << ") GL rgba "
                        << g[0] << " " << g[1] << " " << g[2] << " " << g[3] << " expected " << e[0]
                        << " " << e[1] << " " << e[2] << " " << e[3];
      }
    }
  EXPECT_GT(covered, 3000u);
  EXPECT_EQ(bad, 0u);
  // At the crossing (50, 50) of the two transparent lines the top line
  // (blue, order 0) lies over the orange one, both over the green island.
  const uint32_t ci = uint32_t((50 - view.xmin) / (view.xmax - view.xmin) * opt.width);
  const uint32_t cj = uint32_t((view.ymax - 50) / (view.ymax - view.ymin) * opt.height);
  const double cx = view.xmin + (ci + 0.5) * (view.xmax - view.xmin) / opt.width;
  const double cy = view.ymax - (cj + 0.5) * (view.ymax - view.ymin) / opt.height;
  ASSERT_TRUE(HandShapes::in_line(cx, cy) && HandShapes::in_line2(cx, cy));
  const float* g = &img.decals[4 * (ci + size_t(opt.width) * cj)];
  const double a0 = 0x80 / 255.0, a1 = 0x90 / 255.0;
  // blue channel: 0.502 * 0xe0 + 0.498 * 0.565 * 0 + rest * island 0x20
  const double blue = a0 * (0xe0 / 255.0) + (1 - a0) * (1 - a1) * (0x20 / 255.0);
  EXPECT_NEAR(g[3], 1.0, 2.0 / 255);
  EXPECT_NEAR(g[2], blue, 2.0 / 255);
  EXPECT_NEAR(g[0],
              a0 * (0x20 / 255.0) + (1 - a0) * a1 * 1.0 + (1 - a0) * (1 - a1) * (0x20 / 255.0),
              2.0 / 255);
}

// A square heightfield of n x n posts `d` metres apart from (x0, x0), z(x, y)
// at each, with its z range.
template <class Z>
R::Heightfield square_terrain(uint32_t n, double x0, double d, Z z_of) {
  R::Heightfield h;
  h.nx = h.ny = n;
  h.x0 = h.y0 = x0;
  h.dx = h.dy = d;
  h.zmin = 1e9;
  h.zmax = -1e9;
  for (uint32_t j = 0; j < n; ++j)
    for (uint32_t i = 0; i < n; ++i) {
      const double z = z_of(x0 + i * d, x0 + j * d);
      h.z.push_back(z);
      h.zmin = std::min(h.zmin, z);
      h.zmax = std::max(h.zmax, z);
    }
  return h;
}

// A 320x180 perspective view of the whole model over `terrain`.
R::RenderOptions perspective_view(const prep::DecalModel& model, const R::Heightfield& terrain,
                                  double fov_deg) {
  R::RenderOptions opt;
  opt.width = 320;
  opt.height = 180;
  opt.camera = R::fit_camera(model.extent, terrain.zmin, terrain.zmax, opt.width, opt.height,
                             R::Projection::perspective, fov_deg);
  return opt;
}

TEST(RenderGl, ObliquePerspectiveOverHillsAgreesWithDoubleRayCastOn999Permille) {
  // Independent reference: each pixel's ray cast in double precision against
  // the same mesh, then the analytic coverage of the hand shapes there.
  prep::DecalModel model = render_test::hand_model();
  R::DecalSource src = R::source_of(model);
  const R::Heightfield hills = square_terrain(61, -20, 140.0 / 60, [](double x, double y) {
    return 12 * std::sin(x / 13.0) * std::cos(y / 17.0);
  });
  const R::RenderOptions opt = perspective_view(model, hills, 40);
  R::Image img;
  try {
    img = R::render_gl(src, hills, opt);
  } catch (const prep::render_error& e) {
    GTEST_SKIP() << "no headless GL here: " << e.what();
  }
  prep::write_png_rgba((out_dir() / "hand_perspective.png").string(), img.width, img.height,
                       img.rgba);
  size_t considered = 0, agree = 0;
  for (uint32_t j = 0; j < opt.height; ++j)
    for (uint32_t i = 0; i < opt.width; ++i) {
      std::array<double, 4> e{0, 0, 0, 0};
      if (const auto ground = ground_at(opt, hills, i, j)) e = expected((*ground)[0], (*ground)[1]);
      const float* g = &img.decals[4 * (i + size_t(opt.width) * j)];
      if (e[3] == 0 && g[3] == 0) continue;
      ++considered;
      bool ok = std::abs(g[3] - e[3]) <= 2.0 / 255;
      for (int k = 0; k < 3; ++k) ok = ok && std::abs(g[k] - e[k]) <= 2.0 / 255;
      agree += ok;
    }
  ASSERT_GT(considered, 2000u);
  EXPECT_GE(double(agree) / considered, 0.999) << agree << " of " << considered;
  RecordProperty("agreement", std::to_string(agree) + "/" + std::to_string(considered));
}

TEST(RenderCpu, ASeaAtExactlyZeroIsTintedAsSeaOnEveryRowOfAnObliqueView) {
  // Terrain: a sea at exactly 0 m for x < 50, rising to 30 m beyond. Every
  // pixel whose ray (cast here in double precision) meets the sea well inside
  // it (x < 40: cells whose normals are all vertical) and that has no decal
  // shows the sea albedo lit from straight above, as terrain.frag.glsl
  // shades it: albedo * (0.35 + 0.65 * n.l), n = (0, 0, 1), l = normalized
  // (-0.4, -0.5, 0.75).
  prep::DecalModel model = render_test::hand_model();
  R::DecalSource src = R::source_of(model);
  const R::Heightfield coast = square_terrain(
      71, -20, 2, [](double x, double) { return x < 50 ? 0.0 : std::min(30.0, (x - 50) * 0.5); });
  const R::RenderOptions opt = perspective_view(model, coast, 35);
  R::Image img = R::render_cpu(src, coast, opt);
  prep::write_png_rgba((out_dir() / "cpu_coast.png").string(), img.width, img.height, img.rgba);
  const double l = 0.75 / std::sqrt(0.4 * 0.4 + 0.5 * 0.5 + 0.75 * 0.75);
  const double sea[3] = {0.45, 0.58, 0.70};
  size_t considered = 0, wrong = 0;
  for (uint32_t j = 0; j < opt.height; ++j)
    for (uint32_t i = 0; i < opt.width; ++i) {
      const auto ground = ground_at(opt, coast, i, j);
      if (!ground) continue;
      const auto [x, y] = *ground;
      const size_t k = i + size_t(opt.width) * j;
      if (!(x < 40 && x > -18 && y > -18 && y < 118) || img.decals[4 * k + 3] != 0) continue;
      ++considered;
      for (int ch = 0; ch < 3; ++ch)
        if (std::abs(img.rgba[4 * k + ch] - 255 * sea[ch] * (0.35 + 0.65 * l)) > 1.0) {
          ++wrong;
          break;
        }
    }
  ASSERT_GT(considered, 1000u);
  EXPECT_EQ(wrong, 0u) << "of " << considered << " sea pixels";
}

INSTANTIATE_TEST_SUITE_P(Bindings, RenderGlBinding,
                         ::testing::Values(R::Binding::ssbo, R::Binding::texture),
                         [](const auto& p) {
                           return p.param == R::Binding::ssbo ? "ssbo" : "texture";
                         });

}  // namespace
