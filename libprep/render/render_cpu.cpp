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

// The terrain pass's Lambert shade at a ground point, as terrain.frag.glsl
// computes it: the vertex normals of the triangle the point lies in
// (Heightfield::triangle_gradient's split of the cell), interpolated
// linearly over it as GL interpolates v_normal, normalised.
double shade_at(const Heightfield& t, double x, double y) {
  const Vec3 light = detail::normalize(detail::kLightTowards);
  const int i = std::clamp(int(std::floor((x - t.x0) / t.dx)), 0, int(t.nx) - 2),
            j = std::clamp(int(std::floor((y - t.y0) / t.dy)), 0, int(t.ny) - 2);
  const double u = std::clamp((x - t.x0) / t.dx - i, 0.0, 1.0),
               v = std::clamp((y - t.y0) / t.dy - j, 0.0, 1.0);
  const Vec3 n00 = t.normal_at(i, j), n11 = t.normal_at(i + 1, j + 1);
  Vec3 n;
  if (v <= u) {  // the lower triangle (00, 10, 11)
    const Vec3 n10 = t.normal_at(i + 1, j);
    n = detail::add(detail::add(detail::mul(n00, 1 - u), detail::mul(n10, u - v)),
                    detail::mul(n11, v));
  } else {  // the upper triangle (00, 11, 01)
    const Vec3 n01 = t.normal_at(i, j + 1);
    n = detail::add(detail::add(detail::mul(n00, 1 - v), detail::mul(n11, u)),
                    detail::mul(n01, v - u));
  }
  const double l = std::max(detail::dot(detail::normalize(n), light), 0.0);
  return 0.35 + 0.65 * l;
}

// Terrain colour of the CPU path: albedo (the sea tint at or below 0 m, as
// terrain.frag.glsl; flat terrain is land) times the shade.
std::array<double, 3> terrain_colour(const Heightfield& t, const RenderOptions& opt, double z,
                                     double shade) {
  std::array<double, 3> albedo = opt.albedo;
  if (t.zmax > t.zmin && z <= 0.0) albedo = {0.45, 0.58, 0.70};
  return {albedo[0] * shade, albedo[1] * shade, albedo[2] * shade};
}

}  // namespace

Image render_cpu(const DecalSource& source, const Heightfield& terrain, const RenderOptions& opt) {
  const TileSource whole{source, Extent{-INFINITY, -INFINITY, INFINITY, INFINITY}, 0, 0};
  return render_cpu(std::span<const TileSource>(&whole, 1), terrain, opt);
}

Image render_cpu(std::span<const TileSource> tiles, const Heightfield& terrain,
                 const RenderOptions& opt) {
  return render_cpu(tile_list(tiles, opt), terrain, opt);
}

namespace {

// Runs body(i) for i in [0, n), over up to 16 threads, at least `grain`
// items a thread (evaluate() is thread-safe; each i is written once).
template <class Body>
void parallel_for(size_t n, size_t grain, Body&& body) {
  const size_t cpus = std::max(1u, std::min(16u, std::thread::hardware_concurrency()));
  const size_t nthreads = std::max<size_t>(1, std::min(cpus, (n + grain - 1) / grain));
  auto run = [&](size_t i0) {
    for (size_t i = i0; i < n; i += nthreads) body(i);
  };
  std::vector<std::thread> workers;
  for (size_t t = 1; t < nthreads; ++t) workers.emplace_back(run, t);
  run(0);
  for (auto& w : workers) w.join();
}

// Pixels a thread evaluates at the least (a thread costs about as much as
// evaluating a few hundred).
constexpr size_t kPixelGrain = 4096;

// One CPU frame of several tiles: each pixel's ground point (NaN x where
// its ray sees sky), the tile whose square holds it, then tile by tile:
// the tile opened, its pixels evaluated (static decals, then dynamic
// lines), the tile let go.
struct CpuFrame {
  const TileList& tiles;
  const Heightfield& terrain;
  const RenderOptions& opt;
  uint32_t W, H;
  Image& img;
  std::vector<double> hit_x, hit_y, hit_z;
  // The decals' share from layers drawn unlit (EvalSample::unlit_rgb,
  // premultiplied), kept out of the light in composite(); empty until a
  // tile has such layers under opt.decal_light.
  std::vector<float> unlit;

  CpuFrame(const TileList& t, const Heightfield& h, const RenderOptions& o, Image& i)
      : tiles(t),
        terrain(h),
        opt(o),
        W(o.width),
        H(o.height),
        img(i),
        hit_x(size_t(W) * H, NAN),
        hit_y(size_t(W) * H, NAN),
        hit_z(size_t(W) * H, 0.0) {}

  // Ground metres of one pixel at the point (static_common.glsl
  // pixel_metres): the view's constant orthographic size, or the distance
  // to the eye times 2 tan(fov_y / 2) / H.
  double pixel_metres(double x, double y, double z) const {
    const Camera& c = opt.camera;
    if (c.projection == Projection::orthographic) return detail::ortho_pixel_metres(c, H);
    return std::hypot(x - c.eye[0], y - c.eye[1], z - c.eye[2]) *
           detail::pixel_metres_per_metre(c, H);
  }

