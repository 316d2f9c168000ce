// The GL path's dynamic-line pass (thesis §4.3, §4.4.2): update indices
// (cull + same-pixel removal, stream compaction, segments) in compute
// shaders, segment boxes into per-pixel linked lists, then sort and blend
// them into the dynamic layer.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "decal/gl/bindings.hpp"
#include "decal/lod.hpp"
#include "detail/gl_render.hpp"

namespace prep::render::detail {

// A package's LOD data on the GPU (lod_common.glsl): its lod_points and
// lod_segments, the map of decal::lod_draw_map and the lines it draws.
struct LodBuffers {
  const DecalSource* source = nullptr;
  GLuint points = 0, segments = 0, map = 0, line_drawn = 0;
  uint64_t n_points = 0, n_segments = 0, lines = 0, full = 0;
};

namespace {

template <class T>
std::span<const T> blob_span(const DecalSource& s, decal::BlobId id) {
  for (const DecalSource::Blob& b : s.blobs)
    if (b.id == id) return {static_cast<const T*>(b.data), size_t(b.bytes / sizeof(T))};
  return {};
}

// Made when a package's dynamic pass first runs; `gl` owns the buffers.
std::shared_ptr<LodBuffers> lod_buffers(GlObjects& gl, const DecalSource& src) {
  auto l = std::make_shared<LodBuffers>();
  l->source = &src;
  const auto points = blob_span<decal::LodPoint>(src, decal::BlobId::lod_points);
  const auto segments = blob_span<decal::LodSegment>(src, decal::BlobId::lod_segments);
  const auto starts = blob_span<uint32_t>(src, decal::BlobId::dyn_line_start);
  const decal::LodDrawMap map = decal::lod_draw_map(
      points, segments, blob_span<uvec2>(src, decal::BlobId::lod_line_range),
      blob_span<std::array<int32_t, 4>>(src, decal::BlobId::dyn_vertices), starts,
      blob_span<std::array<int32_t, 2>>(src, decal::BlobId::dyn_prev_next));
  std::vector<uint32_t> pairs(2 * points.size());
  for (size_t p = 0; p < points.size(); ++p) {
    pairs[2 * p] = map.vertex[p];
    pairs[2 * p + 1] = map.end[p];
  }
  const std::vector<uint32_t> drawn(map.line_drawn.begin(), map.line_drawn.end());
  auto upload = [&](const void* data, uint64_t bytes) {
    GLuint b = 0;
    glCreateBuffers(1, &b);
    gl.buffers.push_back(b);
    const uint32_t pad[4] = {};
    glNamedBufferData(b, GLsizeiptr(std::max<uint64_t>(bytes, 16)), bytes ? data : pad,
                      GL_STATIC_DRAW);
    return b;
  };
  l->points = upload(points.data(), points.size_bytes());
  l->segments = upload(segments.data(), segments.size_bytes());
  l->map = upload(pairs.data(), pairs.size() * 4);
  l->line_drawn = upload(drawn.data(), drawn.size() * 4);
  l->n_points = points.size();
  l->n_segments = segments.size();
  l->lines = map.lines;
  l->full = map.original_segments;
  return l;
}

struct DynPrograms {
  GLuint cull = 0, scan_local = 0, scan_blocks = 0, scatter = 0, segments = 0, lists = 0,
         composite = 0;
  GLuint lod_mask = 0, lod_select = 0, lod_segments = 0;   // with LOD data (lod_programs)
  GLuint dash_local = 0, dash_blocks = 0, dash_apply = 0;  // dyn_dash.comp.glsl
};

void lod_programs(GlObjects& gl, const std::string& dd, DynPrograms& p) {
  auto comp = [&](const char* file) {
    return gl.program({{}, {}, {}, {"decal_blobs.glsl", "lod_common.glsl", file}, dd});
  };
  p.lod_mask = comp("lod_mask.comp.glsl");
  p.lod_select = comp("lod_select.comp.glsl");
  p.lod_segments = comp("lod_segments.comp.glsl");
}

// `dd`: the binding, coverage-AA and dynamic defines.
DynPrograms dyn_programs(GlObjects& gl, const std::string& dd) {
  auto comp = [&](const char* file, const std::string& extra) {
    return gl.program({{}, {}, {}, {"decal_blobs.glsl", "dyn_common.glsl", file}, dd + extra});
  };
  DynPrograms p;
  p.cull = comp("dyn_cull.comp.glsl", "");
  p.scan_local = comp("dyn_scan.comp.glsl", "#define SCAN_LOCAL 1\n");
  p.scan_blocks = comp("dyn_scan.comp.glsl", "#define SCAN_BLOCKS 1\n");
  p.scatter = comp("dyn_scan.comp.glsl", "#define SCATTER 1\n");
  p.segments = comp("dyn_segments.comp.glsl", "");
  p.dash_local = comp("dyn_dash.comp.glsl", "#define DASH_LOCAL 1\n");
  p.dash_blocks = comp("dyn_dash.comp.glsl", "#define DASH_BLOCKS 1\n");
  p.dash_apply = comp("dyn_dash.comp.glsl", "#define DASH_APPLY 1\n");
  p.lists =
      gl.program({{"dyn_box.vert.glsl"},
                  {"decal_blobs.glsl", "dyn_common.glsl", "dyn_scale.glsl", "dyn_box.geom.glsl"},
                  {"decal_blobs.glsl", "dyn_common.glsl", "dyn_scale.glsl", "dash.glsl",
                   "dyn_lists.frag.glsl"},
                  {},
                  dd});
  p.composite = gl.program({{"fullscreen.vert.glsl"},
                            {},
                            {"decal_blobs.glsl", "dyn_common.glsl", "dyn_composite.frag.glsl"},
                            {},
                            dd});
  return p;
}

// One frame of the pass: its work buffers, bound at their SSBO bindings
// (decal::gl::kSsboDyn*, kSsboLod*: decal/gl/bindings.hpp), and the uniforms
// every stage takes.
class DynamicLines {
 public:
  DynamicLines(GlObjects& gl, PassTimer& timer, const ViewUniforms& view,
               const Heightfield& terrain, uint32_t W, uint32_t H, uint64_t n_vertices,
               uint64_t n_lines, double miter_limit_deg, bool dashes)
      : miter_limit_deg_(miter_limit_deg),
        dashes_(dashes),
        gl_(gl),
        timer_(timer),
        view_(view),
        terrain_(terrain),
        W_(W),
        H_(H),
        n_dyn_(n_vertices),
        n_lines_(n_lines),
        blocks_(uint32_t((n_vertices + 255) / 256)) {}

