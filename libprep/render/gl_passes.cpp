// The GL path's objects, setup and passes (thesis §4.4) other than the
// dynamic lines (gl_dynamic.cpp): terrain G-buffer, static polygon and line
// passes over the back-projected depth, composite.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "decal/gl/bindings.hpp"
#include "decal/layout.hpp"
#include "detail/gl_render.hpp"
#include "detail/math.hpp"
#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep::render::detail {

namespace {

std::array<float, 16> to_float(const Mat4& m) {
  std::array<float, 16> f{};
  for (int k = 0; k < 16; ++k) f[k] = static_cast<float>(m[k]);
  return f;
}

// Floor division for the grid cell of the anchor.
int64_t floor_div(int64_t a, int64_t b) {
  int64_t q = a / b;
  if ((a % b != 0) && ((a < 0) != (b < 0))) --q;
  return q;
}

}  // namespace

void check(const decal::Status& s) {
  if (!s) fail<render_error>(kNoStage, s.message);
}

// --- GlObjects, PassTimer

GlObjects::~GlObjects() {
  for (GLuint p : programs) glDeleteProgram(p);
  if (!textures.empty()) glDeleteTextures(GLsizei(textures.size()), textures.data());
  if (!framebuffers.empty())
    glDeleteFramebuffers(GLsizei(framebuffers.size()), framebuffers.data());
  if (!buffers.empty()) glDeleteBuffers(GLsizei(buffers.size()), buffers.data());
  if (!arrays.empty()) glDeleteVertexArrays(GLsizei(arrays.size()), arrays.data());
  if (!queries.empty()) glDeleteQueries(GLsizei(queries.size()), queries.data());
}

GLuint GlObjects::texture(GLenum format, uint32_t w, uint32_t h) {
  GLuint t = 0;
  glCreateTextures(GL_TEXTURE_2D, 1, &t);
  glTextureStorage2D(t, 1, format, GLsizei(w), GLsizei(h));
  glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  textures.push_back(t);
  return t;
}

