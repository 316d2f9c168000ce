// The GL path's objects and passes (thesis §4.4), internal to prep_render:
// render_gl.cpp runs them, gl_passes.cpp holds setup, terrain, static and
// composite passes, gl_dynamic.cpp the dynamic-line pass. Only those files
// include this header (it pulls in the GL prototypes).
#pragma once

#ifndef GL_GLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES 1
#endif
#include <GL/glcorearb.h>

#include <array>
#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "decal/gl/gl.hpp"
#include "prep/render.hpp"

namespace prep::render::detail {

// Throws render_error with the status message when `s` failed.
void check(const decal::Status& s);

// Owns every GL object a render_gl call creates; deletes them on scope exit
// (before the context goes).
struct GlObjects {
  std::vector<GLuint> programs, textures, framebuffers, buffers, arrays, queries;
  std::map<std::string, GLuint> program_cache;
  GlObjects() = default;
  GlObjects(const GlObjects&) = delete;
  GlObjects& operator=(const GlObjects&) = delete;
  ~GlObjects();
  GLuint texture(GLenum format, uint32_t w, uint32_t h);
  // Colour attachment plus optional depth (0: none); throws when incomplete.
  GLuint framebuffer(GLuint color, GLuint depth);
  // Built once per distinct source list (repeated frames reuse them).
  GLuint program(decal::gl::ProgramSources src);
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
    int tile = -1;  // a tileset's tile (GlRenderer::tile_), -1: the frame's
  };
  std::vector<Pass> passes;
  int tile = -1;  // recorded with the passes begun from now on
  GLuint stamp();
  // glFinish around each pass: software GL (llvmpipe) defers work to the
  // next flush, so without it a pass's time lands in a later pass.
  void begin(const std::string& name);
  void end();
  void collect(std::vector<PassTime>& out);
  // A tileset's table: one row per pass (a static pass's order range
  // dropped), its times summed over the tiles, named with the tiles (and
  // draws) it counts; passes of the whole frame keep their row.
  void collect_per_pass(std::vector<PassTime>& out);
};

// The camera as the shaders take it. The anchor is the eye rounded to whole
// quanta; everything on the GPU is relative to it (ARCHITECTURE.md
// "Guarantees" 1).
struct ViewUniforms {
  int64_t ax = 0, ay = 0;    // anchor in quanta
  Vec3 anchor{}, eye_rel{};  // anchor in metres; eye relative to it
  std::array<float, 16> view_proj{}, inv_view_proj{};
  // Anchor relative to the grid origin (quanta), its cell and the grid.
  int64_t rx = 0, ry = 0, cell_x = 0, cell_y = 0;
  GridParams grid{};
  // Metres per pixel (thesis Eq. 4.1/4.2, per pixel): coverage AA and
  // dynamic lines.
  double mpp_ortho = 0, mpp_per_metre = 0;
  // Clip w of the near plane (perspective; 0: orthographic): dashes of
  // dynamic lines measure the projected line in front of it.
  double near_w = 0;
  // RenderOptions::clip relative to the anchor, metres (xmin, ymin, xmax, ymax).
  std::array<float, 4> clip{-3e38f, -3e38f, 3e38f, 3e38f};
};
ViewUniforms view_uniforms(const Camera& cam, const GridParams& grid, uint32_t width,
                           uint32_t height);
// The views formats/gl takes of a source's blobs and grid.
std::vector<decal::gl::BlobBytes> gl_blobs(const DecalSource& source);
decal::gl::Grid gl_grid(const DecalSource& source);
// A tile's (dx, dy) in whole quanta; none when it is not on the quantum
// grid (1 µm).
std::optional<std::array<int64_t, 2>> tile_shift(const TilePlace& t);
// The anchor (ax, ay) in quanta of the camera's frame, and the eye and the
// matrices relative to it.
void set_anchor(ViewUniforms& v, const Camera& cam, int64_t ax, int64_t ay, uint32_t width,
                uint32_t height);
// The anchor's cell in `grid` (rx, ry, cell_x, cell_y, grid).
void set_grid(ViewUniforms& v, const GridParams& grid);
// `clip` (metres relative to the package origin) relative to the anchor.
void set_clip(ViewUniforms& v, const Extent& clip);