  void make_buffers();
  // With `lod` (its buffers bound): the LOD passes too (lod_*.comp.glsl).
  void update(const DynPrograms& p, const LodBuffers* lod = nullptr);
  void dash(const DynPrograms& p);
  // Returns how often the node buffer grew.
  uint32_t lists(GLuint p_lists, GLuint f_dyn, GLuint empty_vao);
  void composite(GLuint p_composite);
  // Counters 0 (segments drawn), 4 (vertices kept), 5 (list nodes) and 8
  // (pixels whose composite reached its step bound).
  void read_counters(Image& img) const;
  // The frame's LOD work buffers (links, selection) and uniforms; the LOD
  // counts (and with `indices` the selected segments) into `img`.
  void make_lod_buffers(const LodBuffers& lod, double zmin, double zmax, double tolerance_px,
                        const Camera& camera);
  void read_lod(const LodBuffers& lod, Image& img, bool indices) const;

 private:
  void set_lod_uniforms(GLuint p) const;
  GLuint buffer(uint64_t bytes, uint32_t binding);
  void set_uniforms(GLuint p) const;

  const double miter_limit_deg_;  // the package's: below it a miter corner falls back to round
  const bool dashes_;             // a dynamic line is dashed: run dyn_dash.comp.glsl
  GlObjects& gl_;
  PassTimer& timer_;
  const ViewUniforms& view_;
  const Heightfield& terrain_;
  const uint32_t W_, H_;
  const uint64_t n_dyn_, n_lines_;
  const uint32_t blocks_;
  GLuint counters_ = 0, heads_ = 0, nodes_ = 0;
  uint32_t capacity_ = 0;
  GLuint lod_selection_ = 0;
  LodView lod_view_{};
};

GLuint DynamicLines::buffer(uint64_t bytes, uint32_t binding) {
  GLuint b = 0;
  glCreateBuffers(1, &b);
  gl_.buffers.push_back(b);
  glNamedBufferData(b, GLsizeiptr(std::max<uint64_t>(bytes, 16)), nullptr, GL_DYNAMIC_COPY);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, b);
  return b;
}

void DynamicLines::make_buffers() {
  buffer(n_dyn_ * 4, decal::gl::kSsboDynFlags);
  buffer(n_dyn_ * 4, decal::gl::kSsboDynScan);
  buffer(uint64_t(blocks_) * 4, decal::gl::kSsboDynBlocks);
  buffer(n_dyn_ * 4, decal::gl::kSsboDynCompact);
  buffer(n_dyn_ * 16, decal::gl::kSsboDynSegments);
  counters_ = buffer(48, decal::gl::kSsboDynCounters);
  heads_ = buffer(uint64_t(W_) * H_ * 4, decal::gl::kSsboDynHeads);
  capacity_ = W_ * H_ * 2;
  nodes_ = buffer(uint64_t(capacity_) * 16, decal::gl::kSsboDynNodes);
  // dyn_common.glsl DynDash
  buffer(dashes_ ? (4 * n_dyn_ + 3 * uint64_t(blocks_)) * 4 : 16, decal::gl::kSsboDynDash);
  const uint32_t init[12] = {0, 1, 0, 0, 0, 0, capacity_, uint32_t(n_dyn_), 0, 0, 0, 0};
  glNamedBufferSubData(counters_, 0, sizeof init, init);
}

void DynamicLines::set_uniforms(GLuint p) const {
  const Vec3& eye_rel = view_.eye_rel;
  glUseProgram(p);
  glUniform2i(glGetUniformLocation(p, "u_anchor_q"), GLint(view_.ax), GLint(view_.ay));
  glUniform4fv(glGetUniformLocation(p, "u_clip"), 1, view_.clip.data());
  glUniformMatrix4fv(glGetUniformLocation(p, "u_view_proj"), 1, GL_FALSE, view_.view_proj.data());
  glUniformMatrix4fv(glGetUniformLocation(p, "u_inv_view_proj"), 1, GL_FALSE,
                     view_.inv_view_proj.data());
  glUniform2f(glGetUniformLocation(p, "u_viewport"), float(W_), float(H_));
  glUniform1ui(glGetUniformLocation(p, "u_vertex_count"), GLuint(n_dyn_));
  glUniform1ui(glGetUniformLocation(p, "u_line_count"), GLuint(n_lines_));
  glUniform3f(glGetUniformLocation(p, "u_eye_rel"), float(eye_rel[0]), float(eye_rel[1]),
              float(eye_rel[2]));
  glUniform1f(glGetUniformLocation(p, "u_mpp_ortho"), float(view_.mpp_ortho));
  glUniform1f(glGetUniformLocation(p, "u_mpp_per_metre"), float(view_.mpp_per_metre));
  glUniform1f(glGetUniformLocation(p, "u_zmin"), float(terrain_.zmin));
  glUniform1f(glGetUniformLocation(p, "u_zmax"), float(terrain_.zmax));
  glUniform1f(glGetUniformLocation(p, "u_near"), float(view_.near_w));
  glUniform1f(glGetUniformLocation(p, "u_miter_limit_cos"),
              float(std::cos(miter_limit_deg_ * 3.14159265358979323846 / 180.0)));
}

void DynamicLines::make_lod_buffers(const LodBuffers& lod, double zmin, double zmax,
                                    double tolerance_px, const Camera& camera) {
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kSsboLodPoints, lod.points);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kSsboLodSegments, lod.segments);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kSsboLodMap, lod.map);
  glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kSsboLodLineDrawn, lod.line_drawn);
  const GLuint links = buffer(lod.n_points * 8, decal::gl::kSsboLodLinks);
  const uint32_t none = 0xffffffffu;
  glClearNamedBufferData(links, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &none);
  lod_selection_ = buffer(16 + lod.n_segments * 4, decal::gl::kSsboLodSelection);
  const uint32_t zero[4] = {};
  glNamedBufferSubData(lod_selection_, 0, sizeof zero, zero);
  lod_view_ = lod_view(camera, H_, zmin, zmax, tolerance_px);
}

