// The GL path (thesis §4.4): terrain G-buffer, static polygon and line
// passes over the back-projected depth (one per run of the drawing order),
// composite, read back.
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <cmath>
#include <cstring>

#include "decal/gl/gl.hpp"
#include "detail/math.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"

namespace prep::render {

namespace {

using detail::Mat4;

void check(const decal::Status& s) {
  if (!s) throw render_error(s.message);
}

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

struct GlObjects {
  std::vector<GLuint> programs, textures, framebuffers, buffers, arrays, queries;
  ~GlObjects() {
    for (GLuint p : programs) glDeleteProgram(p);
    if (!textures.empty()) glDeleteTextures(GLsizei(textures.size()), textures.data());
    if (!framebuffers.empty()) glDeleteFramebuffers(GLsizei(framebuffers.size()), framebuffers.data());
    if (!buffers.empty()) glDeleteBuffers(GLsizei(buffers.size()), buffers.data());
    if (!arrays.empty()) glDeleteVertexArrays(GLsizei(arrays.size()), arrays.data());
    if (!queries.empty()) glDeleteQueries(GLsizei(queries.size()), queries.data());
  }
  GLuint texture(GLenum format, uint32_t w, uint32_t h) {
    GLuint t = 0;
    glCreateTextures(GL_TEXTURE_2D, 1, &t);
    glTextureStorage2D(t, 1, format, GLsizei(w), GLsizei(h));
    glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    textures.push_back(t);
    return t;
  }
  GLuint framebuffer(GLuint color, GLuint depth) {
    GLuint f = 0;
    glCreateFramebuffers(1, &f);
    glNamedFramebufferTexture(f, GL_COLOR_ATTACHMENT0, color, 0);
    if (depth) glNamedFramebufferTexture(f, GL_DEPTH_ATTACHMENT, depth, 0);
    framebuffers.push_back(f);
    if (glCheckNamedFramebufferStatus(f, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw render_error("render: framebuffer incomplete");
    return f;
  }
  // Built once per distinct source list (repeated frames reuse them).
  GLuint program(decal::gl::ProgramSources src) {
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
  std::map<std::string, GLuint> program_cache;
};

// GPU pass timing with GL timestamp queries (--stats): a timestamp before
// and after each pass. (GL_TIME_ELAPSED gave a nonsense first value on
// llvmpipe.)
struct PassTimer {
  GlObjects& gl;
  struct Pass {
    std::string name;
    GLuint begin = 0, end = 0;
    std::chrono::steady_clock::time_point wall0, wall1;
  };
  std::vector<Pass> passes;
  GLuint stamp() {
    GLuint q = 0;
    glGenQueries(1, &q);
    gl.queries.push_back(q);
    glQueryCounter(q, GL_TIMESTAMP);
    return q;
  }
  // glFinish around each pass: software GL (llvmpipe) defers work to the
  // next flush, so without it a pass's time lands in a later pass.
  void begin(const std::string& name) {
    glFinish();
    passes.push_back({name, 0, 0, std::chrono::steady_clock::now(), {}});
    passes.back().begin = stamp();
  }
  void end() {
    passes.back().end = stamp();
    glFinish();
    passes.back().wall1 = std::chrono::steady_clock::now();
  }
  void collect(std::vector<PassTime>& out) {
    for (const auto& p : passes) {
      GLuint64 t0 = 0, t1 = 0;
      glGetQueryObjectui64v(p.begin, GL_QUERY_RESULT, &t0);
      glGetQueryObjectui64v(p.end, GL_QUERY_RESULT, &t1);
      out.push_back({p.name, t1 >= t0 ? double(t1 - t0) * 1e-6 : 0.0,
                     std::chrono::duration<double, std::milli>(p.wall1 - p.wall0).count()});
    }
  }
};

}  // namespace

Image render_gl(const DecalSource& source, const Heightfield& terrain, const RenderOptions& opt) {
  const uint32_t W = opt.width, H = opt.height;
  if (W == 0 || H == 0 || W > 16384 || H > 16384) throw usage_error("render: image size must be 1..16384 pixels");

  // Validate before anything touches GL (formats/gl validate_blobs), once:
  // a package's source was checked when it was made.
  std::vector<decal::gl::BlobBytes> blobs;
  for (const auto& b : source.blobs)
    blobs.push_back({b.id, b.count, {static_cast<const std::byte*>(b.data), size_t(b.bytes)}});
  const GridParams& gp = source.view.grid;
  decal::gl::Grid grid{gp.origin_x, gp.origin_y, gp.cell_w, gp.cell_h, gp.nx, gp.ny};
  if (!source.validated) check(decal::gl::validate_blobs(blobs, grid));

  std::unique_ptr<decal::gl::Context> context;
  check(decal::gl::Context::create(context));
  Image img;
  img.width = W;
  img.height = H;
  img.device = context->info().renderer;
  GLint max_frag_ssbo = 0;
  glGetIntegerv(GL_MAX_FRAGMENT_SHADER_STORAGE_BLOCKS, &max_frag_ssbo);
  {
    GlObjects gl;
    PassTimer timer{gl, {}};
    auto wall0 = std::chrono::steady_clock::now();
    std::unique_ptr<decal::gl::GpuPackage> gpu;
    check(decal::gl::GpuPackage::upload(blobs, grid, gpu, true));

    // Camera anchor: the eye rounded to whole quanta; everything on the GPU
    // is relative to it (ARCHITECTURE.md "Guarantees" 1).
    const Camera& cam = opt.camera;
    const double q = decal::kQuantumMetres;
    const int64_t ax = std::llround(cam.eye[0] / q), ay = std::llround(cam.eye[1] / q);
    const Vec3 anchor{double(ax) * q, double(ay) * q, 0.0};
    const Vec3 eye_rel = detail::sub(cam.eye, anchor);
    const Mat4 vp = detail::mat_mul(detail::projection_matrix(cam, double(W) / H), detail::view_matrix(cam, eye_rel));
    const auto vp_f = to_float(vp);
    const auto inv_f = to_float(detail::mat_inverse(vp));

    // Terrain mesh in anchor-relative metres.
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
    GLuint empty_vao = 0;
    glCreateVertexArrays(1, &empty_vao);
    gl.arrays.push_back(empty_vao);

    // G-buffer: terrain colour + float depth (reversed Z); decal layer; final.
    GLuint t_color = gl.texture(GL_RGBA8, W, H), t_depth = gl.texture(GL_DEPTH_COMPONENT32F, W, H);
    GLuint t_decal = gl.texture(GL_RGBA32F, W, H), t_final = gl.texture(GL_RGBA8, W, H);
    GLuint t_dyn = gl.texture(GL_RGBA32F, W, H);
    GLuint f_terrain = gl.framebuffer(t_color, t_depth), f_decal = gl.framebuffer(t_decal, 0),
           f_final = gl.framebuffer(t_final, 0), f_dyn = gl.framebuffer(t_dyn, 0);

    const std::vector<DrawRun> runs = draw_runs(source.view);
    const bool tex = opt.binding == Binding::texture;
    std::string defines = tex ? "#define DECAL_TEXTURE 1\n" : "";
    std::string aa_defines = opt.aa == AntiAliasing::coverage ? "#define DECAL_AA_COVERAGE 1\n"
                             : opt.aa == AntiAliasing::msaa4  ? "#define DECAL_MSAA 1\n"
                                                              : "";
    GLuint p_terrain = gl.program({{"terrain.vert.glsl"}, {}, {"terrain.frag.glsl"}, {}, ""});
    GLuint p_poly = gl.program({{"fullscreen.vert.glsl"}, {}, {"decal_blobs.glsl", "static_common.glsl", "static_polygons.glsl"}, {},
                                defines + aa_defines + "#define DECAL_POLYGONS 1\n"});
    GLuint p_line = gl.program({{"fullscreen.vert.glsl"}, {}, {"decal_blobs.glsl", "static_common.glsl", "static_lines.glsl"}, {},
                                defines + aa_defines + "#define DECAL_LINES 1\n"});
    GLuint p_comp = gl.program({{"fullscreen.vert.glsl"}, {}, {"composite.frag.glsl"}, {}, ""});
    (void)max_frag_ssbo;

    glViewport(0, 0, GLsizei(W), GLsizei(H));
    glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);

    // Frames after the first show warm times (software GL compiles shader
    // variants at their first draw); pass times are the last frame's.
    for (uint32_t frame = 0; frame < std::max<uint32_t>(opt.frames, 1); ++frame) {
    timer.passes.clear();
    // --- terrain pass
    timer.begin("terrain");
    glBindFramebuffer(GL_FRAMEBUFFER, f_terrain);
    const float sky[4] = {0.80f, 0.86f, 0.93f, 1.0f};
    glClearNamedFramebufferfv(f_terrain, GL_COLOR, 0, sky);
    const float zero = 0.0f;
    glClearNamedFramebufferfv(f_terrain, GL_DEPTH, 0, &zero);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_GREATER);
    glUseProgram(p_terrain);
    glUniformMatrix4fv(glGetUniformLocation(p_terrain, "u_view_proj"), 1, GL_FALSE, vp_f.data());
    Vec3 light = detail::normalize({-0.4, -0.5, 0.75});
    glUniform3f(glGetUniformLocation(p_terrain, "u_light_dir"), float(light[0]), float(light[1]), float(light[2]));
    glUniform3f(glGetUniformLocation(p_terrain, "u_albedo"), float(opt.albedo[0]), float(opt.albedo[1]), float(opt.albedo[2]));
    // Flat terrain (all heights 0) is land, not sea.
    glUniform1f(glGetUniformLocation(p_terrain, "u_sea_level"), terrain.zmax > terrain.zmin ? 0.0f : -1e30f);
    glBindVertexArray(vao);
    glDrawElements(GL_TRIANGLES, GLsizei(idx.size()), GL_UNSIGNED_INT, nullptr);
    glDisable(GL_DEPTH_TEST);
    timer.end();

    // --- static decal passes over the back-projected depth
    gpu->bind(tex ? decal::gl::BindingMode::texture : decal::gl::BindingMode::ssbo);
    glBindTextureUnit(31, t_depth);
    // MSAA (option): the static passes shade every sample (per-sample
    // shading, forced by gl_SamplePosition) into a 4x target, resolved into
    // the decal layer afterwards (thesis §4.5).
    GLuint f_static = f_decal;
    if (opt.aa == AntiAliasing::msaa4) {
      GLuint t_ms = 0;
      glCreateTextures(GL_TEXTURE_2D_MULTISAMPLE, 1, &t_ms);
      gl.textures.push_back(t_ms);
      glTextureStorage2DMultisample(t_ms, 4, GL_RGBA32F, GLsizei(W), GLsizei(H), GL_TRUE);
      f_static = gl.framebuffer(t_ms, 0);
      glEnable(GL_SAMPLE_SHADING);
      glMinSampleShading(1.0f);
    }
    glBindFramebuffer(GL_FRAMEBUFFER, f_static);
    const float clear0[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(f_static, GL_COLOR, 0, clear0);
    glClearNamedFramebufferfv(f_decal, GL_COLOR, 0, clear0);
    glBindVertexArray(empty_vao);
    // Metres per pixel (thesis Eq. 4.1/4.2, per pixel): coverage AA and dynamic lines.
    const double mpp_ortho = cam.projection == Projection::orthographic ? cam.ortho_h / H : 0.0;
    const double mpp_per_m = cam.projection == Projection::perspective
                                 ? 2.0 * std::tan(cam.fov_y_deg * 3.14159265358979323846 / 360.0) / H
                                 : 0.0;
    const int64_t rx = ax - gp.origin_x, ry = ay - gp.origin_y;
    const int64_t cxi = floor_div(rx, gp.cell_w), cyi = floor_div(ry, gp.cell_h);
    auto set_common = [&](GLuint p) {
      glUseProgram(p);
      glUniformMatrix4fv(glGetUniformLocation(p, "u_inv_view_proj"), 1, GL_FALSE, inv_f.data());
      glUniform2f(glGetUniformLocation(p, "u_viewport"), float(W), float(H));
      glUniform2i(glGetUniformLocation(p, "u_anchor_q"), GLint(ax), GLint(ay));
      glUniform2i(glGetUniformLocation(p, "u_anchor_cell"), GLint(cxi), GLint(cyi));
      glUniform2f(glGetUniformLocation(p, "u_anchor_in_cell"), float(double(rx - cxi * gp.cell_w) * q),
                  float(double(ry - cyi * gp.cell_h) * q));
      glUniform2f(glGetUniformLocation(p, "u_cell_size"), float(double(gp.cell_w) * q), float(double(gp.cell_h) * q));
      glUniform2i(glGetUniformLocation(p, "u_grid_n"), GLint(gp.nx), GLint(gp.ny));
      glUniform3f(glGetUniformLocation(p, "u_eye_rel"), float(eye_rel[0]), float(eye_rel[1]), float(eye_rel[2]));
      glUniform1f(glGetUniformLocation(p, "u_mpp_ortho"), float(mpp_ortho));
      glUniform1f(glGetUniformLocation(p, "u_mpp_per_metre"), float(mpp_per_m));
    };
    // A kind with no per-cell ranges is absent: its pass would index the
    // 16-byte placeholder buffer, so it is skipped.
    const bool have_polygons = opt.draw_polygons &&
                               gpu->count(decal::BlobId::poly_bvh_range) == uint64_t(gp.nx) * gp.ny &&
                               gpu->count(decal::BlobId::cell_poly_range) == uint64_t(gp.nx) * gp.ny;
    const bool have_lines = opt.draw_lines &&
                            gpu->count(decal::BlobId::line_bvh_range) == uint64_t(gp.nx) * gp.ny &&
                            gpu->count(decal::BlobId::cell_segment_range) == uint64_t(gp.nx) * gp.ny;
    // The drawing order as runs of one kind, top first (formats/SPEC.md
    // "Drawing order"), each pass blended under the earlier ones: front to
    // back, as the evaluator composites.
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);
    for (const DrawRun& run : runs) {
      const bool lines = run.kind == DrawRun::Kind::lines;
      if (lines ? !have_lines : !have_polygons) continue;
      timer.begin(std::string(lines ? "static lines" : "static polygons") + " [" + std::to_string(run.lo) + ", " +
                  std::to_string(run.hi) + ")");
      const GLuint p = lines ? p_line : p_poly;
      set_common(p);
      glUniform1ui(glGetUniformLocation(p, "u_order_lo"), run.lo);
      glUniform1ui(glGetUniformLocation(p, "u_order_hi"), run.hi);
      glDrawArrays(GL_TRIANGLES, 0, 3);
      timer.end();
    }
    glDisable(GL_BLEND);

    if (f_static != f_decal) {
      timer.begin("msaa resolve");
      glDisable(GL_SAMPLE_SHADING);
      glBlitNamedFramebuffer(f_static, f_decal, 0, 0, GLint(W), GLint(H), 0, 0, GLint(W), GLint(H), GL_COLOR_BUFFER_BIT,
                             GL_NEAREST);
      timer.end();
    }

    // --- dynamic lines (thesis §4.3, §4.4.2)
    const float clear_dyn[4] = {0, 0, 0, 0};
    glClearNamedFramebufferfv(f_dyn, GL_COLOR, 0, clear_dyn);
    const uint64_t n_dyn = gpu->count(decal::BlobId::dyn_vertices);
    const uint64_t n_dyn_lines = gpu->count(decal::BlobId::dyn_line_start);
    if (opt.draw_dynamic && n_dyn > 0 && n_dyn_lines > 0) {
      const std::string dd = defines + (opt.aa == AntiAliasing::coverage ? "#define DECAL_AA_COVERAGE 1\n" : "") +
                             "#define DECAL_DYNAMIC 1\n";
      auto comp = [&](const char* file, const std::string& extra) {
        return gl.program({{}, {}, {}, {"decal_blobs.glsl", "dyn_common.glsl", file}, dd + extra});
      };
      GLuint p_cull = comp("dyn_cull.comp.glsl", ""), p_scan_local = comp("dyn_scan.comp.glsl", "#define SCAN_LOCAL 1\n"),
             p_scan_blocks = comp("dyn_scan.comp.glsl", "#define SCAN_BLOCKS 1\n"),
             p_scatter = comp("dyn_scan.comp.glsl", "#define SCATTER 1\n"), p_segments = comp("dyn_segments.comp.glsl", "");
      GLuint p_lists = gl.program({{"dyn_box.vert.glsl"},
                                   {"decal_blobs.glsl", "dyn_common.glsl", "dyn_scale.glsl", "dyn_box.geom.glsl"},
                                   {"decal_blobs.glsl", "dyn_common.glsl", "dyn_scale.glsl", "dyn_lists.frag.glsl"}, {}, dd});
      GLuint p_dcomp = gl.program({{"fullscreen.vert.glsl"}, {}, {"decal_blobs.glsl", "dyn_common.glsl", "dyn_composite.frag.glsl"}, {}, dd});
      const uint32_t blocks = uint32_t((n_dyn + 255) / 256);
      auto buffer = [&](uint64_t bytes, uint32_t binding) {
        GLuint b = 0;
        glCreateBuffers(1, &b);
        gl.buffers.push_back(b);
        glNamedBufferData(b, GLsizeiptr(std::max<uint64_t>(bytes, 16)), nullptr, GL_DYNAMIC_COPY);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, b);
        return b;
      };
      buffer(n_dyn * 4, 24);
      buffer(n_dyn * 4, 25);
      buffer(uint64_t(blocks) * 4, 26);
      buffer(n_dyn * 4, 27);
      buffer(n_dyn * 16, 28);
      GLuint counters = buffer(32, 29);
      GLuint heads = buffer(uint64_t(W) * H * 4, 31);
      uint32_t capacity = W * H * 2;
      GLuint nodes = buffer(uint64_t(capacity) * 16, 32);
      const uint32_t init[8] = {0, 1, 0, 0, 0, 0, capacity, uint32_t(n_dyn)};
      glNamedBufferSubData(counters, 0, sizeof init, init);

      auto set_dyn = [&](GLuint p) {
        glUseProgram(p);
        glUniform2i(glGetUniformLocation(p, "u_anchor_q"), GLint(ax), GLint(ay));
        glUniformMatrix4fv(glGetUniformLocation(p, "u_view_proj"), 1, GL_FALSE, vp_f.data());
        glUniformMatrix4fv(glGetUniformLocation(p, "u_inv_view_proj"), 1, GL_FALSE, inv_f.data());
        glUniform2f(glGetUniformLocation(p, "u_viewport"), float(W), float(H));
        glUniform1ui(glGetUniformLocation(p, "u_vertex_count"), GLuint(n_dyn));
        glUniform1ui(glGetUniformLocation(p, "u_line_count"), GLuint(n_dyn_lines));
        glUniform3f(glGetUniformLocation(p, "u_eye_rel"), float(eye_rel[0]), float(eye_rel[1]), float(eye_rel[2]));
        glUniform1f(glGetUniformLocation(p, "u_mpp_ortho"), float(mpp_ortho));
        glUniform1f(glGetUniformLocation(p, "u_mpp_per_metre"), float(mpp_per_m));
        glUniform1f(glGetUniformLocation(p, "u_zmin"), float(terrain.zmin));
        glUniform1f(glGetUniformLocation(p, "u_zmax"), float(terrain.zmax));
      };
      // Update indices: cull + same-pixel removal, own stream compaction, segments.
      timer.begin("dynamic update (cull, compact, segments)");
      set_dyn(p_cull);
      glDispatchCompute(blocks, 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      set_dyn(p_scan_local);
      glDispatchCompute(blocks, 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      set_dyn(p_scan_blocks);
      glDispatchCompute(1, 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      set_dyn(p_scatter);
      glDispatchCompute(blocks, 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
      set_dyn(p_segments);
      glDispatchCompute(blocks, 1, 1);
      glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT);
      timer.end();
      // Pixel data: segment boxes -> per-pixel linked lists; grow on overflow.
      timer.begin("dynamic lists (boxes + linked lists)");
      glBindFramebuffer(GL_FRAMEBUFFER, f_dyn);
      glColorMaski(0, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
      glBindBuffer(GL_DRAW_INDIRECT_BUFFER, counters);
      glBindVertexArray(empty_vao);
      for (int attempt = 0; attempt < 4; ++attempt) {
        const uint32_t none = 0xffffffffu;
        glClearNamedBufferData(heads, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &none);
        const uint32_t zero_cap[2] = {0, capacity};
        glNamedBufferSubData(counters, 20, sizeof zero_cap, zero_cap);
        set_dyn(p_lists);
        glDrawArraysIndirect(GL_POINTS, nullptr);
        glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
        uint32_t used = 0;
        glGetNamedBufferSubData(counters, 20, 4, &used);
        if (used <= capacity) break;
        capacity = uint32_t(std::min<uint64_t>(uint64_t(used) * 5 / 4 + 1024, 0x7fffffff / 16));
        glNamedBufferData(nodes, GLsizeiptr(uint64_t(capacity) * 16), nullptr, GL_DYNAMIC_COPY);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, 32, nodes);
        img.list_grows++;
      }
      glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
      timer.end();
      timer.begin("dynamic composite (sort + blend)");
      set_dyn(p_dcomp);
      glDrawArrays(GL_TRIANGLES, 0, 3);
      glMemoryBarrier(GL_ALL_BARRIER_BITS);
      timer.end();
      uint32_t stats[8] = {};
      glGetNamedBufferSubData(counters, 0, sizeof stats, stats);
      img.dyn_segments = stats[0];
      img.dyn_kept = stats[4];
      img.dyn_nodes = stats[5];
    }

    // --- composite
    timer.begin("composite");
    glBindFramebuffer(GL_FRAMEBUFFER, f_final);
    glUseProgram(p_comp);
    glBindTextureUnit(29, t_color);
    glBindTextureUnit(30, t_decal);
    glBindTextureUnit(28, t_dyn);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    timer.end();
    }  // frames

    // --- read back (GL rows are bottom-up)
    std::vector<uint8_t> rgba(size_t(W) * H * 4);
    std::vector<float> dec(size_t(W) * H * 4), dyn(size_t(W) * H * 4);
    glGetTextureImage(t_dyn, 0, GL_RGBA, GL_FLOAT, GLsizei(dyn.size() * sizeof(float)), dyn.data());
    glGetTextureImage(t_final, 0, GL_RGBA, GL_UNSIGNED_BYTE, GLsizei(rgba.size()), rgba.data());
    glGetTextureImage(t_decal, 0, GL_RGBA, GL_FLOAT, GLsizei(dec.size() * sizeof(float)), dec.data());
    if (GLenum e = glGetError(); e != GL_NO_ERROR) throw render_error("render: GL error " + std::to_string(e));
    timer.collect(img.times);
    const double frame = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wall0).count();
    img.times.push_back({"total (incl. upload, shader compile, read-back)", frame, frame});
    img.rgba.resize(rgba.size());
    img.decals.resize(dec.size());
    img.dynamic.resize(dyn.size());
    const size_t row = size_t(W) * 4;
    auto straight = [&](const std::vector<float>& from, std::vector<float>& to) {
      for (uint32_t y = 0; y < H; ++y) {
        const float* src = from.data() + (H - 1 - y) * row;
        float* dst = to.data() + y * row;
        for (uint32_t x = 0; x < W; ++x) {
          float a = src[4 * x + 3];
          for (int c = 0; c < 3; ++c) dst[4 * x + c] = a > 0 ? src[4 * x + c] / a : 0.0f;
          dst[4 * x + 3] = a;
        }
      }
    };
    for (uint32_t y = 0; y < H; ++y) std::memcpy(img.rgba.data() + y * row, rgba.data() + (H - 1 - y) * row, row);
    straight(dec, img.decals);
    straight(dyn, img.dynamic);
  }
  return img;
}

}  // namespace prep::render
