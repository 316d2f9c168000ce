// Dynamic lines (thesis §4.3, §4.4.2): pixel width kept when zoomed out,
// same-pixel vertex removal, drawing order at transparent crossings.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <optional>

#include "prep/error.hpp"
#include "prep/render.hpp"

namespace {

namespace R = prep::render;

constexpr uint32_t kRed = 0x800000ffu;   // R=255, alpha 0x80
constexpr uint32_t kBlue = 0x80ff0000u;  // B=255, alpha 0x80

// Densely subdivided dynamic lines at z = 0 (as terrain matching makes them):
// a horizontal line y = 50 (order 0, red) and a vertical line x = 100
// (order 1, blue), vertices every 0.5 m, half width 2 px.
prep::DecalModel dynamic_model(int corner = 0) {
  prep::DecalModel m;
  m.extent = {0, 0, 200, 100};
  m.grid = {0, 0, 200000, 100000, 1, 1};
  auto add_line = [&](double x0, double y0, double x1, double y1, uint32_t rgba, uint32_t order) {
    uint32_t line = uint32_t(m.dyn_line_props.size());
    uint32_t first = uint32_t(m.dyn_vertices.size());
    int n = int(std::hypot(x1 - x0, y1 - y0) / 0.5);
    for (int k = 0; k <= n; ++k) {
      double t = double(k) / n;
      m.dyn_vertices.push_back({int32_t(std::lround((x0 + t * (x1 - x0)) * 1000)),
                                int32_t(std::lround((y0 + t * (y1 - y0)) * 1000)), 0,
                                int32_t(line)});
      m.dyn_prev_next.push_back(
          {k == 0 ? -1 : int32_t(first + k - 1), k == n ? -1 : int32_t(first + k + 1)});
    }
    m.dyn_line_start.push_back(first);
    m.dyn_line_props.push_back({2.0f, rgba, order, uint32_t(corner), 0.f, 0, line, 0});
  };
  add_line(20, 50, 180, 50, kRed, 0);
  add_line(100, 10, 100, 90, kBlue, 1);
  return m;
}

struct Shot {
  R::Image img;
  bool ok = false;
};

Shot shoot(const prep::DecalModel& m, const prep::Extent& view, uint32_t w, uint32_t h,
           R::AntiAliasing aa = R::AntiAliasing::none) {
  R::DecalSource src = R::source_of(m);
  R::RenderOptions opt;
  opt.width = w;
  opt.height = h;
  opt.camera = R::topdown_camera(view, 0, 0);
  opt.aa = aa;
  Shot s;
  try {
    s.img = R::render_gl(src, R::flat_heightfield(view), opt);
    s.ok = true;
  } catch (const prep::render_error& e) {
    std::printf("no headless GL: %s\n", e.what());
  }
  return s;
}

// Covered pixels of the dynamic layer in image column i.
int column_coverage(const R::Image& img, uint32_t i) {
  int n = 0;
  for (uint32_t j = 0; j < img.height; ++j)
    n += img.dynamic[4 * (i + size_t(img.width) * j) + 3] > 0;
  return n;
}

TEST(DynamicLines, KeepTheirPixelWidthWhenZoomedOut) {
  auto m = dynamic_model();
  const uint32_t W = 320, H = 160;
  for (double zoom : {1.0, 4.0, 16.0}) {
    // View centred on the red line, zoom x wider each time.
    double hw = 100 * zoom, hh = 50 * zoom;
    prep::Extent view{100 - hw, 50.25 - hh, 100 + hw, 50.25 + hh};
    Shot s = shoot(m, view, W, H);
    if (!s.ok) GTEST_SKIP() << "no headless GL";
    std::filesystem::create_directories("render-out");
    prep::write_png_rgba("render-out/dynamic_zoom" + std::to_string(int(zoom)) + ".png", W, H,
                         s.img.rgba);
    // A column through the red line away from the blue one: 4 px = 2 x half width.
    uint32_t col = W / 2 - 6;
    int width_px = column_coverage(s.img, col);
    RecordProperty("width_px_zoom" + std::to_string(int(zoom)), width_px);
    EXPECT_GE(width_px, 3) << "zoom " << zoom;
    EXPECT_LE(width_px, 5) << "zoom " << zoom;
    if (zoom == 16.0) {
      // 3200 m over 320 px: 10 m per pixel, vertices 0.5 m apart: most share a pixel.
      EXPECT_LT(s.img.dyn_kept, m.dyn_vertices.size() / 5)
          << "same-pixel removal kept " << s.img.dyn_kept;
      EXPECT_GT(s.img.dyn_kept, 20u);
    }
  }
}

TEST(DynamicLines, CoverageAntiAliasingKeepsTheIntegratedPixelWidth) {
  // With coverage AA a column across the red line integrates to its width
  // (alpha 128/255 times 4 px), at any zoom, also off the pixel grid.
  auto m = dynamic_model();
  const uint32_t W = 320, H = 160;
  for (double zoom : {1.0, 16.0}) {
    double hw = 100 * zoom, hh = 50 * zoom;
    prep::Extent view{100 - hw, 50.37 - hh, 100 + hw, 50.37 + hh};  // line off the pixel centres
    Shot s = shoot(m, view, W, H, R::AntiAliasing::coverage);
    if (!s.ok) GTEST_SKIP() << "no headless GL";
    double sum = 0;
    const uint32_t col = W / 2 - 6;
    for (uint32_t j = 0; j < H; ++j) sum += s.img.dynamic[4 * (col + size_t(W) * j) + 3];
    const double width = sum / (128 / 255.0);
    RecordProperty("aa_width_px_zoom" + std::to_string(int(zoom)), std::to_string(width));
    EXPECT_NEAR(width, 4.0, 0.5) << "zoom " << zoom;
  }
}

TEST(DynamicLines, TransparentCrossingShowsTheTopLineOverTheOther) {
  auto m = dynamic_model();
  Shot s = shoot(m, {0, 0, 200, 100}, 200, 100);
  if (!s.ok) GTEST_SKIP() << "no headless GL";
  // Pixel (100, 49) has its centre at (100.5, 50.5): on both lines.
  const float* c = &s.img.dynamic[4 * (100 + size_t(200) * 49)];
  // red (order 0) over blue: premultiplied 0.502*red + 0.498*0.502*blue.
  double a_top = 128 / 255.0, a = a_top + (1 - a_top) * a_top;
  EXPECT_NEAR(c[3], a, 2.0 / 255);
  EXPECT_NEAR(c[0], a_top / a, 2.0 / 255);
  EXPECT_NEAR(c[2], (1 - a_top) * a_top / a, 2.0 / 255);
  EXPECT_NEAR(c[1], 0.0, 1e-6);
  // Off the crossing, one line only, and each line counts once despite its
  // overlapping segment boxes and round joins.
  const float* r = &s.img.dynamic[4 * (60 + size_t(200) * 49)];
  EXPECT_NEAR(r[3], a_top, 2.0 / 255);
  EXPECT_NEAR(r[0], 1.0, 2.0 / 255);
}

TEST(DynamicLines, GrowTheListBufferWhenItOverflows) {
  // 60 copies of one line on top of each other: 60 list nodes per covered
  // pixel exceed the initial two nodes per pixel, so the pass must regrow.
  auto m = dynamic_model();
  auto base_v = m.dyn_vertices;
  auto base_pn = m.dyn_prev_next;
  m.dyn_vertices.clear();
  m.dyn_prev_next.clear();
  m.dyn_line_start.clear();
  auto props = m.dyn_line_props[0];
  m.dyn_line_props.clear();
  size_t n0 = 0;
  while (n0 < base_v.size() && base_v[n0][3] == 0) ++n0;  // the red line only
  for (uint32_t copy = 0; copy < 60; ++copy) {
    uint32_t first = uint32_t(m.dyn_vertices.size());
    m.dyn_line_start.push_back(first);
    for (size_t k = 0; k < n0; ++k) {
      auto v = base_v[k];
      v[3] = int32_t(copy);
      m.dyn_vertices.push_back(v);
      auto pn = base_pn[k];
      m.dyn_prev_next.push_back(
          {pn[0] < 0 ? -1 : int32_t(first + pn[0]), pn[1] < 0 ? -1 : int32_t(first + pn[1])});
    }
    props.order = copy;
    props.rgba = 0x10ffffffu;  // nearly transparent so no early exit
    m.dyn_line_props.push_back(props);
  }
  Shot s = shoot(m, {90, 45, 110, 55}, 64, 32);
  if (!s.ok) GTEST_SKIP() << "no headless GL";
  EXPECT_GE(s.img.list_grows, 1u);
  EXPECT_GT(s.img.dyn_nodes, 64u * 32u * 2u);
  // Every line of the list is composited (dyn_composite.frag.glsl has no
  // cap): 1 - (1 - 16/255)^60.
  const float* c = &s.img.dynamic[4 * (32 + size_t(64) * 15)];
  EXPECT_NEAR(c[3], 1 - std::pow(1 - 16 / 255.0, 60), 2.0 / 255);
}

// Twelve translucent lines of twelve colours through one pixel, their
// drawing order a permutation of their index: the pixel is all twelve
// composited front to back in that order (straight alpha), analytically.
TEST(DynamicLines, TwelveTransparentLinesThroughOnePixelCompositeAllInDrawingOrder) {
  prep::DecalModel m = dynamic_model();
  m.dyn_vertices.clear();
  m.dyn_prev_next.clear();
  m.dyn_line_start.clear();
  m.dyn_line_props.clear();
  constexpr int kLines = 12;
  std::array<uint32_t, kLines> rgba{}, order{};
  for (int k = 0; k < kLines; ++k) {
    const double a = k * 3.14159265358979 / kLines;  // 15 degrees apart
    const double x0 = 100.5 - 40 * std::cos(a), y0 = 50.5 - 40 * std::sin(a);
    const double x1 = 100.5 + 40 * std::cos(a), y1 = 50.5 + 40 * std::sin(a);
    const uint32_t first = uint32_t(m.dyn_vertices.size());
    m.dyn_line_start.push_back(first);
    m.dyn_vertices.push_back(
        {int32_t(std::lround(x0 * 1000)), int32_t(std::lround(y0 * 1000)), 0, k});
    m.dyn_vertices.push_back(
        {int32_t(std::lround(x1 * 1000)), int32_t(std::lround(y1 * 1000)), 0, k});
    m.dyn_prev_next.push_back({-1, int32_t(first + 1)});
    m.dyn_prev_next.push_back({int32_t(first), -1});
    rgba[k] = uint32_t(20 * k) | uint32_t(255 - 20 * k) << 8 | uint32_t((37 * k) % 256) << 16 |
              0x59u << 24;
    order[k] = uint32_t((5 * k) % kLines);  // 5 and 12 are coprime: a permutation
    m.dyn_line_props.push_back({2.0f, rgba[k], order[k], 0u, 0.f, 0, uint32_t(k), 0});
  }
  Shot s = shoot(m, {0, 0, 200, 100}, 200, 100);
  if (!s.ok) GTEST_SKIP() << "no headless GL";
  // Front to back: the line of order 0 first.
  std::array<int, kLines> by_order{};
  for (int k = 0; k < kLines; ++k) by_order[order[k]] = k;
  double acc[4] = {0, 0, 0, 0};
  for (int r = 0; r < kLines; ++r) {
    const uint32_t c = rgba[by_order[r]];
    const double a = double(c >> 24) / 255.0, w = (1 - acc[3]) * a;
    for (int ch = 0; ch < 3; ++ch) acc[ch] += w * double((c >> (8 * ch)) & 0xffu) / 255.0;
    acc[3] += w;
  }
  // Pixel (100, 49): centre (100.5, 50.5), where every line passes.
  const float* c = &s.img.dynamic[4 * (100 + size_t(200) * 49)];
  EXPECT_NEAR(c[3], acc[3], 2.0 / 255);
  for (int ch = 0; ch < 3; ++ch) EXPECT_NEAR(c[ch], acc[ch] / acc[3], 2.0 / 255) << ch;
  // The same lines composited in index order instead give another colour:
  // the test tells the orders apart.
  double wrong[4] = {0, 0, 0, 0};
  for (int k = 0; k < kLines; ++k) {
    const double a = double(rgba[k] >> 24) / 255.0, w = (1 - wrong[3]) * a;
    for (int ch = 0; ch < 3; ++ch) wrong[ch] += w * double((rgba[k] >> (8 * ch)) & 0xffu) / 255.0;
    wrong[3] += w;
  }
  double differ = 0;
  for (int ch = 0; ch < 3; ++ch) differ = std::max(differ, std::abs(wrong[ch] - acc[ch]) / acc[3]);
  EXPECT_GT(differ, 10.0 / 255);
}

// A miter corner of 30 degrees between its segments: round below the
// package's miter limit (40 by default), a miter tip at a limit of 20. A
// point 2.5 half widths from the corner on the outer side lies in the tip
// (the miter reaches 1 / sin(15 deg) = 3.9 half widths) but off the round cap.
TEST(DynamicLines, MiterCornersFollowThePackagesMiterLimit) {
  prep::DecalModel m = dynamic_model(/*corner=*/1);
  m.dyn_vertices.clear();
  m.dyn_prev_next.clear();
  m.dyn_line_start.clear();
  m.dyn_line_props.clear();
  const double th = 30 * 3.14159265358979 / 180;
  const double vx = 120, vy = 50;
  const double pts[3][2] = {{40, 50}, {vx, vy}, {vx - 70 * std::cos(th), vy + 70 * std::sin(th)}};
  for (int k = 0; k < 3; ++k)
    m.dyn_vertices.push_back(
        {int32_t(std::lround(pts[k][0] * 1000)), int32_t(std::lround(pts[k][1] * 1000)), 0, 0});
  m.dyn_prev_next = {{-1, 1}, {0, 2}, {1, -1}};
  m.dyn_line_start = {0};
  m.dyn_line_props.push_back({3.0f, 0xff0000ffu, 0, 1u, 0.f, 0, 0, 0});
  // Outer side of the corner: away from both segments.
  const double ox = 1 + std::cos(th), oy = -std::sin(th), on = std::hypot(ox, oy);
  const double px = vx + 2.5 * 3 * ox / on, py = vy + 2.5 * 3 * oy / on;
  const uint32_t i = uint32_t(px), j = uint32_t(100 - py);
  auto tip_alpha = [&](double limit) -> std::optional<float> {
    R::DecalSource src = R::source_of(m);
    src.miter_limit_deg = limit;
    R::RenderOptions opt;
    opt.width = 200;
    opt.height = 100;
    opt.camera = R::topdown_camera({0, 0, 200, 100}, 0, 0);
    try {
      const R::Image img = R::render_gl(src, R::flat_heightfield({0, 0, 200, 100}), opt);
      return img.dynamic[4 * (i + size_t(200) * j) + 3];
    } catch (const prep::render_error& e) {
      return std::nullopt;
    }
  };
  const auto round_fallback = tip_alpha(40), miter = tip_alpha(20);
  if (!round_fallback) GTEST_SKIP() << "no headless GL";
  EXPECT_EQ(*round_fallback, 0.0f) << "limit 40: the 30-degree corner is round";
  ASSERT_TRUE(miter);
  EXPECT_GT(*miter, 0.9f) << "limit 20: the 30-degree corner has its miter tip";
}

}  // namespace