void DynamicLines::set_lod_uniforms(GLuint p) const {
  set_uniforms(p);
  glUniform3d(glGetUniformLocation(p, "u_lod_camera"), lod_view_.cx, lod_view_.cy, lod_view_.cz);
  glUniform2d(glGetUniformLocation(p, "u_lod_eps"), lod_view_.base, lod_view_.slope);
}

void DynamicLines::read_lod(const LodBuffers& lod, Image& img, bool indices) const {
  uint32_t n[2] = {};
  glGetNamedBufferSubData(lod_selection_, 0, sizeof n, n);
  img.lod_lines += lod.lines;
  img.lod_selected += n[0];
  img.lod_drawn += n[1];
  img.lod_full += lod.full;
  if (!indices || n[0] == 0) return;
  const size_t at = img.lod_selection.size();
  img.lod_selection.resize(at + n[0]);
  glGetNamedBufferSubData(lod_selection_, 16, GLsizeiptr(uint64_t(n[0]) * 4),
                          img.lod_selection.data() + at);
}

// Update indices: cull + same-pixel removal, own stream compaction, segments;
// with LOD data, the LOD lines leave the chains after the cull and their
// visible segments are chosen and appended after the segments pass.
void DynamicLines::update(const DynPrograms& p, const LodBuffers* lod) {
  constexpr GLbitfield kStorage = GL_SHADER_STORAGE_BARRIER_BIT;
  constexpr GLbitfield kDrawn = GL_SHADER_STORAGE_BARRIER_BIT | GL_COMMAND_BARRIER_BIT;
  // Dispatches `groups` work groups of the program in use, then the
  // barrier the next pass needs.
  auto run = [](GLuint groups, GLbitfield barrier) {
    glDispatchCompute(groups, 1, 1);
    glMemoryBarrier(barrier);
  };
  timer_.begin("dynamic update (cull, compact, segments)");
  set_uniforms(p.cull);
  run(blocks_, kStorage);
  if (lod) {
    set_uniforms(p.lod_mask);
    run(blocks_, kStorage);
  }
  for (GLuint prog : {p.scan_local, p.scan_blocks, p.scatter}) {
    set_uniforms(prog);
    run(prog == p.scan_blocks ? 1 : blocks_, kStorage);
  }
  set_uniforms(p.segments);
  run(blocks_, kDrawn);
  timer_.end();
  if (lod) {
    timer_.begin("dynamic LOD (select, compact, segments)");
    const auto groups = GLuint((lod->n_segments + 255) / 256);
    set_lod_uniforms(p.lod_select);
    glUniform1ui(glGetUniformLocation(p.lod_select, "u_lod_segment_count"),
                 GLuint(lod->n_segments));
    run(groups, kStorage);
    set_lod_uniforms(p.lod_segments);
    run(groups, kDrawn);
    timer_.end();
  }
  if (dashes_) dash(p);
}