  // The tile whose half-open square holds (x, y); none: places.size().
  size_t tile_at(double x, double y) const {
    for (size_t k = 0; k < tiles.places.size(); ++k) {
      const Extent& q = tiles.places[k].square;
      if (x >= q.xmin && x < q.xmax && y >= q.ymin && y < q.ymax) return k;
    }
    return tiles.places.size();
  }

  void put(size_t k, const EvalSample& s) {
    const float a = s.rgba[3];
    for (int c = 0; c < 3; ++c) img.decals[4 * k + c] = a > 0 ? s.rgba[c] / a : 0.0f;
    img.decals[4 * k + 3] = a;
    if (!unlit.empty())
      std::copy(s.unlit_rgb, s.unlit_rgb + 3, unlit.begin() + std::ptrdiff_t(3 * k));
  }

  // Exactly the render_topdown pixel grid; the terrain is under every pixel.
  void topdown_points(const Extent& td) {
    for (uint32_t j = 0; j < H; ++j)
      for (uint32_t i = 0; i < W; ++i) {
        hit_x[i + size_t(W) * j] = td.xmin + (i + 0.5) * (td.xmax - td.xmin) / W;
        hit_y[i + size_t(W) * j] = td.ymax - (j + 0.5) * (td.ymax - td.ymin) / H;
        hit_z[i + size_t(W) * j] = 1.0;  // top-down: terrain tint not derived per pixel
      }
  }

  // Ray-casts the heightfield mesh in double precision from the pixel centre.
  void ray_points() {
    const detail::PixelRays rays(opt.camera, W, H);
    parallel_for(H, 1, [&](size_t j) {
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
      }
    });
  }

  // The pixels with a ground point, grouped by the tile that answers them
  // (counting sort: tile k's are pixels[first[k] .. first[k + 1])).
  void group(std::vector<uint32_t>& pixels, std::vector<size_t>& first) const {
    const size_t n = tiles.places.size(), none = n;
    std::vector<uint32_t> owner(size_t(W) * H, uint32_t(none));
    parallel_for(H, 1, [&](size_t j) {
      for (size_t k = j * W; k < (j + 1) * W; ++k)
        if (!std::isnan(hit_x[k])) owner[k] = uint32_t(tile_at(hit_x[k], hit_y[k]));
    });
    first.assign(n + 1, 0);
    for (uint32_t o : owner)
      if (o != none) ++first[o + 1];
    for (size_t k = 1; k <= n; ++k) first[k] += first[k - 1];
    pixels.resize(first[n]);
    std::vector<size_t> next(first.begin(), first.end() - 1);
    for (size_t k = 0; k < owner.size(); ++k)
      if (owner[k] != none) pixels[next[owner[k]]++] = uint32_t(k);
  }

  // Static decals, then dynamic lines, of tile k at `pixels`.
  void draw_tile(size_t k, std::span<const uint32_t> pixels) {
    const OpenedTile opened = tiles.open(k);
    const TileSource& t = opened.tile;
    const TilePlace& at = tiles.places[k];
    // Kinds not drawn are left out of the view the evaluator sees.
    StaticView view = t.source.view;
    if (!opt.draw_polygons) view.poly_bvh_range = {};
    if (!opt.draw_lines) view.line_bvh_range = {};
    // Slope widths (formats/SPEC.md "Slope widths"): the tile's flagged
    // layers, measured along the gradient of the terrain triangle under the
    // point (the ray's hit triangle; the one under the pixel centre top-down).
    const std::vector<uint8_t> slope =
        opt.draw_lines ? slope_layers(t.source, opt.slope_widths) : std::vector<uint8_t>{};
    // Layers drawn unlit (light = false) under lit decals.
    const std::span<const uint8_t> flat = opt.decal_light
                                              ? std::span<const uint8_t>(t.source.unlit_layers)
                                              : std::span<const uint8_t>{};
    if (!flat.empty() && unlit.empty()) unlit.assign(3 * size_t(W) * H, 0.0f);
    // Minimum widths (formats/SPEC.md "Minimum widths"): the ground size of
    // each pixel at its point, as static_common.glsl pixel_metres.
    const bool widths = !t.source.min_width_px.empty() && t.source.min_width_pixel_m > 0;
    const double reach = min_width_reach(t.source);
    parallel_for(pixels.size(), kPixelGrain, [&](size_t i) {
      const size_t p = pixels[i];
      const double x = hit_x[p], y = hit_y[p];
      if (slope.empty() && flat.empty() && !widths)
        return put(p, evaluate(view, x - at.dx, y - at.dy));
      EvalPixel px;
      if (!slope.empty()) {
        const std::array<double, 2> g = terrain.gradient_at(x, y);
        px.slope = {g[0], g[1], slope};
      }
      px.unlit = flat;
      if (widths) {
        px.pixel_m = pixel_metres(x, y, hit_z[p]);
        px.min_width_px = t.source.min_width_px;
        px.min_width_pixel_m = t.source.min_width_pixel_m;
        px.line_box_margin_m = reach * std::min(px.pixel_m, px.min_width_pixel_m);
      }
      put(p, evaluate(view, x - at.dx, y - at.dy, px));
    });
    if (opt.draw_dynamic) draw_dynamic(t.source, at, pixels);
  }