// G-buffer: terrain colour + float depth (reversed Z); decal layer; final;
// dynamic-line layer. Each colour texture has its framebuffer. With
// `stencil` (the volume method) the depth texture carries an 8-bit stencil.
// With `slope` the terrain framebuffer has a second target, the terrain
// gradient (RG32F) the line pass reads for slope widths.
// `unlit`: the decal layer's framebuffer also holds the share of the
// light = false layers (attachment 1, `unlit`).
struct Targets {
  GLuint color = 0, depth = 0, decal = 0, final = 0, dyn = 0, gradient = 0, unlit = 0;
  GLuint f_terrain = 0, f_decal = 0, f_final = 0, f_dyn = 0;
};
Targets make_targets(GlObjects& gl, uint32_t width, uint32_t height, bool stencil = false,
                     bool slope = false, bool unlit = false);
// Adds `tex` as colour attachment 1 of `fb` and draws to both.
void attach_second(GLuint fb, GLuint tex, const char* what);

// The GL state of the volume and texture methods (gl_methods.cpp).
struct MethodState {
  // Volume (Schneider & Klein §4.2): one vertex range per group of features
  // drawn with one stencil and one cover pass.
  struct Group {
    GLint first = 0;
    GLsizei count = 0;
    uint32_t rgba = 0;
    bool unlit = false;  // a light = false layer's (the cover divides by the shade)
    bool zfail = false;
    std::array<GLint, 4> scissor{};  // x, y, w, h
  };
  std::vector<Group> groups;
  GLuint prism_vao = 0, f_volume = 0, volume_program = 0, cover_program = 0;
  uint64_t prism_triangles = 0;
  // Texture (Taibo et al. §4): the texture, its box relative to the anchor,
  // the terrain program and framebuffer that sample it.
  GLuint texture = 0, terrain_program = 0, f_terrain_decal = 0;
  std::array<float, 4> texture_box{};
  uint32_t texture_w = 0, texture_h = 0;
  double texture_resolution = 0;
  uint64_t texture_bytes = 0, texture_triangles = 0;
  PassTime raster_time;
};

// Terrain mesh in anchor-relative metres (position + normal per vertex);
// with `slope`, a buffer of each triangle's gradient in draw order
// (Heightfield::triangle_gradient) for the terrain pass's gradient target.
struct TerrainMesh {
  GLuint vao = 0;
  GLsizei index_count = 0;
  GLuint gradients = 0;
};
TerrainMesh upload_terrain_mesh(GlObjects& gl, const Heightfield& terrain, const Vec3& anchor,
                                bool slope = false);

// The programs of the terrain, static and composite passes; `defines` is
// the binding's define, shared with the dynamic programs.
struct StaticPrograms {
  std::string defines;
  GLuint terrain = 0, polygons = 0, lines = 0, composite = 0;
};
// `unlit`: the static passes sum the share of the light = false layers
// into a second target that the composite leaves unlit (static_common.glsl
// g_unlit).
StaticPrograms static_programs(GlObjects& gl, const RenderOptions& opt, bool slope = false,
                               bool unlit = false, bool min_widths = false);

// gl_dynamic.cpp: a package's LOD data on the GPU (kept across frames).
struct LodBuffers;
struct MethodGeometry;  // detail/method_geometry.hpp

// One render_gl call: the state set up once (constructor) and the passes of
// a frame, in order.
class GlRenderer {
 public:
  // Uploads the blobs, the terrain mesh, makes the targets and programs.
  // The GL context must be current and outlive this object.
  GlRenderer(std::span<const decal::gl::BlobBytes> blobs, const decal::gl::Grid& grid,
             const DecalSource& source, const Heightfield& terrain, const RenderOptions& opt);
  // A tileset's tiles in one frame (the decal method; render_gl.cpp says
  // why the result is the per-tile render's): the terrain mesh, targets and
  // programs once; each frame draws the terrain once, then per tile uploads
  // its blobs, draws its static and dynamic passes clipped to its square
  // into the shared layers and frees its buffers before the next tile;
  // composite once. The caller validates the tiles' blobs (formats/gl
  // validate_blobs). Every tile's (dx, dy) must be a whole number of
  // quanta (tile_shift).
  GlRenderer(const TileList& tiles, const Heightfield& terrain, const RenderOptions& opt);
  // All passes of one frame; dynamic-line counts go to `img`.
  void frame(Image& img);
  // Reads the layers back into `img` (rows top-down, straight alpha) with
  // the pass times of the last frame.
  void read_back(Image& img);