// Dashes: each kept vertex's screen distance from its line's start, a
// segmented scan of the kept segments' projected lengths.
void DynamicLines::dash(const DynPrograms& p) {
  timer_.begin("dynamic dash (screen length prefix)");
  for (GLuint prog : {p.dash_local, p.dash_blocks, p.dash_apply}) {
    set_uniforms(prog);
    glDispatchCompute(prog == p.dash_blocks ? 1 : blocks_, 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  }
  timer_.end();
}

// Pixel data: segment boxes -> per-pixel linked lists; grow on overflow.
uint32_t DynamicLines::lists(GLuint p_lists, GLuint f_dyn, GLuint empty_vao) {
  uint32_t grows = 0;
  timer_.begin("dynamic lists (boxes + linked lists)");
  glBindFramebuffer(GL_FRAMEBUFFER, f_dyn);
  glColorMaski(0, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  glBindBuffer(GL_DRAW_INDIRECT_BUFFER, counters_);
  glBindVertexArray(empty_vao);
  constexpr int kTries = 4;
  for (int attempt = 0; attempt < kTries; ++attempt) {
    const uint32_t none = 0xffffffffu;
    glClearNamedBufferData(heads_, GL_R32UI, GL_RED_INTEGER, GL_UNSIGNED_INT, &none);
    const uint32_t zero_cap[2] = {0, capacity_};
    glNamedBufferSubData(counters_, 20, sizeof zero_cap, zero_cap);
    set_uniforms(p_lists);
    glDrawArraysIndirect(GL_POINTS, nullptr);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT | GL_BUFFER_UPDATE_BARRIER_BIT);
    uint32_t used = 0;
    glGetNamedBufferSubData(counters_, 20, 4, &used);
    if (used <= capacity_) break;
    // Grow and draw again, unless this was the last try or the buffer is at
    // its largest: then the lists keep the nodes that fitted (the fragment
    // shader only counts the others), and a new, undefined buffer must not
    // replace them before the composite reads them.
    const uint32_t grown =
        uint32_t(std::min<uint64_t>(uint64_t(used) * 5 / 4 + 1024, 0x7fffffff / 16));
    if (attempt == kTries - 1 || grown <= capacity_) break;
    capacity_ = grown;
    glNamedBufferData(nodes_, GLsizeiptr(uint64_t(capacity_) * 16), nullptr, GL_DYNAMIC_COPY);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, decal::gl::kSsboDynNodes, nodes_);
    grows++;
  }
  glColorMaski(0, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  timer_.end();
  return grows;
}

// Blended under what the layer holds (another tile's lines: squares do not
// overlap, so at most one tile's lines reach a pixel centre; the layer is
// cleared once per frame, so a single package's lines land as drawn).
void DynamicLines::composite(GLuint p_composite) {
  timer_.begin("dynamic composite (sort + blend)");
  set_uniforms(p_composite);
  glEnable(GL_BLEND);
  glBlendFunc(GL_ONE_MINUS_DST_ALPHA, GL_ONE);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glDisable(GL_BLEND);
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  timer_.end();
}

void DynamicLines::read_counters(Image& img) const {
  uint32_t stats[9] = {};
  glGetNamedBufferSubData(counters_, 0, sizeof stats, stats);
  img.dyn_segments += stats[0];
  img.dyn_kept += stats[4];
  img.dyn_nodes += stats[5];
  img.dyn_truncated += stats[8];
}

// Whether some dynamic line's layer has a dash pattern (then the pass runs
// dyn_dash.comp.glsl).
bool dynamic_dashes(const DecalSource& source) {
  if (!source.view.dashes || !source.view.dashes->table.any()) return false;
  for (const DecalSource::Blob& b : source.blobs) {
    if (b.id != decal::BlobId::dyn_line_props) continue;
    for (uint64_t k = 0; k < b.bytes / sizeof(decal::LineProps); ++k) {
      decal::LineProps p;
      std::memcpy(&p, static_cast<const std::byte*>(b.data) + k * sizeof p, sizeof p);
      if (!source.view.dashes->table.of(p.layer).empty()) return true;
    }
  }
  return false;
}

}  // namespace

