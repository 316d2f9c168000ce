// The GL path (thesis §4.4): terrain G-buffer, static polygon and line
// passes over the back-projected depth (one per run of the drawing order),
// dynamic lines, composite, read back. The passes are in gl_passes.cpp and
// gl_dynamic.cpp (detail/gl_render.hpp).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include "detail/gl_render.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "prep/stage_error.hpp"

namespace prep::render {

namespace detail {

namespace {

// GL rows are bottom-up: turns `v` (rows of `row` elements) upside down in
// place, so that read-back needs no second copy of the frame.
template <class T>
void flip_rows(std::vector<T>& v, size_t row, uint32_t H) {
  for (uint32_t y = 0; y < H / 2; ++y)
    std::swap_ranges(v.begin() + std::ptrdiff_t(y * row), v.begin() + std::ptrdiff_t((y + 1) * row),
                     v.begin() + std::ptrdiff_t((H - 1 - y) * row));
}

// Premultiplied alpha to straight, in place.
void straighten(std::vector<float>& v) {
  for (size_t k = 0; k + 3 < v.size(); k += 4) {
    const float a = v[k + 3];
    for (int c = 0; c < 3; ++c) v[k + c] = a > 0 ? v[k + c] / a : 0.0f;
  }
}

}  // namespace

void GlRenderer::read_back(Image& img) {
  const uint32_t W = W_, H = H_;
  img.rgba.assign(size_t(W) * H * 4, 0);
  img.decals.assign(size_t(W) * H * 4, 0.0f);
  img.dynamic.assign(size_t(W) * H * 4, 0.0f);
  glGetTextureImage(t_.dyn, 0, GL_RGBA, GL_FLOAT, GLsizei(img.dynamic.size() * sizeof(float)),
                    img.dynamic.data());
  glGetTextureImage(t_.final, 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(img.rgba.size()),
                    img.rgba.data());
  glGetTextureImage(t_.decal, 0, GL_RGBA, GL_FLOAT, GLsizei(img.decals.size() * sizeof(float)),
                    img.decals.data());
  if (GLenum e = glGetError(); e != GL_NO_ERROR)
    fail<render_error>(kRenderStage, "GL error " + std::to_string(e));
  if (!tiles_)
    timer_.collect(img.times);
  else
    timer_.collect_per_pass(img.times);
  if (!m_.raster_time.pass.empty()) img.times.insert(img.times.begin(), m_.raster_time);
  const double frame =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall0_).count();
  img.times.push_back({"total (incl. upload, shader compile, read-back)", frame, frame});
  const size_t row = size_t(W) * 4;
  flip_rows(img.rgba, row, H);
  flip_rows(img.decals, row, H);
  flip_rows(img.dynamic, row, H);
  straighten(img.decals);
  straighten(img.dynamic);
}

}  // namespace detail

namespace {

// Whether a tileset is drawn in one frame (render_gl of tiles below).
bool one_frame(const TileList& tiles, const RenderOptions& opt) {
  if (opt.method != Method::decal) return false;
  for (const TilePlace& t : tiles.places)
    if (!detail::tile_shift(t)) return false;
  return true;
}

// One context; the renderer make() returns (its GL objects go before the
// context) draws opt.frames frames and reads the last back. Frames after
// the first show warm times (software GL compiles shader variants at
// their first draw); pass times are the last frame's.
template <class Make>
Image draw_frames(const RenderOptions& opt, Make&& make) {
  std::unique_ptr<decal::gl::Context> context;
  detail::check(decal::gl::Context::create(context));
  Image img;
  img.width = opt.width;
  img.height = opt.height;
  img.device = context->info().renderer;
  {
    std::unique_ptr<detail::GlRenderer> gl = make();
    for (uint32_t frame = 0; frame < std::max<uint32_t>(opt.frames, 1); ++frame) gl->frame(img);
    gl->read_back(img);
  }
  return img;
}

}  // namespace

Image render_gl(const DecalSource& source, const Heightfield& terrain, const RenderOptions& opt) {
  check_render_options(opt);
  // Validate before anything touches GL (formats/gl validate_blobs), once:
  // a package's source was checked when it was made.
  const std::vector<decal::gl::BlobBytes> blobs = detail::gl_blobs(source);
  const decal::gl::Grid grid = detail::gl_grid(source);
  if (!source.validated) detail::check(decal::gl::validate_blobs(blobs, grid));
  return draw_frames(
      opt, [&] { return std::make_unique<detail::GlRenderer>(blobs, grid, source, terrain, opt); });
}

Image render_gl(std::span<const TileSource> tiles, const Heightfield& terrain,
                const RenderOptions& opt) {
  return render_gl(tile_list(tiles, opt), terrain, opt);
}