 private:
  void setup();
  void terrain_pass();
  // Tileset: puts view_ in tile k's frame and sets scissor_
  // (tile_scissor); when the scissor box is not empty, opens the tile
  // (tile_, its blobs validated unless already) and uploads its blobs and
  // runs (else gpu_ stays empty, the tile is not opened and is skipped).
  void load_tile(size_t k);
  std::array<GLint, 4> tile_scissor() const;
  // The package's blobs and the terrain depth, bound where the decal
  // passes read them (static passes and dynamic lines, whatever --method).
  void bind_package() const;
  // Dashed lines: the source's dash table and static-line vertex distances
  // (uploaded once per package into dash_gl_), bound at their bindings.
  void bind_dashes();
  // gl_passes.cpp: one pass per run of the drawing order, blended under
  // what `f_static` holds (cleared by begin_static, resolved into the decal
  // layer by end_static with MSAA).
  GLuint begin_static();
  void static_passes(GLuint f_static);
  void end_static(GLuint f_static);
  GLuint static_target();
  void set_static_uniforms(GLuint p) const;
  // Slope widths: the current package's layer flags (slope_layers) as the
  // buffer texture the line pass reads.
  void upload_slope_layers(const DecalSource& source);
  // Lit decals: the current package's unlit layer flags (unlit_layers) as
  // the buffer texture the static passes read.
  void upload_unlit_layers(const DecalSource& source);
  // Minimum widths: the current package's min_width_px per layer as the
  // buffer texture the line pass reads.
  void upload_min_widths(const DecalSource& source);
  // gl_methods.cpp: set-up of the volume and texture methods, the volume
  // passes and the texture's rasterisation (once, before the first frame).
  void method_setup();
  void volume_setup(const MethodGeometry& g);
  void texture_setup(const MethodGeometry& g);
  void volume_passes();
  void texture_raster();
  void method_stats(Image& img) const;
  // gl_dynamic.cpp (thesis §4.3, §4.4.2): draws the current package's
  // dynamic lines under what the (cleared) dynamic layer holds; its work
  // buffers live in `work`.
  void dynamic_pass(Image& img, GlObjects& work);
  // gl_dynamic.cpp: the current package's LOD buffers (lod_), or null
  // without RenderOptions::lod or LOD data; the camera in its frame.
  const LodBuffers* lod_data(GlObjects& work);
  Camera lod_camera() const;
  void composite_pass();

  const TileList* tiles_ = nullptr;      // a tileset (null: one package)
  OpenedTile tile_;                      // a tileset's current tile, while it draws
  const DecalSource* source_ = nullptr;  // the package (the current tile)
  const Heightfield& terrain_;
  const RenderOptions& opt_;
  const uint32_t W_, H_;
  GlObjects gl_;
  PassTimer timer_{gl_, {}};
  std::chrono::steady_clock::time_point wall0_;
  std::unique_ptr<decal::gl::GpuPackage> gpu_;
  ViewUniforms view0_;  // the frame's camera, terrain and targets (a tileset's index frame)
  ViewUniforms view_;   // view0_ in the current package's frame
  TerrainMesh mesh_;
  GLuint empty_vao_ = 0;
  Targets t_;
  std::vector<DrawRun> runs_;
  std::array<GLint, 4> scissor_{};  // the current tile's pixels: x, y, w, h
  StaticPrograms p_;
  MethodState m_;
  std::shared_ptr<LodBuffers> lod_;     // gl_dynamic.cpp: the current package's LOD buffers
  bool slope_ = false;                  // some package's lines take slope widths
  GLuint slope_layers_ = 0;             // buffer texture of the current package's flags
  bool unlit_ = false;                  // decals lit, and some layer may be drawn unlit
  GLuint unlit_layers_ = 0;             // buffer texture of the current package's flags
  bool min_widths_ = false;             // some package's lines have minimum widths
  GLuint min_widths_tex_ = 0;           // buffer texture of the current package's widths
  std::unique_ptr<GlObjects> dash_gl_;  // bind_dashes' buffers, for dash_for_
  const DecalSource* dash_for_ = nullptr;
};

}  // namespace prep::render::detail