// Draws into the dynamic layer (cleared by frame()) when there are dynamic
// lines to draw; the work buffers go into `work`, the programs into gl_.
void GlRenderer::dynamic_pass(Image& img, GlObjects& work) {
  const uint64_t n_dyn = gpu_->count(decal::BlobId::dyn_vertices);
  const uint64_t n_dyn_lines = gpu_->count(decal::BlobId::dyn_line_start);
  if (!opt_.draw_dynamic || n_dyn == 0 || n_dyn_lines == 0) return;
  // The volume and texture methods draw no static decal pass, which is
  // where the decal method binds these.
  bind_package();
  bind_dashes();
  // Minimum widths in metres (min_width_m), per layer.
  const bool min_widths = !source_->min_width_m.empty();
  if (min_widths) {
    GLuint buf = 0, tex = 0;
    glCreateBuffers(1, &buf);
    work.buffers.push_back(buf);
    glNamedBufferStorage(buf, GLsizeiptr(source_->min_width_m.size() * sizeof(float)),
                         source_->min_width_m.data(), 0);
    glCreateTextures(GL_TEXTURE_BUFFER, 1, &tex);
    work.textures.push_back(tex);
    glTextureBuffer(tex, GL_R32F, buf);
    glBindTextureUnit(decal::gl::kUnitDynMinWidths, tex);
  }
  const std::string dd =
      p_.defines + (opt_.aa == AntiAliasing::coverage ? "#define DECAL_AA_COVERAGE 1\n" : "") +
      (min_widths ? "#define DECAL_DYN_MIN_WIDTHS 1\n" : "") + "#define DECAL_DYNAMIC 1\n";
  DynPrograms p = dyn_programs(gl_, dd);
  DynamicLines dyn(work, timer_, view_, terrain_, W_, H_, n_dyn, n_dyn_lines,
                   source_->miter_limit_deg, dynamic_dashes(*source_));
  dyn.make_buffers();
  const LodBuffers* lod = lod_data(work);
  if (lod) {
    lod_programs(gl_, dd, p);
    dyn.make_lod_buffers(*lod, terrain_.zmin, terrain_.zmax, opt_.lod_tolerance_px, lod_camera());
  }
  dyn.update(p, lod);
  img.list_grows += dyn.lists(p.lists, t_.f_dyn, empty_vao_);
  dyn.composite(p.composite);
  dyn.read_counters(img);
  if (lod) dyn.read_lod(*lod, img, opt_.lod_read_selection);
}

// The current package's LOD buffers when RenderOptions::lod and it has LOD
// segments (made once for a package; per tile for a tileset, whose tiles'
// buffers go with `work`); else null.
const LodBuffers* GlRenderer::lod_data(GlObjects& work) {
  if (!opt_.lod || blob_span<decal::LodSegment>(*source_, decal::BlobId::lod_segments).empty())
    return nullptr;
  if (tiles_ || !lod_ || lod_->source != source_) lod_ = lod_buffers(tiles_ ? work : gl_, *source_);
  return lod_.get();
}

// The camera in the current package's frame: the anchor (whole quanta, the
// package's) plus the eye relative to it, which is the eye exactly for one
// package (Sterbenz: eye - anchor is exact) and the eye moved by the tile's
// origin for a tileset's tile.
Camera GlRenderer::lod_camera() const {
  Camera c = opt_.camera;
  const double q = decal::kQuantumMetres;
  c.eye = {double(view_.ax) * q + view_.eye_rel[0], double(view_.ay) * q + view_.eye_rel[1],
           c.eye[2]};
  return c;
}

}  // namespace prep::render::detail
