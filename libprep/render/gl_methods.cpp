// The two older methods `decalprep render --method` draws beside the decal
// method (thesis §5.2.2): the volume method (Schneider & Klein §4) and the
// texture method (Taibo et al. §4). Both take their triangles from
// method_geometry.cpp; the terrain, dynamic-line and composite passes are the
// decal method's.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "detail/gl_render.hpp"
#include "detail/math.hpp"
#include "detail/method_geometry.hpp"
#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep::render::detail {

namespace {

// The terrain's height range under a box: the mesh vertices of the cells
// the box meets (the mesh is linear between them), or the whole mesh's
// range where the box leaves it. Schneider & Klein §4.1 bound the caps with
// their terrain quad-tree's boxes; this is the same conservative bound.
struct HeightRange {
  const Heightfield& h;
  std::pair<double, double> operator()(const Extent& b) const {
    const double fi0 = (b.xmin - h.x0) / h.dx, fi1 = (b.xmax - h.x0) / h.dx;
    const double fj0 = (b.ymin - h.y0) / h.dy, fj1 = (b.ymax - h.y0) / h.dy;
    const double ilo = std::floor(std::min(fi0, fi1)), ihi = std::ceil(std::max(fi0, fi1));
    const double jlo = std::floor(std::min(fj0, fj1)), jhi = std::ceil(std::max(fj0, fj1));
    if (!(ilo >= 0 && jlo >= 0 && ihi <= double(h.nx - 1) && jhi <= double(h.ny - 1)) ||
        h.z.empty())
      return {h.zmin, h.zmax};
    double lo = INFINITY, hi = -INFINITY;
    for (uint32_t j = uint32_t(jlo); j <= uint32_t(jhi); ++j)
      for (uint32_t i = uint32_t(ilo); i <= uint32_t(ihi); ++i) {
        const double z = h.z[i + size_t(h.nx) * j];
        lo = std::min(lo, z);
        hi = std::max(hi, z);
      }
    return {lo, hi};
  }
};

std::array<float, 16> method_floats(const Mat4& m) {
  std::array<float, 16> f{};
  for (int k = 0; k < 16; ++k) f[k] = static_cast<float>(m[k]);
  return f;
}

// One vertex buffer of positions. GL implementations cap one buffer (Mesa's
// llvmpipe at 2 GiB; past it the upload fails or the draw crashes), so a
// larger one is refused with what it would have held.
GLuint upload_positions(GlObjects& gl, const std::vector<float>& xyz, const char* method) {
  const uint64_t bytes = uint64_t(std::max<size_t>(xyz.size(), 3)) * sizeof(float);
  constexpr uint64_t kMaxBuffer = (uint64_t(1) << 31) - 1;
  auto too_big = [&] {
    char b[400];
    std::snprintf(b, sizeof b,
                  "--method %s: %llu triangles (%.2f GB of vertices) do not fit one GL vertex "
                  "buffer (at most %.2f GB here); draw fewer layers (--only) or use --method "
                  "decal",
                  method, static_cast<unsigned long long>(xyz.size() / 9), double(bytes) / 1e9,
                  double(kMaxBuffer) / 1e9);
    fail<resource_error>(kRenderStage, b);
  };
  if (bytes > kMaxBuffer) too_big();
  GLuint vbo = 0, vao = 0;
  glCreateBuffers(1, &vbo);
  gl.buffers.push_back(vbo);
  while (glGetError() != GL_NO_ERROR) {
  }
  glNamedBufferStorage(vbo, GLsizeiptr(bytes), xyz.empty() ? nullptr : xyz.data(), 0);
  if (glGetError() == GL_OUT_OF_MEMORY) too_big();
  glCreateVertexArrays(1, &vao);
  gl.arrays.push_back(vao);
  glVertexArrayVertexBuffer(vao, 0, vbo, 0, 3 * sizeof(float));
  glEnableVertexArrayAttrib(vao, 0);
  glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
  glVertexArrayAttribBinding(vao, 0, 0);
  return vao;
}

}  // namespace