Image render_gl(const TileList& tiles, const Heightfield& terrain, const RenderOptions& opt) {
  if (tiles.places.size() == 1 && std::isinf(tiles.places[0].square.xmin))
    return render_gl(tiles.open(0).tile.source, terrain, opt);
  if (tiles.places.empty())
    fail<usage_error>(kRenderStage, "no tile of the tileset meets the view");
  // The decal method draws every tile in one frame, in one context: the
  // terrain G-buffer once in the index frame, then per tile its static and
  // dynamic passes clipped to its square into the shared layers, its blobs
  // on the GPU only while they draw; composite and read back once.
  // Precision: a tile's frame is the index frame moved by its (dx, dy), a
  // whole number of quanta (tileset origins are quantised), so the anchor
  // in the tile's frame is the index anchor minus that integer, and every
  // float the GPU holds relative to the anchor (eye, matrices, terrain
  // depth, clip) is the same as in the tile's own render below; only the
  // integer anchor uniforms and the anchor's offset in its grid cell
  // (double on the CPU) differ per tile (GlRenderer::load_tile). The
  // result is the per-tile render's up to the rounding of the terrain
  // vertices (x0 - dx + i*dx - anchor there, x0 + i*dx - anchor here).
  // Pixels are not merged: squares are half-open and do not overlap, so
  // each pixel centre (each sample with MSAA) is drawn by one tile at most;
  // the passes blend under what the shared layers hold.
  // Each tile is opened as its turn comes and let go after its passes
  // (GlRenderer::load_tile), its blobs validated then, before GL sees them.
  if (one_frame(tiles, opt)) {
    check_render_options(opt);
    return draw_frames(opt,
                       [&] { return std::make_unique<detail::GlRenderer>(tiles, terrain, opt); });
  }
  // The volume and texture methods (and tile origins off the quantum
  // grid) keep one draw per tile, each with its own context: their set-up
  // (prisms, the decal texture) is per package and made before the frame.
  // Each tile is drawn in its own frame (camera and terrain moved by its
  // origin, so GL precision is the single package's), its decals clipped
  // to its square; each pixel then takes the tile that drew there. Squares
  // do not overlap, so without anti-aliasing exactly one tile can.
  Image out;
  for (size_t k = 0; k < tiles.places.size(); ++k) {
    const TilePlace& t = tiles.places[k];
    RenderOptions o = opt;
    for (Vec3* v : {&o.camera.eye, &o.camera.target}) {
      (*v)[0] -= t.dx;
      (*v)[1] -= t.dy;
    }
    if (o.camera.topdown_extent) {
      Extent& e = *o.camera.topdown_extent;
      e = {e.xmin - t.dx, e.ymin - t.dy, e.xmax - t.dx, e.ymax - t.dy};
    }
    o.clip = Extent{t.square.xmin - t.dx, t.square.ymin - t.dy, t.square.xmax - t.dx,
                    t.square.ymax - t.dy};
    Heightfield h = terrain;
    h.x0 -= t.dx;
    h.y0 -= t.dy;
    Image img = render_gl(tiles.open(k).tile.source, h, o);
    if (out.rgba.empty()) {
      out = std::move(img);
      continue;
    }
    for (size_t p = 0; p < size_t(out.width) * out.height; ++p) {
      const float a = img.decals[4 * p + 3] + img.dynamic[4 * p + 3];
      const float b = out.decals[4 * p + 3] + out.dynamic[4 * p + 3];
      if (!(a > b)) continue;
      for (int c = 0; c < 4; ++c) {
        out.rgba[4 * p + c] = img.rgba[4 * p + c];
        out.decals[4 * p + c] = img.decals[4 * p + c];
        out.dynamic[4 * p + c] = img.dynamic[4 * p + c];
      }
    }
    for (uint32_t Image::*m :
         {&Image::dyn_kept, &Image::dyn_segments, &Image::dyn_nodes, &Image::dyn_truncated,
          &Image::list_grows, &Image::volume_groups, &Image::zfail_groups})
      out.*m += img.*m;
    for (uint64_t Image::*m :
         {&Image::prism_triangles, &Image::texture_bytes, &Image::texture_triangles,
          &Image::lod_lines, &Image::lod_selected, &Image::lod_drawn, &Image::lod_full})
      out.*m += img.*m;
    for (PassTime& pt : img.times) out.times.push_back(std::move(pt));
    out.lod_selection.insert(out.lod_selection.end(), img.lod_selection.begin(),
                             img.lod_selection.end());
  }
  return out;
}

}  // namespace prep::render
