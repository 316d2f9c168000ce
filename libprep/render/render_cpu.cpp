// The CPU path (`render --cpu`): the same view through prep::evaluate.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <span>
#include <thread>
#include <vector>

#include "detail/dynamic_cpu.hpp"
#include "detail/math.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"

namespace prep::render {

namespace {

// Terrain colour of the CPU path: the same Lambert model as terrain.frag.glsl
// with the vertex normals averaged over the hit triangle's cell.
std::array<double, 3> shade(const Heightfield& t, const RenderOptions& opt, double x, double y,
                            double z) {
  const Vec3 light = detail::normalize({-0.4, -0.5, 0.75});
  int i = std::clamp(int((x - t.x0) / t.dx), 0, int(t.nx) - 2),
      j = std::clamp(int((y - t.y0) / t.dy), 0, int(t.ny) - 2);
  Vec3 n = detail::add(detail::add(t.normal_at(i, j), t.normal_at(i + 1, j)),
                       detail::add(t.normal_at(i, j + 1), t.normal_at(i + 1, j + 1)));
  double l = std::max(detail::dot(detail::normalize(n), light), 0.0);
  // Sea tint at or below 0 m, as terrain.frag.glsl (flat terrain is land).
  std::array<double, 3> albedo = opt.albedo;
  if (t.zmax > t.zmin && z <= 0.0) albedo = {0.45, 0.58, 0.70};
  return {albedo[0] * (0.35 + 0.65 * l), albedo[1] * (0.35 + 0.65 * l),
          albedo[2] * (0.35 + 0.65 * l)};
}

}  // namespace

Image render_cpu(const DecalSource& source, const Heightfield& terrain, const RenderOptions& opt) {
  const TileSource whole{source, Extent{-INFINITY, -INFINITY, INFINITY, INFINITY}, 0, 0};
  return render_cpu(std::span<const TileSource>(&whole, 1), terrain, opt);
}

namespace {

// One CPU frame of several tiles: the evaluator's views, the slope-width
// layers, and each pixel's ground point (NaN x where its ray sees sky).
struct CpuFrame {
  std::span<const TileSource> tiles;
  const Heightfield& terrain;
  const RenderOptions& opt;
  uint32_t W, H;
  Image& img;
  std::vector<StaticView> views;
  std::vector<std::vector<uint8_t>> slope;
  bool any_slope = false;
  std::vector<double> hit_x, hit_y, hit_z;

  CpuFrame(std::span<const TileSource> t, const Heightfield& h, const RenderOptions& o, Image& i)
      : tiles(t),
        terrain(h),
        opt(o),
        W(o.width),
        H(o.height),
        img(i),
        slope(t.size()),
        hit_x(size_t(W) * H, NAN),
        hit_y(size_t(W) * H, NAN),
        hit_z(size_t(W) * H, 0.0) {
    // Kinds not drawn are left out of the views the evaluator sees.
    for (const TileSource& tile : tiles) {
      StaticView view = tile.source.view;
      if (!opt.draw_polygons) view.poly_bvh_range = {};
      if (!opt.draw_lines) view.line_bvh_range = {};
      views.push_back(view);
    }
    // Slope widths (formats/SPEC.md "Slope widths"): each tile's flagged
    // layers, measured along the gradient of the terrain triangle under the
    // point (the ray's hit triangle; the one under the pixel centre top-down).
    for (size_t k = 0; k < tiles.size(); ++k) {
      if (opt.draw_lines) slope[k] = slope_layers(tiles[k].source, opt.slope_widths);
      any_slope = any_slope || !slope[k].empty();
    }
  }

  // The tile whose half-open square holds (x, y); none: tiles.size().
  size_t tile_at(double x, double y) const {
    for (size_t k = 0; k < tiles.size(); ++k) {
      const Extent& q = tiles[k].square;
      if (x >= q.xmin && x < q.xmax && y >= q.ymin && y < q.ymax) return k;
    }
    return tiles.size();
  }

  // A point is answered by the one tile whose half-open square holds it.
  EvalSample sample(double x, double y) const {
    const size_t k = tile_at(x, y);
    if (k == tiles.size()) return EvalSample{};
    if (slope[k].empty()) return evaluate(views[k], x - tiles[k].dx, y - tiles[k].dy);
    const std::array<double, 2> g = terrain.gradient_at(x, y);
    return evaluate(views[k], x - tiles[k].dx, y - tiles[k].dy, {g[0], g[1], slope[k]});
  }

  // Rows in parallel (evaluate() is thread-safe; each pixel is written once).
  template <class Row>
  void parallel_rows(Row&& row) const {
    const uint32_t nthreads = std::max(1u, std::min(16u, std::thread::hardware_concurrency()));
    auto rows = [&](uint32_t j0, uint32_t step) {
      for (uint32_t j = j0; j < H; j += step) row(j);
    };
    std::vector<std::thread> workers;
    for (uint32_t t = 1; t < nthreads; ++t) workers.emplace_back(rows, t, nthreads);
    rows(0, nthreads);
    for (auto& w : workers) w.join();
  }

  void put(size_t k, const EvalSample& s) {
    const float a = s.rgba[3];
    for (int c = 0; c < 3; ++c) img.decals[4 * k + c] = a > 0 ? s.rgba[c] / a : 0.0f;
    img.decals[4 * k + 3] = a;
  }