namespace {

// Whether feature f's layer is drawn unlit (flags: DecalSource::unlit_layers
// under lit decals, else empty).
bool feature_unlit(const MethodFeature& f, std::span<const uint8_t> flags) {
  return !flags.empty() && flags[std::min<size_t>(f.layer, flags.size() - 1)] != 0;
}

// The end of the group that starts at feature k: a run of consecutive
// opaque features of one colour (and one lighting); translucent features
// of one colour share a group while their boxes are disjoint (then no texel
// is covered twice).
size_t group_end(const MethodGeometry& g, size_t k, std::span<const uint8_t> unlit) {
  const MethodFeature& f0 = g.features[k];
  const bool flat = feature_unlit(f0, unlit);
  const bool opaque = (f0.rgba >> 24) == 255;
  std::vector<Extent> boxes{f0.box};
  auto disjoint = [&](const Extent& b) {
    if (boxes.size() >= 64) return false;
    for (const Extent& o : boxes)
      if (b.xmin <= o.xmax && o.xmin <= b.xmax && b.ymin <= o.ymax && o.ymin <= b.ymax)
        return false;
    boxes.push_back(b);
    return true;
  };
  size_t end = k + 1;
  while (end < g.features.size() && g.features[end].rgba == f0.rgba &&
         feature_unlit(g.features[end], unlit) == flat && (opaque || disjoint(g.features[end].box)))
    ++end;
  return end;
}

// The prisms of features [k, end) appended to `xyz` (anchor-relative):
// caps over their triangles, walls over their boundary edges, faces
// outwards, from below to above the terrain under each; `box`, `zlo` and
// `zhi` grow to hold them.
void append_prisms(const MethodGeometry& g, size_t k, size_t end, const HeightRange& range,
                   const Vec3& anchor, std::vector<float>& xyz, Extent& box, double& zlo,
                   double& zhi) {
  auto put = [&](const P2d& p, double z) {
    xyz.push_back(float(p[0] - anchor[0]));
    xyz.push_back(float(p[1] - anchor[1]));
    xyz.push_back(float(z));
  };
  for (size_t i = k; i < end; ++i) {
    const MethodFeature& f = g.features[i];
    auto [lo, hi] = range(f.box);
    // Margins keep the caps off the terrain (depth ties).
    const double margin = 0.5 + 1e-3 * (hi - lo);
    lo -= margin;
    hi += margin;
    for (uint32_t t = f.first_triangle; t < f.first_triangle + f.triangles; ++t) {
      const P2d* v = &g.triangles[size_t(t) * 3];
      for (int c : {0, 1, 2}) put(v[c], hi);  // top cap, facing up
      for (int c : {0, 2, 1}) put(v[c], lo);  // bottom cap, facing down
    }
    for (uint32_t e = f.first_edge; e < f.first_edge + f.edges; ++e) {
      const auto& [a, b] = g.edges[e];  // interior on the left: the wall faces right
      put(a, lo);
      put(b, lo);
      put(b, hi);
      put(a, lo);
      put(b, hi);
      put(a, hi);
    }
    box = {std::min(box.xmin, f.box.xmin), std::min(box.ymin, f.box.ymin),
           std::max(box.xmax, f.box.xmax), std::max(box.ymax, f.box.ymax)};
    zlo = std::min(zlo, lo);
    zhi = std::max(zhi, hi);
  }
}

// z-pass unless a prism may reach the near plane (Schneider & Klein §4.2.1
// decide per volume from its bounding box): a box corner closer than the
// near plane (perspective) or behind the eye plane (orthographic) means
// z-fail. Scissor: the box's projection, on a W x H image.
void place_group(MethodState::Group& grp, const Extent& box, double zlo, double zhi, const Mat4& vp,
                 const Vec3& anchor, const Camera& camera, uint32_t W, uint32_t H) {
  const bool perspective = camera.projection == Projection::perspective;
  double sx0 = INFINITY, sy0 = INFINITY, sx1 = -INFINITY, sy1 = -INFINITY;
  bool near_hit = false;
  for (int c = 0; c < 8; ++c) {
    const double x = (c & 1 ? box.xmax : box.xmin) - anchor[0];
    const double y = (c & 2 ? box.ymax : box.ymin) - anchor[1];
    const double z = c & 4 ? zhi : zlo;
    double clip[4];
    for (int r = 0; r < 4; ++r) clip[r] = vp[r] * x + vp[4 + r] * y + vp[8 + r] * z + vp[12 + r];
    const double w = clip[3];
    if (perspective ? !(w > camera.near * 1.001) : !(clip[2] <= w)) {
      near_hit = true;
      continue;
    }
    sx0 = std::min(sx0, clip[0] / w), sx1 = std::max(sx1, clip[0] / w);
    sy0 = std::min(sy0, clip[1] / w), sy1 = std::max(sy1, clip[1] / w);
  }
  grp.zfail = near_hit;
  if (near_hit) {
    grp.scissor = {0, 0, GLint(W), GLint(H)};
    return;
  }
  const double px0 = std::floor((std::max(sx0, -1.0) + 1) * 0.5 * W) - 1;
  const double px1 = std::ceil((std::min(sx1, 1.0) + 1) * 0.5 * W) + 1;
  const double py0 = std::floor((std::max(sy0, -1.0) + 1) * 0.5 * H) - 1;
  const double py1 = std::ceil((std::min(sy1, 1.0) + 1) * 0.5 * H) + 1;
  const GLint x0 = GLint(std::clamp(px0, 0.0, double(W)));
  const GLint y0 = GLint(std::clamp(py0, 0.0, double(H)));
  const GLint x1 = GLint(std::clamp(px1, 0.0, double(W)));
  const GLint y1 = GLint(std::clamp(py1, 0.0, double(H)));
  grp.scissor = {x0, y0, std::max(0, x1 - x0), std::max(0, y1 - y0)};
}

}  // namespace

