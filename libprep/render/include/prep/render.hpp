// prep/render.hpp — stage 7 (render): draws a decal package over terrain,
// headless, with OpenGL (formats/gl) or, for comparison, on the CPU with the
// evaluator (prep::evaluate) over the same terrain and camera.
//
//   .decals --load--> DecalSource --render_gl / render_cpu--> Image --> PNG
//
// Coordinates are scene metres relative to the package origin (the frame of
// prep::evaluate); GL work happens in anchor-relative metres. `decalprep
// render --extent` takes absolute coordinates of the frame CRS, as `build
// --extent` and the world file do (prep::extent_in_frame_crs), and
// subtracts the origin before it gets here.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "prep/dem.hpp"
#include "prep/evaluate.hpp"
#include "prep/features.hpp"
#include "prep/model.hpp"

namespace decal {
class Package;
}

namespace prep::render {

using Vec3 = std::array<double, 3>;

enum class Projection { perspective, orthographic };

// A pinhole (perspective) or parallel (orthographic) camera.
struct Camera {
  Projection projection = Projection::perspective;
  Vec3 eye{0, 0, 1000}, target{0, 0, 0}, up{0, 0, 1};
  double fov_y_deg = 45.0;          // perspective: vertical field of view
  double ortho_w = 0, ortho_h = 0;  // orthographic: view size in metres
  double near = 1.0;                // perspective near plane (far is infinite)
  double depth_range = 1e5;         // orthographic: metres in front of the eye
  // Set by topdown_camera(): the imaged extent exactly as given (so the CPU
  // path places pixel centres from the same numbers).
  std::optional<Extent> topdown_extent;
};

// Top-down orthographic camera whose pixel (i, j) centre lies at
// (xmin + (i + 0.5) * (xmax - xmin) / W, ymax - (j + 0.5) * (ymax - ymin) / H),
// exactly as gdal_rasterize -te/-ts and prep::render_topdown place them.
Camera topdown_camera(const Extent& extent, double zmin, double zmax);

// Oblique camera framing `extent` (--fit): looks at its centre from the
// south at `pitch_deg` below the horizontal, far enough that the whole
// extent fits the W x H image.
Camera fit_camera(const Extent& extent, double zmin, double zmax, uint32_t width, uint32_t height,
                  Projection projection, double pitch_deg = 45.0);

// A terrain heightfield sampled on a regular grid of the scene frame:
// sample (i, j) lies at (x0 + i * dx, y0 + j * dy) with height z[i + nx * j].
// The mesh splits every cell into the triangles (00, 10, 11) and (00, 11, 01);
// the GL path rasterises exactly these triangles and the CPU path ray-casts
// them.
struct Heightfield {
  double x0 = 0, y0 = 0, dx = 1, dy = 1;
  uint32_t nx = 2, ny = 2;
  std::vector<double> z;
  double zmin = 0, zmax = 0;
  // Bound on |mesh - DEM surface| in metres: 0 for flat terrain, the
  // twist bound of prep::DemSampler::max_twist() when the mesh lies on the
  // DEM's lattice, +infinity when no bound is known (a DEM in another CRS,
  // or a lattice too fine for max_samples).
  double surface_error_bound = 0;
  // First intersection of the ray o + t d (t > 0) with the mesh; t or nullopt.
  std::optional<double> intersect(const Vec3& o, const Vec3& d) const;
  Vec3 normal_at(uint32_t i, uint32_t j) const;  // vertex normal (central differences)
  // Height of the mesh (the triangles drawn) at scene point (x, y); NaN
  // outside the grid.
  double height_at(double x, double y) const;
  // Gradient (dh/dx, dh/dy) of triangle `upper` (false: (00, 10, 11), true:
  // (00, 11, 01)) of cell (i, j); the GL terrain pass draws it as primitive
  // 2 (i + (nx - 1) j) + upper.
  std::array<double, 2> triangle_gradient(uint32_t i, uint32_t j, bool upper) const;
  // Gradient of the triangle holding scene point (x, y), the one height_at
  // interpolates in; (0, 0) outside the grid.
  std::array<double, 2> gradient_at(double x, double y) const;
};

// Flat terrain at height 0 covering `extent`.
Heightfield flat_heightfield(const Extent& extent);

// The terrain mesh of the DEM surface (prep/dem.hpp: the surface terrain
// matching drapes dynamic lines on, with the same CRS rule, no-data fill,
// band scale and offset, vertical units and z-scale) covering `extent`.
// Every mesh vertex is a height of that surface. When the DEM's cell-centre
// lattice is a regular grid of the scene frame (DEM in the frame CRS,
// north-up), the vertices lie on that lattice, each cell split s x s times
// with s the smallest that keeps the mesh within kMeshTolerance of the
// bilinear surface (DemSampler::max_twist); otherwise the grid follows the
// frame with the spacing of the DEM cell near the centre (vertices on the
// surface, no bound between them: surface_error_bound is infinite).
// At most `max_samples` vertices per axis (coarser when the extent needs
// more). Throws input_error / gdal_error naming the file when the DEM cannot
// be read or transformed.
// kMeshTolerance: a quarter of the package's height quantum, so that a stored
// dynamic-line height (rounded to 1 mm) and the mesh under it agree to
// 0.75 mm. kMeshSamples: `decalprep render`'s vertices per axis.
constexpr double kMeshTolerance = 0.25e-3;
constexpr uint32_t kMeshSamples = 512;
Heightfield load_heightfield(const DemSpec& dem, const SceneFrame& frame, const Extent& extent,
                             uint32_t max_samples = kMeshSamples);

// The DEM a package was built with and the settings that made its surface,
// from its metadata (build_options: dem, dem_assume_crs, z_scale,
// nodata_fill; a mosaic's dem is a list: path and more_paths); an empty
// path when it records none. Missing keys keep the
// DemSpec defaults. A relative DEM path is relative to the package's folder
// (formats/SPEC.md "Metadata"): given `package_path`, it is resolved there
// (also behind a /vsizip/, /vsigzip/, /vsitar/ or /vsi7z/ prefix). The spec
// is marked named_by_package, so opening it follows prep/dem.hpp's rule for
// a DEM a package names (a local regular file, self-contained drivers;
// never the network).
DemSpec recorded_dem(const std::string& metadata_json, const std::string& package_path = {});

// ---------------------------------------------------------- terrain files --
// The terrain file version this build writes; it reads any minor of its
// major (formats/SPEC.md "Terrain files").
inline constexpr uint16_t kTerrainFileMajor = 1, kTerrainFileMinor = 0;

// The mesh `render` draws, in a file a browser reads (formats/SPEC.md
// "Terrain files"): STEM.terrain beside STEM.decals, written by `decalprep
// terrain`. The heights are stored bit for bit, so a decoded mesh is the
// encoded one exactly.
struct TerrainFile {
  Heightfield mesh;                   // x0, y0 relative to the origin below; zmin, zmax, bound
  double origin_x = 0, origin_y = 0;  // the package's frame origin (absolute)
  uint64_t source_xxh64 = 0;          // XXH64 of the package (tileset.json); 0: none
};
// The first 8 bytes of every terrain file.
inline constexpr std::array<uint8_t, 8> kTerrainMagic = {0x89, 'D',  'T',  'R',
                                                         0x0D, 0x0A, 0x1A, 0x0A};
// Limits a reader enforces (SPEC "Terrain files": Limits).
constexpr uint32_t kTerrainMaxSide = 16384;
constexpr uint64_t kTerrainMaxVertices = uint64_t(1) << 24;

// The mesh `render` draws for a package (or tileset) whose frame and data
// extent (metres relative to the origin) are given, with `dem`: exactly
// load_heightfield(dem, frame, extent, kMeshSamples), the terrain of
// render's --fit, --eye/--target and of a top-down --extent inside the
// extent. Throws as load_heightfield does.
TerrainFile make_terrain(const DemSpec& dem, const SceneFrame& frame, const Extent& extent,
                         uint64_t source_xxh64);

// The file's bytes. Throws usage_error when the mesh breaks a limit of the
// format (sizes, non-finite numbers, zmin/zmax not the heights' range).
std::string encode_terrain(const TerrainFile& terrain);

// The header's position and height fields by their SPEC names, in the
// order SPEC "Terrain files" lists them: x0, y0, dx, dy, zmin, zmax,
// origin_x, origin_y (surface_error_bound, which may be infinite, apart).
std::array<std::pair<const char*, double>, 8> terrain_fields(const TerrainFile& t);

// Reads a terrain file, treating it as hostile: every field is checked in
// the order of SPEC "Terrain files" (Validation) before it is used. Throws
// format_error "<label>: <field>: <why>" naming the field and the bad value.
TerrainFile decode_terrain(std::span<const uint8_t> bytes, const std::string& label);

// The terrain file at `path`: opened as the package reader opens a file
// (never a FIFO, device or socket), refused unread when larger than the
// format's largest file, then decode_terrain. Throws input_error when it
// cannot be read.
TerrainFile read_terrain_file(const std::string& path);

// The decal data a renderer reads: frame, extent, grid and the static view
// (CPU) plus the raw blobs (GL), all views into an owner that must outlive it.
struct DecalSource {
  SceneFrame frame;
  Extent extent;
  StaticView view;
  struct Blob {
    decal::BlobId id{};
    uint64_t count = 0;
    const void* data = nullptr;
    uint64_t bytes = 0;
  };
  std::vector<Blob> blobs;
  // The blobs passed the package's structural check with this grid
  // (decal::validate_blobs; source_of(Package) runs it), so render_gl does
  // not run it again. False for models in memory: render_gl checks them.
  bool validated = false;
  // Miter corners of dynamic lines fall back to round below this angle
  // between segments: the package's build_options.miter_limit_deg (the
  // static corners were built with it), else the build default.
  double miter_limit_deg = 40.0;
  // Per layer-table index: the layer's static line widths are measured
  // along the terrain (the metadata layer table's slope_widths; formats/
  // SPEC.md "Slope widths"), then a 0 that a line layer past the table
  // takes (prep::SurfaceSlope). Empty when no layer asks, or for a model in
  // memory.
  std::vector<uint8_t> slope_layers;
  // Per layer-table index: the layer's static decals are drawn unlit under
  // RenderOptions::decal_light (the layer table's light = false; formats/
  // SPEC.md "Lit decals"), then a 0 for layers past the table. Empty when
  // every layer is lit.
  std::vector<uint8_t> unlit_layers;
  // Minimum widths (formats/SPEC.md "Minimum widths"): per layer-table
  // index the layer's min_width_px, then a 0 for layers past the table
  // (empty when no layer has one), and the package's pixel limit
  // (metadata min_width_pixel_m). A static line is drawn with half width
  // max(hw, f N min(pixel, limit)), f = 1/2 (1 for inset and offset).
  std::vector<float> min_width_px;
  double min_width_pixel_m = 0;
  // The largest f N over those layers, times a miter's reach 1 / sin(limit
  // / 2) for a mitred layer (min_width_reach).
  double min_width_reach = 0;
  // Per layer-table index the layer's min_width_m (dynamic lines: drawn at
  // least that many ground metres wide), then a 0; empty when no layer has
  // one.
  std::vector<float> min_width_m;
};

// Views of a model in memory (for tests and `build --render`).
DecalSource source_of(const DecalModel& model);
// Views of an opened package; reads frame, extent and grid from its
// metadata. Throws format_error when they are missing or inconsistent.
DecalSource source_of(const decal::Package& package);

// Colour ramps applied when drawing (`render --ramp`): thesis §4.2.1 stores
// a value per feature (LineProps/PolyProps.value) and maps it through a
// transfer function, so a value-coloured layer is restyled without a
// rebuild. One entry per layer of the package's layer table (the metadata's
// "layers", which LineProps::layer and PolyProps::layer index); no stops:
// the layer keeps its stored colours.
using LayerRamps = std::vector<std::vector<ColorStop>>;

// A string field `key` of each entry of a package's layer table, in index
// order (metadata "layers"[i][key]; "" where missing); empty when the
// metadata has no layer table.
std::vector<std::string> layer_strings(const std::string& metadata_json, const char* key);
// layer_strings(metadata_json, "name").
std::vector<std::string> layer_names(const std::string& metadata_json);

// The recoloured props of one source; they must outlive it.
struct RestyledProps {
  std::vector<decal::PolyProps> poly;
  std::vector<decal::LineProps> line, dyn;
  uint64_t recoloured = 0;  // features whose colour the ramps set
};

// Recolours `source` for every renderer (decal, volume and texture methods,
// GL and CPU alike): each exterior polygon, static line and dynamic line of a
// layer with stops gets prep::ramp_rgba(stops, its stored value, its stored
// colour) (prep/model.hpp, the build's own formula); a feature with no
// value (NaN) keeps its stored colour. The props are copied into `held`
// and the source's view and blobs point at the copies; the package is not
// touched. Throws format_error when a feature names a layer past `ramps`.
void restyle(DecalSource& source, const LayerRamps& ramps, RestyledProps& held);

enum class AntiAliasing { none, coverage, msaa4 };
enum class Binding { ssbo, texture };
// How static decals are drawn (thesis §5.2.2 compares the three): the
// screen-space decal method of the package (thesis §4.4); the volume method
// (Schneider & Klein §4: the features extruded to prisms over the terrain's
// height range, stencil counting z-pass or z-fail, one stencil and cover
// pass per run of opaque features of one colour, or per translucent
// feature); the texture method (Taibo et al. §4.2: the same tessellated
// features rasterised into a mipmapped texture over the package extent,
// sampled on the terrain in the terrain pass). Volume and texture draw
// only static polygons and lines; dynamic lines keep the decal method's
// pass. GL only; neither anti-aliases (AntiAliasing::none).
enum class Method { decal, volume, texture };
// Static line widths along the terrain (formats/SPEC.md "Slope widths";
// `render --slope-widths auto|on|off`): as each layer of the package asks
// (DecalSource::slope_layers), or for every static line, or for none. The
// decal method (GL) and the CPU evaluator apply it; dynamic lines (pixels)
// and polygons never change.
enum class SlopeWidths { package, on, off };

// The largest image: each side at most kMaxImageSide pixels and at most
// kMaxImagePixels in all (8192 x 8192). A pixel costs about 40 bytes across
// the RGBA8 image, the float decal layer and the GL targets, so the largest
// image takes about 2.5 GiB.
constexpr uint64_t kMaxImageSide = 16384;
constexpr uint64_t kMaxImagePixels = uint64_t(8192) * 8192;

struct RenderOptions {
  uint32_t width = 640, height = 360;
  Camera camera;
  AntiAliasing aa = AntiAliasing::none;
  Binding binding = Binding::ssbo;
  std::array<double, 3> albedo{0.62, 0.66, 0.58};
  // The static decal layer lit by the terrain's light in the final image
  // (render --decal-light on|off): its colour times the terrain pass's
  // Lambert shade at the pixel, 0.35 + 0.65 max(n . l, 0), the same light
  // and normal as the terrain (formats/SPEC.md "Lit decals"). The decal
  // layer itself (Image::decals, --decals, --raw) stays unlit; dynamic lines
  // (screen-space symbols, pixel widths) are drawn unlit over it.
  bool decal_light = true;
  // Which decal kinds to draw (e.g. polygons alone for a coverage check).
  bool draw_polygons = true, draw_lines = true, draw_dynamic = true;
  // GL: frames rendered in one context; pass times are the last one's.
  uint32_t frames = 1;
  // Decals only where the ground point lies in this half-open box, metres
  // relative to the source's origin (one tile's square in a tileset); none:
  // everywhere.
  std::optional<Extent> clip;
  Method method = Method::decal;
  // Texture method: ground metres per texel of the finest level; 0: 1 m,
  // coarser where the extent would need more than kTextureAutoTexels a side.
  double texture_resolution = 0;
  // LOCALIS LOD (formats/SPEC.md "Choosing the threshold"): the dynamic
  // lines of layers built with `lod = true` are drawn from the LOD segments
  // visible for this view at a screen-space tolerance of lod_tolerance_px
  // pixels (lod_view; GL: chosen per segment in a compute shader, CPU:
  // decal::visible_segments); off: from their full vertex chains. Other
  // lines, and packages without LOD data, draw the same either way.
  bool lod = true;
  double lod_tolerance_px = 0.5;
  // GL: copy the indices (into lod_segments) of the selected LOD segments
  // to Image::lod_selection (tests).
  bool lod_read_selection = false;
  SlopeWidths slope_widths = SlopeWidths::package;
};

// Throws usage_error ("render: ...", in the words of `decalprep render`'s
// options) when `options` cannot be drawn: a side outside 1..16384 pixels,
// anti-aliasing or slope widths on with the volume or texture method, a
// negative or non-finite texture resolution. render_gl checks them, and
// check_render_request (prep/pipeline.hpp) before a file is opened.
void check_render_options(const RenderOptions& options);

// The layers whose static lines `mode` measures along the terrain, as
// prep::SurfaceSlope::layers takes them (on: {1}); empty when none is.
std::vector<uint8_t> slope_layers(const DecalSource& source, SlopeWidths mode);

// Minimum widths (formats/SPEC.md "Minimum widths"): how far, per metre of
// min(pixel, min_width_pixel_m), the drawn shape of a min_width_px line
// may pass its BVH leaf box (the stored width's): DecalSource::
// min_width_reach with a 1% margin; 0 without such layers.
double min_width_reach(const DecalSource& source);
constexpr uint32_t kTextureAutoTexels = 8192;

struct PassTime {
  std::string pass;
  double ms = 0;       // GL timestamp queries around the pass (GPU time), or CPU time
  double wall_ms = 0;  // host wall time of the pass, glFinish() on both sides
};

// Row 0 is the top row in both images.
struct Image {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> rgba;   // final image: decals over shaded terrain, 8-bit
  std::vector<float> decals;   // static decal layer alone, straight alpha, 0..1
  std::vector<float> dynamic;  // dynamic-line layer alone, straight alpha
  uint32_t dyn_kept = 0, dyn_segments = 0, dyn_nodes = 0;  // dynamic update counts
  uint32_t list_grows = 0;  // linked-list buffer regrowths this frame
  // Pixels whose dynamic-line composite stopped at its bound of list entries
  // read (dyn_composite.frag.glsl) before compositing every line: 0 unless a
  // pixel holds about a thousand lines.
  uint32_t dyn_truncated = 0;
  std::vector<PassTime> times;
  std::string device;  // GL renderer string, or "cpu"
  // Volume method: prism triangles drawn, stencil+cover groups, groups
  // counted with z-fail (the rest z-pass).
  uint64_t prism_triangles = 0;
  uint32_t volume_groups = 0, zfail_groups = 0;
  // Texture method: texture bytes (every mip level), finest level's size
  // and its ground metres per texel; texture triangles.
  uint64_t texture_bytes = 0, texture_triangles = 0;
  uint32_t texture_width = 0, texture_height = 0;
  double texture_resolution = 0;
  // LOD (RenderOptions::lod): the LOD lines drawn from their segments, the
  // segments the visibility rule selects, those drawn (selected and not
  // outside one frustum plane), and the full-detail segments of those
  // lines; with lod_read_selection the selected indices (any order).
  uint64_t lod_lines = 0, lod_selected = 0, lod_drawn = 0, lod_full = 0;
  std::vector<uint32_t> lod_selection;
};

// The LOD selection of a view (formats/SPEC.md "Choosing the threshold"):
// the camera C of the visibility rule, metres relative to the source's
// origin, and ε(d) = base + slope · max(d, 0). Perspective: slope =
// tolerance_px · 2 tan(fov_y / 2) / height (tolerance_px times a pixel's
// size per metre of distance), base 0, and C = (eye x, eye y, the eye's
// height above or below the terrain range [zmin, zmax], 0 within it), so
// that d never exceeds the distance from the eye to a point on the terrain.
// Orthographic: base = tolerance_px · ortho_h / height, slope 0.
struct LodView {
  double cx = 0, cy = 0, cz = 0;
  double base = 0, slope = 0;
};
LodView lod_view(const Camera& camera, uint32_t height, double zmin, double zmax,
                 double tolerance_px);

// Renders with OpenGL in a headless EGL context. Validates the blobs before
// any GL call (decal::gl::validate_blobs). Throws render_error (exit code
// render) when no EGL display/context can be made, a shader fails or the
// blobs are invalid. Not thread-safe (one GL context per call).
Image render_gl(const DecalSource& source, const Heightfield& terrain,
                const RenderOptions& options);

// Same view on the CPU: top-down orthographic views call prep::render_topdown;
// others ray-cast the same heightfield mesh in double precision and call
// prep::evaluate per pixel. Dynamic lines are drawn at each pixel's ground
// point by the rules of the GL pass (detail/dynamic_cpu.hpp: vertices kept,
// segments, corners at the pixel's scale, every covering line composited in
// drawing order; with RenderOptions::lod, the LOD lines from the segments
// decal::visible_segments selects for lod_view, the GL pass's selection)
// into Image::dynamic, and composited over the decals.
// Thread-safe.
Image render_cpu(const DecalSource& source, const Heightfield& terrain,
                 const RenderOptions& options);

// One tile of a tileset (prep/tile.hpp) as the renderers take it. The
// camera and the terrain are in a reference frame (metres relative to a
// reference origin, e.g. the tileset's frame origin); `square` is the part
// of that plane this tile answers, half-open [xmin, xmax) x [ymin, ymax),
// and (dx, dy) its package origin minus the reference origin.
struct TileSource {
  DecalSource source;
  Extent square;
  double dx = 0, dy = 0;
};

// Where a tile answers, known before its blobs are read: TileSource's
// square and (dx, dy).
struct TilePlace {
  Extent square;
  double dx = 0, dy = 0;
};

// An opened tile: `tile.source` views what `keep` owns (a package's decoded
// blobs, restyled props), freed when the last copy goes.
struct OpenedTile {
  TileSource tile;
  std::shared_ptr<const void> keep;
};

// The tiles of a view as the renderers take them: their places, and how to
// open tile k. A renderer opens each tile when it draws it and lets it go
// before it opens the next, so host memory holds one tile's blobs at a time
// (plus the frame), not the view's; a tile whose square the image does not
// reach is not opened. `open` may be called more than once for a tile (GL
// --frames: once per frame). `slope`: some tile may measure line widths
// along the terrain (slope_layers); the renderer then samples the terrain's
// gradient for every tile. A tile with none draws the same either way.
struct TileList {
  std::vector<TilePlace> places;
  std::function<OpenedTile(size_t k)> open;
  bool slope = false;
  bool unlit = false;       // some tile's layer table has a light = false layer
  bool min_widths = false;  // ... or a layer with min_width_px
};

// A TileList over tiles already in memory (opening one copies its
// TileSource; `keep` stays empty): the caller keeps them alive.
TileList tile_list(std::span<const TileSource> tiles, const RenderOptions& options);

// The GL view of several tiles, each tile's decals clipped to its square
// (RenderOptions::clip). The decal method draws them in one frame and one
// GL context: the terrain once, then each tile opened, its blobs uploaded,
// its passes drawn into the shared layers and its buffers freed in turn
// (render_gl.cpp says why that equals each tile drawn in its own frame).
// The volume and texture methods draw each tile in its own frame and
// context, then take per pixel the tile that drew there.
Image render_gl(const TileList& tiles, const Heightfield& terrain, const RenderOptions& options);
Image render_gl(std::span<const TileSource> tiles, const Heightfield& terrain,
                const RenderOptions& options);

// The CPU view of several tiles: each pixel's ground point is evaluated by
// the one tile whose square holds it (none: no decal), tile by tile, each
// tile opened only while its pixels are evaluated. A single source is one
// tile with an unbounded square.
Image render_cpu(const TileList& tiles, const Heightfield& terrain, const RenderOptions& options);
Image render_cpu(std::span<const TileSource> tiles, const Heightfield& terrain,
                 const RenderOptions& options);

// The ground size of one screen pixel at `point` (metres relative to the
// camera's frame, like the camera).
double pixel_ground_size(const Camera& camera, uint32_t width, uint32_t height, const Vec3& point);

// The box of scene points the camera can see on terrain between zmin and
// zmax (metres relative to the origin): the top-down extent, or the box of
// the image's corner rays where they cross the planes z = zmin and z = zmax.
// None when a corner ray does not come down to the terrain (sky, horizon).
std::optional<Extent> ground_footprint(const Camera& camera, uint32_t width, uint32_t height,
                                       double zmin, double zmax);

// True when `camera` looks straight down with an orthographic projection
// and axis-aligned image (the render_topdown case); `extent` is then the
// imaged area.
bool is_topdown(const Camera& camera, uint32_t width, uint32_t height, Extent* extent = nullptr);

// PNG and world-file output: prep::write_png_rgba, prep::to_rgba8 and
// prep::write_world_file (prep/evaluate.hpp), one writer for every raster.

}  // namespace prep::render