  // Exactly the render_topdown pixel grid; the terrain is under every pixel.
  void draw_topdown(const Extent& td) {
    const bool single = tiles.size() == 1 && std::isinf(tiles[0].square.xmin) && !any_slope;
    if (single) {
      img.decals = render_topdown(views[0], td, W, H);
    } else {
      parallel_rows([&](uint32_t j) {
        for (uint32_t i = 0; i < W; ++i)
          put(i + size_t(W) * j, sample(td.xmin + (i + 0.5) * (td.xmax - td.xmin) / W,
                                        td.ymax - (j + 0.5) * (td.ymax - td.ymin) / H));
      });
    }
    for (uint32_t j = 0; j < H; ++j)
      for (uint32_t i = 0; i < W; ++i) {
        hit_x[i + size_t(W) * j] = td.xmin + (i + 0.5) * (td.xmax - td.xmin) / W;
        hit_y[i + size_t(W) * j] = td.ymax - (j + 0.5) * (td.ymax - td.ymin) / H;
        hit_z[i + size_t(W) * j] = 1.0;  // top-down: terrain tint not derived per pixel
      }
  }

  // Ray-casts the heightfield mesh in double precision from the pixel centre.
  void draw_rays() {
    const detail::PixelRays rays(opt.camera, W, H);
    parallel_rows([&](uint32_t j) {
      for (uint32_t i = 0; i < W; ++i) {
        Vec3 o, d;
        rays.ray((i + 0.5) / W * 2 - 1, 1 - (j + 0.5) / H * 2, o, d);
        auto t = terrain.intersect(o, d);
        if (!t) continue;
        const size_t k = i + size_t(W) * j;
        hit_x[k] = o[0] + *t * d[0];
        hit_y[k] = o[1] + *t * d[1];
        // The surface's own height there, not the ray's (o + t·d carries
        // rounding: on a sea at exactly 0 m it strays above 0 by a few ulps in
        // some rows, which shade() would tint as land); GL interpolates the
        // vertex heights the same way.
        const double h = terrain.height_at(hit_x[k], hit_y[k]);
        hit_z[k] = std::isnan(h) ? o[2] + *t * d[2] : h;
        put(k, sample(hit_x[k], hit_y[k]));
      }
    });
  }

  // Dynamic lines, as the GL pass draws them (detail/dynamic_cpu.hpp): each
  // tile's in its own frame, at the ground point of every pixel with
  // terrain, drawn by the tile whose square holds the point.
  void draw_dynamic() {
    const Camera& cam = opt.camera;
    std::vector<detail::DynamicLinesCpu> dyn;
    bool any = false;
    for (const TileSource& t : tiles) {
      Camera c = cam;
      c.eye = {cam.eye[0] - t.dx, cam.eye[1] - t.dy, cam.eye[2]};
      c.target = {cam.target[0] - t.dx, cam.target[1] - t.dy, cam.target[2]};
      dyn.emplace_back(
          t.source, c, W, H,
          detail::DynamicLod{opt.lod, opt.lod_tolerance_px, terrain.zmin, terrain.zmax});
      any = any || !dyn.back().empty();
      const std::array<uint64_t, 4> n = dyn.back().lod_counts();
      img.lod_lines += n[0];
      img.lod_selected += n[1];
      img.lod_drawn += n[2];
      img.lod_full += n[3];
    }
    if (!any) return;
    parallel_rows([&](uint32_t j) {
      for (uint32_t i = 0; i < W; ++i) {
        const size_t k = i + size_t(W) * j;
        if (std::isnan(hit_x[k])) continue;
        const size_t t = tile_at(hit_x[k], hit_y[k]);
        if (t == tiles.size()) continue;
        const std::array<float, 4> c =
            dyn[t].at({hit_x[k] - tiles[t].dx, hit_y[k] - tiles[t].dy, hit_z[k]});
        std::copy(c.begin(), c.end(), img.dynamic.begin() + std::ptrdiff_t(4 * k));
      }
    });
  }

  // Final image: dynamic lines over the decal layer over the shaded
  // terrain, sky where no terrain (composite.frag.glsl).
  void composite() {
    for (size_t k = 0; k < size_t(W) * H; ++k) {
      std::array<double, 3> base{0.80, 0.86, 0.93};
      if (!std::isnan(hit_x[k])) base = shade(terrain, opt, hit_x[k], hit_y[k], hit_z[k]);
      const double a = img.decals[4 * k + 3], l = img.dynamic[4 * k + 3];
      for (int c = 0; c < 3; ++c) {
        const double under = img.decals[4 * k + c] * a + (1 - a) * base[c];
        const double v = img.dynamic[4 * k + c] * l + (1 - l) * under;
        img.rgba[4 * k + c] = uint8_t(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
      }
      img.rgba[4 * k + 3] = 255;
    }
  }
};

}  // namespace

Image render_cpu(std::span<const TileSource> tiles, const Heightfield& terrain,
                 const RenderOptions& opt) {
  const uint32_t W = opt.width, H = opt.height;
  auto wall0 = std::chrono::steady_clock::now();
  Image img;
  img.width = W;
  img.height = H;
  img.device = "cpu";
  img.decals.assign(size_t(W) * H * 4, 0.0f);
  img.rgba.assign(size_t(W) * H * 4, 0);
  CpuFrame frame(tiles, terrain, opt, img);
  Extent td;
  if (is_topdown(opt.camera, W, H, &td))
    frame.draw_topdown(td);
  else
    frame.draw_rays();
  img.dynamic.assign(size_t(W) * H * 4, 0.0f);
  if (opt.draw_dynamic) frame.draw_dynamic();
  frame.composite();
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall0).count();
  img.times.push_back({"cpu frame", ms, ms});
  return img;
}

}  // namespace prep::render