namespace {

// The texels of the texture method: --texture-resolution, else the extent
// (clipped) over kTextureAutoTexels texels a side, at least 1 m.
double texel_metres(const DecalSource& source, const RenderOptions& opt) {
  Extent e = source.extent;
  if (opt.clip)
    e = {std::max(e.xmin, opt.clip->xmin), std::max(e.ymin, opt.clip->ymin),
         std::min(e.xmax, opt.clip->xmax), std::min(e.ymax, opt.clip->ymax)};
  if (!(e.xmax > e.xmin && e.ymax > e.ymin)) e = {0, 0, 1, 1};
  if (opt.texture_resolution > 0) return opt.texture_resolution;
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  const double span = std::max(e.xmax - e.xmin, e.ymax - e.ymin);
  return std::max(1.0, span / std::min<double>(kTextureAutoTexels, max_size));
}

// Minimum widths in the methods drawn from one geometry (formats/SPEC.md
// "Minimum widths"): `view` with the lines of min_width_px layers widened
// for one pixel size, their half widths and corner vectors in `props` and
// `corners` (prep::min_width_scale); `view` itself when none is.
StaticView widened_view(const DecalSource& source, double pixel_m,
                        std::vector<decal::LineProps>& props,
                        std::vector<decal::LineCorner>& corners) {
  StaticView v = source.view;
  if (source.min_width_px.empty() || !(source.min_width_pixel_m > 0)) return v;
  EvalPixel px;
  px.pixel_m = pixel_m;
  px.min_width_px = source.min_width_px;
  px.min_width_pixel_m = source.min_width_pixel_m;
  // Each line's scale once, for its props and its vertices' corners.
  std::vector<double> scale(v.line_props.size());
  for (uint32_t l = 0; l < scale.size(); ++l) scale[l] = min_width_scale(source.view, l, px);
  props.assign(v.line_props.begin(), v.line_props.end());
  corners.assign(v.line_corners.begin(), v.line_corners.end());
  for (size_t i = 0; i < v.line_vertex_line.size() && i < corners.size(); ++i) {
    const double k = scale.at(v.line_vertex_line[i]);
    for (float* c : {corners[i].miter, corners[i].bevel_in, corners[i].bevel_out}) {
      c[0] = float(k * double(c[0]));
      c[1] = float(k * double(c[1]));
    }
  }
  for (uint32_t l = 0; l < props.size(); ++l)
    props[l].half_width = float(double(props[l].half_width) * scale[l]);
  v.line_props = props;
  v.line_corners = corners;
  return v;
}

}  // namespace