GLuint GlObjects::framebuffer(GLuint color, GLuint depth) {
  GLuint f = 0;
  glCreateFramebuffers(1, &f);
  glNamedFramebufferTexture(f, GL_COLOR_ATTACHMENT0, color, 0);
  if (depth) {
    GLint format = 0;
    glGetTextureLevelParameteriv(depth, 0, GL_TEXTURE_INTERNAL_FORMAT, &format);
    glNamedFramebufferTexture(
        f, format == GL_DEPTH32F_STENCIL8 ? GL_DEPTH_STENCIL_ATTACHMENT : GL_DEPTH_ATTACHMENT,
        depth, 0);
  }
  framebuffers.push_back(f);
  if (glCheckNamedFramebufferStatus(f, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    fail<render_error>(kRenderStage, "framebuffer incomplete");
  return f;
}

GLuint GlObjects::program(decal::gl::ProgramSources src) {
  std::string key = src.defines;
  for (const auto* list : {&src.vertex, &src.geometry, &src.fragment, &src.compute}) {
    key += "|";
    for (const auto& f : *list) key += f + ",";
  }
  if (auto it = program_cache.find(key); it != program_cache.end()) return it->second;
  GLuint p = 0;
  check(decal::gl::build_program(src, p));
  programs.push_back(p);
  program_cache.emplace(key, p);
  return p;
}

GLuint PassTimer::stamp() {
  GLuint q = 0;
  glGenQueries(1, &q);
  gl.queries.push_back(q);
  glQueryCounter(q, GL_TIMESTAMP);
  return q;
}

void PassTimer::begin(const std::string& name) {
  glFinish();
  passes.push_back({name, 0, 0, std::chrono::steady_clock::now(), {}, tile});
  passes.back().begin = stamp();
}

void PassTimer::end() {
  passes.back().end = stamp();
  glFinish();
  passes.back().wall1 = std::chrono::steady_clock::now();
}

void PassTimer::collect(std::vector<PassTime>& out) {
  for (const auto& p : passes) {
    GLuint64 t0 = 0, t1 = 0;
    glGetQueryObjectui64v(p.begin, GL_QUERY_RESULT, &t0);
    glGetQueryObjectui64v(p.end, GL_QUERY_RESULT, &t1);
    out.push_back({p.name, t1 >= t0 ? double(t1 - t0) * 1e-6 : 0.0,
                   std::chrono::duration<double, std::milli>(p.wall1 - p.wall0).count()});
  }
}

void PassTimer::collect_per_pass(std::vector<PassTime>& out) {
  std::vector<PassTime> each;
  collect(each);
  struct Row {
    PassTime sum;
    size_t draws = 0, tiles = 0;
    int last_tile = -1;
    bool per_tile = false;
  };
  std::vector<Row> rows;
  for (size_t k = 0; k < each.size(); ++k) {
    const int tile = passes[k].tile;
    std::string name = each[k].pass;
    if (tile >= 0) name = name.substr(0, name.find(" ["));
    auto it = std::find_if(rows.begin(), rows.end(), [&](const Row& r) {
      return r.sum.pass == name && r.per_tile == (tile >= 0);
    });
    if (it == rows.end()) {
      rows.push_back({{name, 0, 0}, 0, 0, -1, tile >= 0});
      it = rows.end() - 1;
    }
    it->sum.ms += each[k].ms;
    it->sum.wall_ms += each[k].wall_ms;
    it->draws++;
    if (tile != it->last_tile) it->tiles++, it->last_tile = tile;
  }
  for (Row& r : rows) {
    if (r.per_tile)
      r.sum.pass += " [" + (r.draws != r.tiles ? std::to_string(r.draws) + " draws, " : "") +
                    std::to_string(r.tiles) + (r.tiles == 1 ? " tile]" : " tiles]");
    out.push_back(std::move(r.sum));
  }
}

// --- setup

ViewUniforms view_uniforms(const Camera& cam, const GridParams& gp, uint32_t W, uint32_t H) {
  ViewUniforms v;
  const double q = decal::kQuantumMetres;
  set_anchor(v, cam, std::llround(cam.eye[0] / q), std::llround(cam.eye[1] / q), W, H);
  set_grid(v, gp);
  v.mpp_ortho = ortho_pixel_metres(cam, H);
  v.mpp_per_metre = pixel_metres_per_metre(cam, H);
  v.near_w = cam.projection == Projection::perspective ? cam.near : 0.0;
  return v;
}

void set_anchor(ViewUniforms& v, const Camera& cam, int64_t ax, int64_t ay, uint32_t W,
                uint32_t H) {
  const double q = decal::kQuantumMetres;
  v.ax = ax;
  v.ay = ay;
  v.anchor = {double(v.ax) * q, double(v.ay) * q, 0.0};
  v.eye_rel = sub(cam.eye, v.anchor);
  const Mat4 vp = mat_mul(projection_matrix(cam, double(W) / H), view_matrix(cam, v.eye_rel));
  v.view_proj = to_float(vp);
  v.inv_view_proj = to_float(mat_inverse(vp));
}

void set_grid(ViewUniforms& v, const GridParams& gp) {
  v.rx = v.ax - gp.origin_x;
  v.ry = v.ay - gp.origin_y;
  v.cell_x = floor_div(v.rx, gp.cell_w);
  v.cell_y = floor_div(v.ry, gp.cell_h);
  v.grid = gp;
}

void set_clip(ViewUniforms& v, const Extent& clip) {
  const double q = decal::kQuantumMetres;
  const double ax = double(v.ax) * q, ay = double(v.ay) * q;
  v.clip = {float(clip.xmin - ax), float(clip.ymin - ay), float(clip.xmax - ax),
            float(clip.ymax - ay)};
}

void attach_second(GLuint fb, GLuint tex, const char* what) {
  glNamedFramebufferTexture(fb, GL_COLOR_ATTACHMENT1, tex, 0);
  const GLenum both[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glNamedFramebufferDrawBuffers(fb, 2, both);
  if (glCheckNamedFramebufferStatus(fb, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    fail<render_error>(kRenderStage, std::string("framebuffer incomplete (") + what + ")");
}

Targets make_targets(GlObjects& gl, uint32_t W, uint32_t H, bool stencil, bool slope, bool unlit) {
  Targets t;
  t.color = gl.texture(GL_RGBA8, W, H);
  t.depth = gl.texture(stencil ? GL_DEPTH32F_STENCIL8 : GL_DEPTH_COMPONENT32F, W, H);
  t.decal = gl.texture(GL_RGBA32F, W, H);
  t.final = gl.texture(GL_RGBA8, W, H);
  t.dyn = gl.texture(GL_RGBA32F, W, H);
  t.f_terrain = gl.framebuffer(t.color, t.depth);
  if (slope) {
    t.gradient = gl.texture(GL_RG32F, W, H);
    attach_second(t.f_terrain, t.gradient, "terrain gradient");
  }
  t.f_decal = gl.framebuffer(t.decal, 0);
  if (unlit) {
    t.unlit = gl.texture(GL_RGBA32F, W, H);
    attach_second(t.f_decal, t.unlit, "unlit share");
  }
  t.f_final = gl.framebuffer(t.final, 0);
  t.f_dyn = gl.framebuffer(t.dyn, 0);
  return t;
}

TerrainMesh upload_terrain_mesh(GlObjects& gl, const Heightfield& terrain, const Vec3& anchor,
                                bool slope) {
  std::vector<float> verts;
  verts.reserve(size_t(terrain.nx) * terrain.ny * 6);
  for (uint32_t j = 0; j < terrain.ny; ++j)
    for (uint32_t i = 0; i < terrain.nx; ++i) {
      Vec3 n = terrain.normal_at(i, j);
      verts.push_back(float(terrain.x0 + i * terrain.dx - anchor[0]));
      verts.push_back(float(terrain.y0 + j * terrain.dy - anchor[1]));
      verts.push_back(float(terrain.z[i + size_t(terrain.nx) * j]));
      verts.push_back(float(n[0]));
      verts.push_back(float(n[1]));
      verts.push_back(float(n[2]));
    }
  std::vector<uint32_t> idx;
  idx.reserve(size_t(terrain.nx - 1) * (terrain.ny - 1) * 6);
  for (uint32_t j = 0; j + 1 < terrain.ny; ++j)
    for (uint32_t i = 0; i + 1 < terrain.nx; ++i) {
      uint32_t v00 = i + terrain.nx * j, v10 = v00 + 1, v01 = v00 + terrain.nx, v11 = v01 + 1;
      idx.insert(idx.end(), {v00, v10, v11, v00, v11, v01});
    }
  GLuint vbo = 0, ibo = 0, vao = 0;
  glCreateBuffers(1, &vbo);
  gl.buffers.push_back(vbo);
  glNamedBufferStorage(vbo, GLsizeiptr(verts.size() * sizeof(float)), verts.data(), 0);
  glCreateBuffers(1, &ibo);
  gl.buffers.push_back(ibo);
  glNamedBufferStorage(ibo, GLsizeiptr(idx.size() * sizeof(uint32_t)), idx.data(), 0);
  glCreateVertexArrays(1, &vao);
  gl.arrays.push_back(vao);
  glVertexArrayVertexBuffer(vao, 0, vbo, 0, 6 * sizeof(float));
  glVertexArrayElementBuffer(vao, ibo);
  glEnableVertexArrayAttrib(vao, 0);
  glEnableVertexArrayAttrib(vao, 1);
  glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribFormat(vao, 1, 3, GL_FLOAT, GL_FALSE, 3 * sizeof(float));
  glVertexArrayAttribBinding(vao, 0, 0);
  glVertexArrayAttribBinding(vao, 1, 0);
  GLuint gradients = 0;
  if (slope) {
    // Primitive 2 k + upper of cell k = i + (nx - 1) j, as drawn above.
    std::vector<float> g;
    g.reserve(size_t(terrain.nx - 1) * (terrain.ny - 1) * 4);
    for (uint32_t j = 0; j + 1 < terrain.ny; ++j)
      for (uint32_t i = 0; i + 1 < terrain.nx; ++i)
        for (bool upper : {false, true}) {
          const std::array<double, 2> t = terrain.triangle_gradient(i, j, upper);
          g.push_back(float(t[0]));
          g.push_back(float(t[1]));
        }
    glCreateBuffers(1, &gradients);
    gl.buffers.push_back(gradients);
    glNamedBufferStorage(gradients, GLsizeiptr(g.size() * sizeof(float)), g.data(), 0);
  }
  return {vao, GLsizei(idx.size()), gradients};
}

StaticPrograms static_programs(GlObjects& gl, const RenderOptions& opt, bool slope, bool unlit,
                               bool min_widths) {
  StaticPrograms p;
  p.defines = opt.binding == Binding::texture ? "#define DECAL_TEXTURE 1\n" : "";
  const std::string aa_defines = opt.aa == AntiAliasing::coverage ? "#define DECAL_AA_COVERAGE 1\n"
                                 : opt.aa == AntiAliasing::msaa4  ? "#define DECAL_MSAA 1\n"
                                                                  : "";
  const std::string slope_define = slope ? "#define DECAL_SLOPE_WIDTHS 1\n" : "";
  const std::string unlit_define = unlit ? "#define DECAL_UNLIT_LAYERS 1\n" : "";
  p.terrain = gl.program({{"terrain.vert.glsl"}, {}, {"terrain.frag.glsl"}, {}, slope_define});
  p.polygons = gl.program({{"fullscreen.vert.glsl"},
                           {},
                           {"decal_blobs.glsl", "static_common.glsl", "static_polygons.glsl"},
                           {},
                           p.defines + aa_defines + unlit_define + "#define DECAL_POLYGONS 1\n"});
  p.lines = gl.program({{"fullscreen.vert.glsl"},
                        {},
                        {"decal_blobs.glsl", "static_common.glsl", "slope_widths.glsl", "dash.glsl",
                         "static_lines.glsl"},
                        {},
                        p.defines + aa_defines + slope_define + unlit_define +
                            (min_widths ? "#define DECAL_MIN_WIDTHS 1\n" : "") +
                            "#define DECAL_LINES 1\n"});
  p.composite =
      gl.program({{"fullscreen.vert.glsl"}, {}, {"composite.frag.glsl"}, {}, unlit_define});
  return p;
}

GlRenderer::GlRenderer(std::span<const decal::gl::BlobBytes> blobs, const decal::gl::Grid& grid,
                       const DecalSource& source, const Heightfield& terrain,
                       const RenderOptions& opt)
    : source_(&source), terrain_(terrain), opt_(opt), W_(opt.width), H_(opt.height) {
  wall0_ = std::chrono::steady_clock::now();
  check(decal::gl::GpuPackage::upload(blobs, grid, gpu_, true));
  view0_ = view_uniforms(opt.camera, source.view.grid, W_, H_);
  if (opt.clip) set_clip(view0_, *opt.clip);
  view_ = view0_;
  runs_ = draw_runs(source.view);
  slope_ = opt.method == Method::decal && opt.draw_lines &&
           !slope_layers(source, opt.slope_widths).empty();
  // Layers drawn unlit: the decal method's static passes and the volume
  // method's cover pass; the texture method lights its whole texture.
  unlit_ = opt.decal_light && opt.method != Method::texture && !source.unlit_layers.empty();
  min_widths_ = opt.method == Method::decal && opt.draw_lines && !source.min_width_px.empty() &&
                source.min_width_pixel_m > 0;
  setup();
  if (slope_) upload_slope_layers(source);
  if (unlit_) upload_unlit_layers(source);
  if (min_widths_) upload_min_widths(source);
  if (opt.method != Method::decal) method_setup();
}

GlRenderer::GlRenderer(const TileList& tiles, const Heightfield& terrain, const RenderOptions& opt)
    : tiles_(&tiles), terrain_(terrain), opt_(opt), W_(opt.width), H_(opt.height) {
  wall0_ = std::chrono::steady_clock::now();
  if (opt.method != Method::decal || tiles.places.empty())
    fail<render_error>(kRenderStage, "a tileset in one frame takes the decal method");
  // The grid only sets view0_'s cell, which no pass reads: each tile's
  // view_ takes its own (load_tile).
  view0_ = view_uniforms(opt.camera, GridParams{}, W_, H_);
  view_ = view0_;
  slope_ = opt.draw_lines && tiles.slope;
  unlit_ = opt.decal_light && tiles.unlit;  // each tile uploads its flags (load_tile)
  min_widths_ = opt.draw_lines && tiles.min_widths;
  setup();
}

// What every package of the frame shares: terrain mesh, targets, programs.
void GlRenderer::setup() {
  mesh_ = upload_terrain_mesh(gl_, terrain_, view0_.anchor, slope_);
  glCreateVertexArrays(1, &empty_vao_);
  gl_.arrays.push_back(empty_vao_);
  t_ = make_targets(gl_, W_, H_, opt_.method == Method::volume, slope_, unlit_);
  p_ = static_programs(gl_, opt_, slope_, unlit_, min_widths_);
  glViewport(0, 0, GLsizei(W_), GLsizei(H_));
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
}

std::vector<decal::gl::BlobBytes> gl_blobs(const DecalSource& source) {
  std::vector<decal::gl::BlobBytes> blobs;
  for (const auto& b : source.blobs)
    blobs.push_back({b.id, b.count, {static_cast<const std::byte*>(b.data), size_t(b.bytes)}});
  return blobs;
}

decal::gl::Grid gl_grid(const DecalSource& source) {
  const GridParams& gp = source.view.grid;
  return {gp.origin_x, gp.origin_y, gp.cell_w, gp.cell_h, gp.nx, gp.ny};
}

std::optional<std::array<int64_t, 2>> tile_shift(const TilePlace& t) {
  const double q = decal::kQuantumMetres;
  const std::array<int64_t, 2> k{std::llround(t.dx / q), std::llround(t.dy / q)};
  if (!(std::fabs(t.dx - double(k[0]) * q) <= 1e-6 && std::fabs(t.dy - double(k[1]) * q) <= 1e-6))
    return std::nullopt;
  return k;
}

// The tile's frame is the index frame moved by (dx, dy), a whole number of
// quanta k: the anchor there is view0_'s anchor minus k, exactly, and every
// anchor-relative float the GPU holds (eye, matrices, terrain depth, clip)
// stays view0_'s. Only integer uniforms (u_anchor_q, u_anchor_cell) and the
// anchor's offset in its cell change, computed in double on the CPU; for a
// tile far from the eye, the anchor moves into the tile (below).
void GlRenderer::load_tile(size_t k) {
  const TilePlace& t = tiles_->places[k];
  timer_.tile = int(k);
  gpu_.reset();
  tile_ = OpenedTile{};  // the previous tile's blobs go before the next one's come
  source_ = nullptr;
  const std::optional<std::array<int64_t, 2>> shift = tile_shift(t);
  if (!shift) fail<render_error>(kRenderStage, "tile origin not on the quantum grid");
  view_ = view0_;
  view_.ax -= (*shift)[0];
  view_.ay -= (*shift)[1];
  const double q = decal::kQuantumMetres;
  Extent clip{t.square.xmin - t.dx, t.square.ymin - t.dy, t.square.xmax - t.dx,
              t.square.ymax - t.dy};
  // The shaders subtract the anchor from the tile's int32 quanta: every
  // vertex of the tile (its square, grown by 1% for the margin) must lie
  // within 2^31 quanta of the anchor on each axis. Where the eye does not
  // (a tile far from it in a view of a continent or the world, or any spot
  // of a tile over 2,147 km wide), the anchor moves to the nearest point
  // that does, and the matrices and the eye follow it, recomputed in double
  // from the camera. Their float32 rounding at a distance D from the eye is
  // about D * 6e-8, far below a pixel there.
  {
    constexpr double kReach = double((int64_t(1) << 31) - 1);
    const double pad = 0.01 * (t.square.xmax - t.square.xmin);
    const auto reach = [&](double lo, double hi, int64_t at) {
      const double l = (hi + pad) / q - kReach, h = (lo - pad) / q + kReach;
      return l > h ? at : std::clamp<int64_t>(at, int64_t(std::ceil(l)), int64_t(std::floor(h)));
    };
    const int64_t x = reach(t.square.xmin - t.dx, t.square.xmax - t.dx, view_.ax);
    const int64_t y = reach(t.square.ymin - t.dy, t.square.ymax - t.dy, view_.ay);
    if (x != view_.ax || y != view_.ay) {
      set_anchor(view_, opt_.camera, x + (*shift)[0], y + (*shift)[1], W_, H_);
      view_.ax = x;
      view_.ay = y;
    }
  }
  view_.anchor = {double(view_.ax) * q, double(view_.ay) * q, 0.0};
  if (opt_.clip)
    clip = {
        std::max(clip.xmin, opt_.clip->xmin - t.dx), std::max(clip.ymin, opt_.clip->ymin - t.dy),
        std::min(clip.xmax, opt_.clip->xmax - t.dx), std::min(clip.ymax, opt_.clip->ymax - t.dy)};
  set_clip(view_, clip);
  scissor_ = tile_scissor();
  if (scissor_[2] == 0 || scissor_[3] == 0) return;  // not in the image: not even opened
  timer_.begin("tile open (read, decode)");
  tile_ = tiles_->open(k);
  timer_.end();
  source_ = &tile_.tile.source;
  dash_for_ = nullptr;  // a new tile may sit where the last one was
  const std::vector<decal::gl::BlobBytes> blobs = gl_blobs(*source_);
  if (!source_->validated) check(decal::gl::validate_blobs(blobs, gl_grid(*source_)));
  set_grid(view_, source_->view.grid);
  runs_ = draw_runs(source_->view);
  if (slope_) upload_slope_layers(*source_);
  if (unlit_) upload_unlit_layers(*source_);
  if (min_widths_) upload_min_widths(*source_);
  timer_.begin("tile upload (blobs)");
  check(decal::gl::GpuPackage::upload(blobs, gl_grid(*source_), gpu_, true));
  timer_.end();
}

// The pixels a tile can draw: the box of the image points of its square's
// corners at the terrain's lowest and highest height (the projection of a
// box in front of the camera lies in the hull of its corners' images),
// grown by 2 pixels; the whole image when a corner is not in front. Every
// pass of the tile is scissored to it, so hundreds of tiles cost about one
// image's worth of fragments rather than one image each.
std::array<GLint, 4> GlRenderer::tile_scissor() const {
  const std::array<GLint, 4> all{0, 0, GLint(W_), GLint(H_)};
  const std::array<float, 16>& m = view_.view_proj;  // relative to view_'s anchor, as the clip
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (int k = 0; k < 8; ++k) {
    const double p[3] = {view_.clip[(k & 1) ? 2 : 0], view_.clip[(k & 2) ? 3 : 1],
                         (k & 4) ? terrain_.zmax : terrain_.zmin};
    double c[4];
    for (int r = 0; r < 4; ++r) c[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
    if (!(c[3] > 1e-6) || !std::isfinite(c[0] / c[3]) || !std::isfinite(c[1] / c[3])) return all;
    const double px = (0.5 * c[0] / c[3] + 0.5) * W_, py = (0.5 * c[1] / c[3] + 0.5) * H_;
    x0 = std::min(x0, px), x1 = std::max(x1, px), y0 = std::min(y0, py), y1 = std::max(y1, py);
  }
  const auto clamp = [](double v, uint32_t hi) { return GLint(std::clamp(v, 0.0, double(hi))); };
  const GLint ix0 = clamp(std::floor(x0) - 2, W_), iy0 = clamp(std::floor(y0) - 2, H_);
  const GLint ix1 = clamp(std::ceil(x1) + 2, W_), iy1 = clamp(std::ceil(y1) + 2, H_);
  return {ix0, iy0, std::max(ix1 - ix0, 0), std::max(iy1 - iy0, 0)};
}

void GlRenderer::frame(Image& img) {
  timer_.passes.clear();
  timer_.tile = -1;
  if (opt_.method == Method::texture && !m_.texture) texture_raster();
  terrain_pass();
  const GLuint f_static = opt_.method == Method::decal ? begin_static() : 0;
  const float clear0[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(t_.f_dyn, GL_COLOR, 0, clear0);
  img.dyn_kept = img.dyn_segments = img.dyn_nodes = 0;
  img.lod_lines = img.lod_selected = img.lod_drawn = img.lod_full = 0;
  img.lod_selection.clear();
  for (size_t k = 0; k < (tiles_ ? tiles_->places.size() : 1); ++k) {
    if (tiles_) {
      load_tile(k);
      if (!gpu_) continue;
      glEnable(GL_SCISSOR_TEST);
      glScissor(scissor_[0], scissor_[1], scissor_[2], scissor_[3]);
    }
    if (opt_.method == Method::decal)
      static_passes(f_static);
    else if (opt_.method == Method::volume)
      volume_passes();
    {
      GlObjects work;  // the dynamic pass's buffers, freed with the tile
      dynamic_pass(img, work);
    }
    if (tiles_) {
      glDisable(GL_SCISSOR_TEST);
      gpu_.reset();
    }
  }
  if (tiles_) {
    tile_ = OpenedTile{};
    source_ = nullptr;
  }
  timer_.tile = -1;
  if (opt_.method == Method::decal) end_static(f_static);
  composite_pass();
  method_stats(img);
}

// --- passes

// In the frame's camera (view0_), whatever package is current.
void GlRenderer::terrain_pass() {
  // The texture method samples its texture here into a second target, the
  // decal layer (Taibo et al. §4).
  const bool sample_texture = opt_.method == Method::texture;
  const GLuint fb = sample_texture ? m_.f_terrain_decal : t_.f_terrain;
  timer_.begin(sample_texture ? "terrain + decal texture" : "terrain");
  glBindFramebuffer(GL_FRAMEBUFFER, fb);
  const float sky[4] = {0.80f, 0.86f, 0.93f, 1.0f};
  glClearNamedFramebufferfv(fb, GL_COLOR, 0, sky);
  if (sample_texture) {
    const float clear0[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(fb, GL_COLOR, 1, clear0);
  }
  const float zero = 0.0f;
  glClearNamedFramebufferfv(fb, GL_DEPTH, 0, &zero);
  if (slope_) {
    const float level[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(fb, GL_COLOR, 1, level);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kSsboTerrainGradient, mesh_.gradients);
  }
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_GREATER);
  const GLuint p = sample_texture ? m_.terrain_program : p_.terrain;
  glUseProgram(p);
  if (sample_texture) {
    glBindTextureUnit(decal::gl::kUnitDecalTexture, m_.texture);
    glUniform4fv(glGetUniformLocation(p, "u_texture_box"), 1, m_.texture_box.data());
    glUniform4fv(glGetUniformLocation(p, "u_clip"), 1, view0_.clip.data());
  }
  glUniformMatrix4fv(glGetUniformLocation(p, "u_view_proj"), 1, GL_FALSE, view0_.view_proj.data());
  const Vec3 light = normalize(kLightTowards);
  glUniform3f(glGetUniformLocation(p, "u_light_dir"), float(light[0]), float(light[1]),
              float(light[2]));
  glUniform3f(glGetUniformLocation(p, "u_albedo"), float(opt_.albedo[0]), float(opt_.albedo[1]),
              float(opt_.albedo[2]));
  // Flat terrain (all heights 0) is land, not sea.
  glUniform1f(glGetUniformLocation(p, "u_sea_level"),
              terrain_.zmax > terrain_.zmin ? 0.0f : -1e30f);
  glBindVertexArray(mesh_.vao);
  glDrawElements(GL_TRIANGLES, mesh_.index_count, GL_UNSIGNED_INT, nullptr);
  glDisable(GL_DEPTH_TEST);
  timer_.end();
}

// MSAA (option): the static passes shade every sample (per-sample shading,
// forced by gl_SamplePosition) into a 4x target, resolved into the decal
// layer afterwards (thesis §4.5). Otherwise they draw into the decal layer.
GLuint GlRenderer::static_target() {
  if (opt_.aa != AntiAliasing::msaa4) return t_.f_decal;
  GLuint t_ms = 0;
  glCreateTextures(GL_TEXTURE_2D_MULTISAMPLE, 1, &t_ms);
  gl_.textures.push_back(t_ms);
  glTextureStorage2DMultisample(t_ms, 4, GL_RGBA32F, GLsizei(W_), GLsizei(H_), GL_TRUE);
  const GLuint fb = gl_.framebuffer(t_ms, 0);
  if (unlit_) {
    GLuint u_ms = 0;
    glCreateTextures(GL_TEXTURE_2D_MULTISAMPLE, 1, &u_ms);
    gl_.textures.push_back(u_ms);
    glTextureStorage2DMultisample(u_ms, 4, GL_RGBA32F, GLsizei(W_), GLsizei(H_), GL_TRUE);
    attach_second(fb, u_ms, "msaa unlit share");
  }
  return fb;
}

void GlRenderer::set_static_uniforms(GLuint p) const {
  const double q = decal::kQuantumMetres;
  const GridParams& gp = view_.grid;
  const int64_t cxi = view_.cell_x, cyi = view_.cell_y;
  const Vec3& eye_rel = view_.eye_rel;
  glUseProgram(p);
  glUniformMatrix4fv(glGetUniformLocation(p, "u_inv_view_proj"), 1, GL_FALSE,
                     view_.inv_view_proj.data());
  glUniform2f(glGetUniformLocation(p, "u_viewport"), float(W_), float(H_));
  glUniform2i(glGetUniformLocation(p, "u_anchor_q"), GLint(view_.ax), GLint(view_.ay));
  glUniform2i(glGetUniformLocation(p, "u_anchor_cell"), GLint(cxi), GLint(cyi));
  glUniform2f(glGetUniformLocation(p, "u_anchor_in_cell"),
              float(double(view_.rx - cxi * gp.cell_w) * q),
              float(double(view_.ry - cyi * gp.cell_h) * q));
  glUniform2f(glGetUniformLocation(p, "u_cell_size"), float(double(gp.cell_w) * q),
              float(double(gp.cell_h) * q));
  glUniform2i(glGetUniformLocation(p, "u_grid_n"), GLint(gp.nx), GLint(gp.ny));
  // The u16 BVH boxes of v1.3 are relative to their cell (decal/layout.hpp).
  glUniform2i(glGetUniformLocation(p, "u_grid_origin_q"), GLint(gp.origin_x), GLint(gp.origin_y));
  glUniform2i(glGetUniformLocation(p, "u_cell_q"), GLint(gp.cell_w), GLint(gp.cell_h));
  glUniform1i(glGetUniformLocation(p, "u_box16_shift"),
              GLint(decal::layout::box16_shift(gp.cell_w, gp.cell_h)));
  glUniform4fv(glGetUniformLocation(p, "u_clip"), 1, view_.clip.data());
  glUniform3f(glGetUniformLocation(p, "u_eye_rel"), float(eye_rel[0]), float(eye_rel[1]),
              float(eye_rel[2]));
  glUniform1f(glGetUniformLocation(p, "u_mpp_ortho"), float(view_.mpp_ortho));
  glUniform1f(glGetUniformLocation(p, "u_mpp_per_metre"), float(view_.mpp_per_metre));
  if (min_widths_ && p == p_.lines) {
    glUniform1f(glGetUniformLocation(p, "u_min_width_pixel_m"),
                float(source_->min_width_pixel_m > 0 ? source_->min_width_pixel_m : 0.0));
    glUniform1f(glGetUniformLocation(p, "u_min_width_reach"), float(min_width_reach(*source_)));
  }
}

void GlRenderer::bind_package() const {
  gpu_->bind(opt_.binding == Binding::texture ? decal::gl::BindingMode::texture
                                              : decal::gl::BindingMode::ssbo);
  glBindTextureUnit(decal::gl::kUnitDepth, t_.depth);
  if (slope_) {
    glBindTextureUnit(decal::gl::kUnitTerrainGradient, t_.gradient);
    glBindTextureUnit(decal::gl::kUnitSlopeLayers, slope_layers_);
  }
  if (min_widths_) glBindTextureUnit(decal::gl::kUnitMinWidths, min_widths_tex_);
  if (unlit_) glBindTextureUnit(decal::gl::kUnitUnlitLayers, unlit_layers_);
}

namespace {

// One flag a layer-table index as an R8UI buffer texture (none: one 0).
GLuint layer_flags_texture(GlObjects& gl, std::vector<uint8_t> flags) {
  if (flags.empty()) flags.push_back(0);
  GLuint buf = 0, tex = 0;
  glCreateBuffers(1, &buf);
  gl.buffers.push_back(buf);
  glNamedBufferStorage(buf, GLsizeiptr(flags.size()), flags.data(), 0);
  glCreateTextures(GL_TEXTURE_BUFFER, 1, &tex);
  gl.textures.push_back(tex);
  glTextureBuffer(tex, GL_R8UI, buf);
  return tex;
}

}  // namespace

void GlRenderer::upload_slope_layers(const DecalSource& source) {
  slope_layers_ = layer_flags_texture(gl_, slope_layers(source, opt_.slope_widths));
}

void GlRenderer::upload_unlit_layers(const DecalSource& source) {
  unlit_layers_ = layer_flags_texture(gl_, source.unlit_layers);
}

void GlRenderer::upload_min_widths(const DecalSource& source) {
  std::vector<float> n = source.min_width_px;
  if (n.empty() || !(source.min_width_pixel_m > 0)) n.assign(1, 0.0f);  // this package: none
  GLuint buf = 0;
  glCreateBuffers(1, &buf);
  gl_.buffers.push_back(buf);
  glNamedBufferStorage(buf, GLsizeiptr(n.size() * sizeof(float)), n.data(), 0);
  glCreateTextures(GL_TEXTURE_BUFFER, 1, &min_widths_tex_);
  gl_.textures.push_back(min_widths_tex_);
  glTextureBuffer(min_widths_tex_, GL_R32F, buf);
}

void GlRenderer::bind_dashes() {
  if (!dash_gl_ || dash_for_ != source_) {
    dash_gl_ = std::make_unique<GlObjects>();  // frees the previous package's
    dash_for_ = source_;
    const LineDashes* d = source_->view.dashes.get();
    const std::vector<uint32_t> words = d ? dash_gpu_words(d->table) : std::vector<uint32_t>{0u};
    std::vector<float> dist(d ? d->vertex_distance.size() : 0);
    for (size_t k = 0; k < dist.size(); ++k) dist[k] = float(d->vertex_distance[k]);
    auto upload = [&](const void* data, size_t bytes) {
      GLuint b = 0;
      glCreateBuffers(1, &b);
      dash_gl_->buffers.push_back(b);
      std::vector<std::byte> padded(std::max<size_t>(bytes, 16));
      if (bytes) std::memcpy(padded.data(), data, bytes);
      glNamedBufferStorage(b, GLsizeiptr(padded.size()), padded.data(), 0);
    };
    upload(words.data(), words.size() * 4);
    upload(dist.data(), dist.size() * 4);
  }
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kBindingDashTable, dash_gl_->buffers[0]);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kBindingDashVertex, dash_gl_->buffers[1]);
}

GLuint GlRenderer::begin_static() {
  const GLuint f_static = static_target();
  const float clear0[4] = {0, 0, 0, 0};
  for (GLint b = 0; b < (unlit_ ? 2 : 1); ++b) {
    glClearNamedFramebufferfv(f_static, GL_COLOR, b, clear0);
    glClearNamedFramebufferfv(t_.f_decal, GL_COLOR, b, clear0);
  }
  return f_static;
}

// Static decal passes over the back-projected depth.
void GlRenderer::static_passes(GLuint f_static) {
  bind_package();
  bind_dashes();
  glBindFramebuffer(GL_FRAMEBUFFER, f_static);
  glBindVertexArray(empty_vao_);
  if (f_static != t_.f_decal) {
    glEnable(GL_SAMPLE_SHADING);
    glMinSampleShading(1.0f);
  }
  // A kind with no per-cell ranges is absent: its pass would index the
  // 16-byte placeholder buffer, so it is skipped.
  const uint64_t cells = uint64_t(view_.grid.nx) * view_.grid.ny;
  // (The loader holds the v1.3 layout: one cell_*_first per cell plus one.)
  const bool have_polygons =
      opt_.draw_polygons && gpu_->count(decal::BlobId::cell_poly_first) == cells + 1;
  const bool have_lines =
      opt_.draw_lines && gpu_->count(decal::BlobId::cell_line_first) == cells + 1;
  // The drawing order as runs of one kind, top first (formats/SPEC.md
  // "Drawing order"), each pass blended under the earlier ones: front to
  // back, as the evaluator composites.
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);
  for (const DrawRun& run : runs_) {
    const bool lines = run.kind == DrawRun::Kind::lines;
    if (lines ? !have_lines : !have_polygons) continue;
    timer_.begin(std::string(lines ? "static lines" : "static polygons") + " [" +
                 std::to_string(run.lo) + ", " + std::to_string(run.hi) + ")");
    const GLuint p = lines ? p_.lines : p_.polygons;
    set_static_uniforms(p);
    glUniform1ui(glGetUniformLocation(p, "u_order_lo"), run.lo);
    glUniform1ui(glGetUniformLocation(p, "u_order_hi"), run.hi);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    timer_.end();
  }
  glDisable(GL_BLEND);
  glDisable(GL_SAMPLE_SHADING);
}

void GlRenderer::end_static(GLuint f_static) {
  if (f_static != t_.f_decal) {
    timer_.begin("msaa resolve");
    // Each attachment on its own (a blit reads one buffer).
    for (GLenum a : {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1}) {
      if (a == GL_COLOR_ATTACHMENT1 && !unlit_) break;
      glNamedFramebufferReadBuffer(f_static, a);
      glNamedFramebufferDrawBuffer(t_.f_decal, a);
      glBlitNamedFramebuffer(f_static, t_.f_decal, 0, 0, GLint(W_), GLint(H_), 0, 0, GLint(W_),
                             GLint(H_), GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    if (unlit_) {
      const GLenum both[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
      glNamedFramebufferDrawBuffers(t_.f_decal, 2, both);
    }
    timer_.end();
  }
}

void GlRenderer::composite_pass() {
  timer_.begin("composite");
  glBindFramebuffer(GL_FRAMEBUFFER, t_.f_final);
  glUseProgram(p_.composite);
  glUniform1i(glGetUniformLocation(p_.composite, "u_decal_light"), opt_.decal_light ? 1 : 0);
  glBindTextureUnit(decal::gl::kUnitTerrainColour, t_.color);
  glBindTextureUnit(decal::gl::kUnitDecalLayer, t_.decal);
  if (unlit_) glBindTextureUnit(decal::gl::kUnitUnlitLayer, t_.unlit);
  glBindTextureUnit(decal::gl::kUnitDynamicLayer, t_.dyn);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  timer_.end();
}

}  // namespace prep::render::detail