  // Dynamic lines, as the GL pass draws them (detail/dynamic_cpu.hpp): the
  // tile's in its own frame, at the ground point of each of its pixels.
  void draw_dynamic(const DecalSource& source, const TilePlace& at,
                    std::span<const uint32_t> pixels) {
    const Camera& cam = opt.camera;
    Camera c = cam;
    c.eye = {cam.eye[0] - at.dx, cam.eye[1] - at.dy, cam.eye[2]};
    c.target = {cam.target[0] - at.dx, cam.target[1] - at.dy, cam.target[2]};
    const detail::DynamicLinesCpu dyn(
        source, c, W, H,
        detail::DynamicLod{opt.lod, opt.lod_tolerance_px, terrain.zmin, terrain.zmax});
    const std::array<uint64_t, 4> n = dyn.lod_counts();
    img.lod_lines += n[0];
    img.lod_selected += n[1];
    img.lod_drawn += n[2];
    img.lod_full += n[3];
    if (dyn.empty()) return;
    parallel_for(pixels.size(), kPixelGrain, [&](size_t i) {
      const size_t p = pixels[i];
      const std::array<float, 4> col = dyn.at({hit_x[p] - at.dx, hit_y[p] - at.dy, hit_z[p]});
      std::copy(col.begin(), col.end(), img.dynamic.begin() + std::ptrdiff_t(4 * p));
    });
  }

  void draw() {
    Extent td;
    const bool topdown = is_topdown(opt.camera, W, H, &td);
    if (topdown)
      topdown_points(td);
    else
      ray_points();
    // One package top-down without slope widths: exactly render_topdown.
    const bool single = tiles.places.size() == 1 && std::isinf(tiles.places[0].square.xmin);
    if (single && topdown) {
      const OpenedTile opened = tiles.open(0);
      const DecalSource& source = opened.tile.source;
      if ((!opt.draw_lines || slope_layers(source, opt.slope_widths).empty()) &&
          (!opt.decal_light || source.unlit_layers.empty()) &&
          (!opt.draw_lines || source.min_width_px.empty())) {
        StaticView view = source.view;
        if (!opt.draw_polygons) view.poly_bvh_range = {};
        if (!opt.draw_lines) view.line_bvh_range = {};
        img.decals = render_topdown(view, td, W, H);
        std::vector<uint32_t> all(size_t(W) * H);
        for (size_t k = 0; k < all.size(); ++k) all[k] = uint32_t(k);
        if (opt.draw_dynamic) draw_dynamic(source, tiles.places[0], all);
        return;
      }
    }
    std::vector<uint32_t> pixels;
    std::vector<size_t> first;
    group(pixels, first);
    for (size_t k = 0; k < tiles.places.size(); ++k)
      if (first[k + 1] > first[k])
        draw_tile(k, std::span<const uint32_t>(pixels).subspan(first[k], first[k + 1] - first[k]));
  }

  // Final image: dynamic lines over the decal layer (lit by the terrain's
  // shade with opt.decal_light) over the shaded terrain, sky where no
  // terrain (composite.frag.glsl).
  void composite() {
    for (size_t k = 0; k < size_t(W) * H; ++k) {
      std::array<double, 3> base{0.80, 0.86, 0.93};
      double lit = 1;
      if (!std::isnan(hit_x[k])) {
        const double s = shade_at(terrain, hit_x[k], hit_y[k]);
        base = terrain_colour(terrain, opt, hit_z[k], s);
        if (opt.decal_light) lit = s;
      }
      const double a = img.decals[4 * k + 3], l = img.dynamic[4 * k + 3];
      for (int c = 0; c < 3; ++c) {
        // Unlit layers' share (light = false) is added without the shade.
        const double flat = unlit.empty() ? 0.0 : unlit[3 * k + c];
        const double under = (img.decals[4 * k + c] * a - flat) * lit + flat + (1 - a) * base[c];
        const double v = img.dynamic[4 * k + c] * l + (1 - l) * under;
        img.rgba[4 * k + c] = uint8_t(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
      }
      img.rgba[4 * k + 3] = 255;
    }
  }
};

}  // namespace

Image render_cpu(const TileList& tiles, const Heightfield& terrain, const RenderOptions& opt) {
  const uint32_t W = opt.width, H = opt.height;
  auto wall0 = std::chrono::steady_clock::now();
  Image img;
  img.width = W;
  img.height = H;
  img.device = "cpu";
  img.decals.assign(size_t(W) * H * 4, 0.0f);
  img.rgba.assign(size_t(W) * H * 4, 0);
  img.dynamic.assign(size_t(W) * H * 4, 0.0f);
  CpuFrame frame(tiles, terrain, opt, img);
  frame.draw();
  frame.composite();
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall0).count();
  img.times.push_back({"cpu frame", ms, ms});
  return img;
}

}  // namespace prep::render