void GlRenderer::method_setup() {
  // One pixel size for the whole geometry: the texture's texel, or the
  // volume view's pixel at its target (exact top-down).
  const Camera& cam = opt_.camera;
  const double pixel_m = opt_.method == Method::texture ? texel_metres(*source_, opt_)
                         : view_.mpp_ortho > 0
                             ? view_.mpp_ortho
                             : std::hypot(cam.target[0] - cam.eye[0], cam.target[1] - cam.eye[1],
                                          cam.target[2] - cam.eye[2]) *
                                   view_.mpp_per_metre;
  std::vector<decal::LineProps> props;
  std::vector<decal::LineCorner> corners;
  const StaticView view = widened_view(*source_, pixel_m, props, corners);
  const MethodGeometry g = method_geometry(view, opt_.draw_polygons, opt_.draw_lines, opt_.clip);
  if (opt_.method == Method::volume)
    volume_setup(g);
  else
    texture_setup(g);
}

// Schneider & Klein §4.1: every feature extruded to a closed prism from
// below to above the terrain under it (caps over its triangles, walls over
// its boundary edges, faces outwards). Groups (§4.2): a run of consecutive
// opaque features of one colour shares one stencil and one cover pass
// (their union composites as the features one by one would); translucent
// ones share one only while their boxes are disjoint, so overlapping
// features blend as often as in the decal method.
void GlRenderer::volume_setup(const MethodGeometry& g) {
  const Vec3& anchor = view_.anchor;
  const HeightRange range{terrain_};
  const Mat4 vp = mat_mul(projection_matrix(opt_.camera, double(W_) / H_),
                          view_matrix(opt_.camera, view_.eye_rel));
  std::vector<float> xyz;
  const std::span<const uint8_t> unlit =
      unlit_ ? std::span<const uint8_t>(source_->unlit_layers) : std::span<const uint8_t>{};
  for (size_t k = 0; k < g.features.size();) {
    const size_t end = group_end(g, k, unlit);
    MethodState::Group grp;
    grp.first = GLint(xyz.size() / 3);
    grp.rgba = g.features[k].rgba;
    grp.unlit = feature_unlit(g.features[k], unlit);
    Extent box{INFINITY, INFINITY, -INFINITY, -INFINITY};
    double zlo = INFINITY, zhi = -INFINITY;
    append_prisms(g, k, end, range, anchor, xyz, box, zlo, zhi);
    grp.count = GLsizei(xyz.size() / 3) - grp.first;
    place_group(grp, box, zlo, zhi, vp, anchor, opt_.camera, W_, H_);
    if (grp.count > 0 && grp.scissor[2] > 0 && grp.scissor[3] > 0) m_.groups.push_back(grp);
    m_.prism_triangles += uint64_t(grp.count) / 3;
    k = end;
  }
  m_.prism_vao = upload_positions(gl_, xyz, "volume");
  m_.f_volume = gl_.framebuffer(t_.decal, t_.depth);
  if (unlit_) attach_second(m_.f_volume, t_.unlit, "volume unlit share");
  m_.volume_program =
      gl_.program({{"method_prism.vert.glsl"}, {}, {"method_colour.frag.glsl"}, {}, ""});
  m_.cover_program = gl_.program({{"fullscreen.vert.glsl"},
                                  {},
                                  {"method_colour.frag.glsl"},
                                  {},
                                  unlit_ ? "#define DECAL_UNLIT_LAYERS 1\n" : ""});
}

// Texture method (Taibo et al. §4): the package extent (a tile's square
// where clipped) at `texture_resolution` metres per texel.
void GlRenderer::texture_setup(const MethodGeometry& g) {
  const Vec3& anchor = view_.anchor;
  Extent e = source_->extent;
  if (opt_.clip)
    e = {std::max(e.xmin, opt_.clip->xmin), std::max(e.ymin, opt_.clip->ymin),
         std::min(e.xmax, opt_.clip->xmax), std::min(e.ymax, opt_.clip->ymax)};
  if (!(e.xmax > e.xmin && e.ymax > e.ymin)) e = {0, 0, 1, 1};
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  const double span = std::max(e.xmax - e.xmin, e.ymax - e.ymin);
  const double res = texel_metres(*source_, opt_);
  if (opt_.texture_resolution > 0 && span / res > max_size) {
    fail<usage_error>(kRenderStage, "--texture-resolution " + std::to_string(res) +
                                        ": the extent's " + std::to_string(span) + " m need " +
                                        std::to_string(span / res) +
                                        " texels a side, more than GL_MAX_TEXTURE_SIZE " +
                                        std::to_string(max_size) + "; give at least " +
                                        std::to_string(span / max_size) + " m");
  }
  m_.texture_resolution = res;
  m_.texture_w = std::max<uint32_t>(1, uint32_t(std::ceil((e.xmax - e.xmin) / res)));
  m_.texture_h = std::max<uint32_t>(1, uint32_t(std::ceil((e.ymax - e.ymin) / res)));
  const double tw = m_.texture_w * res, th = m_.texture_h * res;
  m_.texture_box = {float(e.xmin - anchor[0]), float(e.ymin - anchor[1]), float(1.0 / tw),
                    float(1.0 / th)};
  // Triangles relative to the texture's corner; the matrix maps it to NDC.
  std::vector<float> xyz;
  std::vector<MethodState::Group> features;
  for (const MethodFeature& f : g.features) {
    MethodState::Group grp;
    grp.first = GLint(xyz.size() / 3);
    grp.count = GLsizei(f.triangles * 3);
    grp.rgba = f.rgba;
    for (uint32_t v = f.first_triangle * 3; v < (f.first_triangle + f.triangles) * 3; ++v) {
      xyz.push_back(float(g.triangles[v][0] - e.xmin));
      xyz.push_back(float(g.triangles[v][1] - e.ymin));
      xyz.push_back(0.0f);
    }
    features.push_back(grp);
  }
  m_.texture_triangles = xyz.size() / 9;
  m_.groups = std::move(features);
  m_.prism_vao = upload_positions(gl_, xyz, "texture");
  m_.volume_program =
      gl_.program({{"method_prism.vert.glsl"}, {}, {"method_colour.frag.glsl"}, {}, ""});
  m_.terrain_program = gl_.program(
      {{"terrain.vert.glsl"}, {}, {"terrain.frag.glsl"}, {}, "#define DECAL_TEXTURE_METHOD 1\n"});
  m_.f_terrain_decal = gl_.framebuffer(t_.color, t_.depth);
  glNamedFramebufferTexture(m_.f_terrain_decal, GL_COLOR_ATTACHMENT1, t_.decal, 0);
  const GLenum bufs[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  glNamedFramebufferDrawBuffers(m_.f_terrain_decal, 2, bufs);
  if (glCheckNamedFramebufferStatus(m_.f_terrain_decal, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    fail<render_error>(kRenderStage, "texture method: terrain framebuffer incomplete");
}

// Taibo et al. §4.2–4.3: the tessellated features rasterised into the
// texture's finest level, then the coarser levels by averaging
// (glGenerateTextureMipmap), the multi-resolution form. Features top first,
// blended front to back; the stencil holds the last feature that wrote a
// texel (1..255, cleared when the numbers run out), so a feature whose own
// pieces overlap (joints, round ends) blends once per texel, as in the
// decal method.
void GlRenderer::texture_raster() {
  timer_.begin("texture raster (once)");
  const uint32_t w = m_.texture_w, h = m_.texture_h;
  GLsizei levels = 1;
  while ((std::max(w, h) >> levels) > 0) ++levels;
  glCreateTextures(GL_TEXTURE_2D, 1, &m_.texture);
  gl_.textures.push_back(m_.texture);
  glTextureStorage2D(m_.texture, levels, GL_RGBA8, GLsizei(w), GLsizei(h));
  m_.texture_bytes = 0;
  for (GLsizei l = 0; l < levels; ++l)
    m_.texture_bytes += uint64_t(std::max(1u, w >> l)) * std::max(1u, h >> l) * 4;
  glTextureParameteri(m_.texture, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTextureParameteri(m_.texture, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTextureParameteri(m_.texture, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_BORDER);
  glTextureParameteri(m_.texture, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_BORDER);
  const float border[4] = {0, 0, 0, 0};
  glTextureParameterfv(m_.texture, GL_TEXTURE_BORDER_COLOR, border);
  GLuint stencil = 0, fbo = 0;
  glCreateRenderbuffers(1, &stencil);
  glNamedRenderbufferStorage(stencil, GL_STENCIL_INDEX8, GLsizei(w), GLsizei(h));
  glCreateFramebuffers(1, &fbo);
  glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, m_.texture, 0);
  glNamedFramebufferRenderbuffer(fbo, GL_STENCIL_ATTACHMENT, GL_RENDERBUFFER, stencil);
  if (glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
    glDeleteFramebuffers(1, &fbo);
    glDeleteRenderbuffers(1, &stencil);
    fail<render_error>(kRenderStage, "texture method: texture framebuffer incomplete");
  }
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glViewport(0, 0, GLsizei(w), GLsizei(h));
  const float clear0[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(fbo, GL_COLOR, 0, clear0);
  const GLint zero = 0;
  glClearNamedFramebufferiv(fbo, GL_STENCIL, 0, &zero);
  const double tw = double(w) * m_.texture_resolution, th = double(h) * m_.texture_resolution;
  Mat4 m{};
  m[0] = 2.0 / tw;
  m[5] = 2.0 / th;
  m[10] = 1;
  m[12] = -1;
  m[13] = -1;
  m[15] = 1;
  const std::array<float, 16> mf = method_floats(m);
  const GLuint p = m_.volume_program;
  glUseProgram(p);
  glUniformMatrix4fv(glGetUniformLocation(p, "u_view_proj"), 1, GL_FALSE, mf.data());
  const GLint loc_rgba = glGetUniformLocation(p, "u_rgba");
  glBindVertexArray(m_.prism_vao);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);
  glEnable(GL_STENCIL_TEST);
  glStencilOp(GL_KEEP, GL_KEEP, GL_REPLACE);
  GLint id = 0;
  for (const MethodState::Group& f : m_.groups) {
    if (++id > 255) {
      glClearNamedFramebufferiv(fbo, GL_STENCIL, 0, &zero);
      id = 1;
    }
    glStencilFunc(GL_NOTEQUAL, id, 0xff);
    glUniform1ui(loc_rgba, f.rgba);
    glDrawArrays(GL_TRIANGLES, f.first, f.count);
  }
  glDisable(GL_STENCIL_TEST);
  glDisable(GL_BLEND);
  glGenerateTextureMipmap(m_.texture);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  glViewport(0, 0, GLsizei(W_), GLsizei(H_));
  timer_.end();
  glDeleteFramebuffers(1, &fbo);
  glDeleteRenderbuffers(1, &stencil);
  // Kept apart: the frame's passes are cleared each frame.
  std::vector<PassTime> t;
  timer_.collect(t);
  if (!t.empty()) m_.raster_time = t.back();
  timer_.passes.clear();
}

// Schneider & Klein §4.2: per group, the prisms into the stencil (front
// faces +1 and back faces -1 where the depth test passes, z-pass; back
// faces +1 and front faces -1 where it fails, z-fail), then a cover pass
// where the count is not zero that resets it (§4.2.2: no stencil clear per
// group). The cover is the scissored screen rectangle of the group's box.
// Depth clamping keeps the far end from clipping the prisms (§4.2.1: the
// far plane at infinity; the perspective projection here already has it).
void GlRenderer::volume_passes() {
  timer_.begin("volume: stencil + cover (" + std::to_string(m_.groups.size()) + " groups, " +
               std::to_string(m_.prism_triangles) + " prism triangles)");
  glBindFramebuffer(GL_FRAMEBUFFER, m_.f_volume);
  const float clear0[4] = {0, 0, 0, 0};
  glClearNamedFramebufferfv(m_.f_volume, GL_COLOR, 0, clear0);
  if (unlit_) glClearNamedFramebufferfv(m_.f_volume, GL_COLOR, 1, clear0);
  const GLint zero = 0;
  glClearNamedFramebufferiv(m_.f_volume, GL_STENCIL, 0, &zero);
  const GLuint pv = m_.volume_program, pc = m_.cover_program;
  glUseProgram(pv);
  glUniformMatrix4fv(glGetUniformLocation(pv, "u_view_proj"), 1, GL_FALSE, view_.view_proj.data());
  const GLint loc_rgba = glGetUniformLocation(pc, "u_rgba");
  const GLint loc_unlit = unlit_ ? glGetUniformLocation(pc, "u_unlit") : -1;
  glEnable(GL_SCISSOR_TEST);
  glEnable(GL_STENCIL_TEST);
  glEnable(GL_DEPTH_CLAMP);
  glDisable(GL_CULL_FACE);
  glDepthFunc(GL_GREATER);  // reversed Z: nearer passes
  glDepthMask(GL_FALSE);
  glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);
  for (const MethodState::Group& g : m_.groups) {
    glScissor(g.scissor[0], g.scissor[1], g.scissor[2], g.scissor[3]);
    // Stencil: no colour, depth test against the terrain, no depth writes.
    glUseProgram(pv);
    glBindVertexArray(m_.prism_vao);
    glColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_BLEND);
    glStencilFunc(GL_ALWAYS, 0, 0xff);
    if (g.zfail) {
      glStencilOpSeparate(GL_FRONT, GL_KEEP, GL_DECR_WRAP, GL_KEEP);
      glStencilOpSeparate(GL_BACK, GL_KEEP, GL_INCR_WRAP, GL_KEEP);
    } else {
      glStencilOpSeparate(GL_FRONT, GL_KEEP, GL_KEEP, GL_INCR_WRAP);
      glStencilOpSeparate(GL_BACK, GL_KEEP, GL_KEEP, GL_DECR_WRAP);
    }
    glDrawArrays(GL_TRIANGLES, g.first, g.count);
    // Cover: where the count is not zero, blended under what is there.
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glStencilFunc(GL_NOTEQUAL, 0, 0xff);
    glStencilOp(GL_KEEP, GL_KEEP, GL_ZERO);
    glUseProgram(pc);
    glUniform1ui(loc_rgba, g.rgba);
    if (unlit_) glUniform1i(loc_unlit, g.unlit ? 1 : 0);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }
  glDisable(GL_BLEND);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_STENCIL_TEST);
  glDisable(GL_DEPTH_CLAMP);
  glDepthMask(GL_TRUE);
  timer_.end();
}

void GlRenderer::method_stats(Image& img) const {
  if (opt_.method == Method::volume) {
    img.prism_triangles = m_.prism_triangles;
    img.volume_groups = uint32_t(m_.groups.size());
    img.zfail_groups = uint32_t(std::count_if(m_.groups.begin(), m_.groups.end(),
                                              [](const MethodState::Group& g) { return g.zfail; }));
  } else if (opt_.method == Method::texture) {
    img.texture_bytes = m_.texture_bytes;
    img.texture_triangles = m_.texture_triangles;
    img.texture_width = m_.texture_w;
    img.texture_height = m_.texture_h;
    img.texture_resolution = m_.texture_resolution;
  }
}

}  // namespace prep::render::detail
