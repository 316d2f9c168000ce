// prep/tile.hpp — stage 3b, tile: one cleaned scene -> the scenes of the
// tiles of a tileset (ARCHITECTURE.md "3b. tile"; the index format is
// formats/SPEC.md "Tilesets").
//
//   SceneFeatures --tile_plan--> TilePlan --tile_scene(key)--> SceneFeatures
//                                                              (one tile, own origin)
//
// Tiles are squares of `size` metres of the frame CRS on a grid anchored at
// the CRS's own zero: tile (x, y) covers [x*size, (x+1)*size) x
// [y*size, (y+1)*size) in absolute frame coordinates, and its package's
// origin is the tile centre, so every tile keeps int32 millimetre positions
// (decal/format.hpp) however far it lies from the scene centre.
//
// A pixel is answered by exactly one tile (the one whose half-open square
// holds it), and the tile answers it exactly as a single package of the whole
// scene would. Each tile therefore carries every feature that can cover a
// point of its square, cut so that the cut cannot show inside it:
//  - static lines and outlines keep whole segments: every segment whose box
//    meets the square grown by `margin` (the widest stroke's reach, corners
//    included), plus one neighbour segment at each end of a run, so the
//    corners on the segments that matter are the corners of the whole line;
//    the run's cut ends lie farther than `margin` from the square;
//  - polygons are clipped to the square grown by `margin` (GEOS rectangle
//    clip); the new edges lie on that border, out of reach of the square;
//  - outlines clipped to their own ring (inset / offset) are clipped as that
//    ring's polygon, so the even-odd test that keeps one side (thesis §3.6)
//    is unchanged inside the square;
//  - dynamic lines (pixel widths) keep whole segments within
//    `dynamic_margin` (half a tile) of the square.
// Drawing-order keys (area, length, importance) are those of the whole
// feature, so every tile sorts its features as the whole scene does.
#pragma once

#include <algorithm>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "prep/features.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/model.hpp"

namespace prep {

struct TileKey {
  int64_t x = 0, y = 0;
  auto operator<=>(const TileKey&) const = default;
};

// "x<X>_y<Y>", the tile's file stem.
std::string tile_name(const TileKey& key);

// The smallest and largest tile size accepted, metres. Above the largest a
// tile's half plus its margin would not fit int32 millimetres.
constexpr double kMinTileSize = 1.0;
constexpr double kMaxTileSize = 4'000'000.0;

struct TilePlan {
  double size = 0;            // tile edge, frame metres
  double margin = 0;          // static strokes' reach beyond a tile, frame metres
  double dynamic_margin = 0;  // dynamic lines' reach (half a tile)
  SceneFrame frame;           // the scene's frame (origin: the scene's)
  // Every tile that receives a part, in key order, with the indices of the
  // scene's polygons, lines and dynamic lines whose boxes reach it.
  struct Members {
    std::vector<uint32_t> polygons, lines, dynamic_lines;
  };
  std::map<TileKey, Members> tiles;

  // The tile's square in absolute frame coordinates.
  Extent square(const TileKey& key) const;
  // The tile's package origin (the square's centre), absolute.
  std::pair<double, double> origin(const TileKey& key) const;
};

// The widest reach of any static stroke of `scene` beyond its line, frame
// metres: half the band (the whole band for inset / offset outlines) over
// sin(miter_limit / 2), the longest a miter corner can reach, plus 1%, at
// least 1 m.
double stroke_margin(const SceneFeatures& scene, const ModelOptions& options);

// The margin stroke_margin() gives for a widest half band `half_width`
// (the same arithmetic): the maximum over chunks of a scene equals the
// whole scene's margin, so a streaming pass can compute it chunk by chunk.
double stroke_margin_of(double half_width, const ModelOptions& options);
// The widest half band of `scene`'s static lines (the argument of
// stroke_margin_of; 0 when there is none).
double stroke_half_width(const SceneFeatures& scene);

// The bounding box of a ring (a polygon part's shell, a line's points):
// what the plan places a part by. Empty rings give an inverted box.
Extent ring_box(const Ring& ring);

// The tiles a part with box `local` (scene coordinates, relative to the
// frame origin `origin_x, origin_y`) reaches when grown by `by`: x in
// [lo.x, hi.x], y in [lo.y, hi.y]. tile_plan places every part with it.
struct TileRange {
  TileKey lo, hi;
  bool holds(const TileKey& k) const {
    return k.x >= lo.x && k.x <= hi.x && k.y >= lo.y && k.y <= hi.y;
  }
};
TileRange tile_range(const Extent& local, double by, double origin_x, double origin_y,
                     double tile_size);

// Throws usage_error when `tile_size` is outside [kMinTileSize, kMaxTileSize].
void check_tile_size(double tile_size);

// Which tiles each part reaches. Throws usage_error when `tile_size` is
// outside [kMinTileSize, kMaxTileSize].
TilePlan tile_plan(const SceneFeatures& scene, const ModelOptions& options, double tile_size);

// The scene of one tile: its parts cut as described above, in the scene's
// order, in coordinates relative to the tile's origin; the frame is the
// scene's with the tile's origin; the extent is the tile's parts' box. The
// manifest holds this tile's counts only (read = kept = features with a part
// here, parts, vertices_out; no entries; the scene's notes): the tileset
// index carries the scene's. Thread-safe (each call has its own GEOS
// context).
SceneFeatures tile_scene(const SceneFeatures& scene, const TilePlan& plan, const TileKey& key);

}  // namespace prep

// ---------------------------------------------------------- tileset index --

namespace prep {

// a tileset directory: tileset.json (the index,
// formats/SPEC.md "Tilesets"), manifest.json (the scene's manifest entries)
// and tiles/<x>_<y>.decals, one package per non-empty tile; with overview
// levels also tiles/L<L>/x<X>_y<Y>.decals.
// The index's format version (major.minor; a reader accepts its own major).
constexpr int kTilesetMajor = 1;
constexpr int kTilesetMinor = 0;
// The minor version of an index with overview levels ("1.1"); an index
// without levels is written as 1.0, byte for byte as before them.
constexpr int kTilesetMinorLevels = 1;
// A level is made to be drawn at no more than this many pixels across a
// tile: its resolution is tile_size / kLevelTilePixels.
constexpr double kLevelTilePixels = 1024;
// An overview level's decal grid has cells at least this many of its
// resolutions wide (ModelOptions::min_cell_m).
constexpr double kLevelMinCellPixels = 2;
constexpr const char* kTilesetIndexName = "tileset.json";
// The largest tileset.json a reader parses and a writer writes
// (formats/SPEC.md "tileset.json"): about 1.9·10^5 tiles of one layer
// (700 bytes a tile of one layer, 230 more per further layer). Parsing takes about 25 times the
// text in memory, so an index at the limit costs ~3 GB; a bigger one is
// refused before it is read.
constexpr uint64_t kMaxTilesetIndexBytes = uint64_t(128) << 20;
// Every count of an index (features, parts, vertices, bytes) is at most
// 2^53: exact as a JSON number in any reader, and sums of a few thousand
// cannot wrap 64 bits.
constexpr uint64_t kMaxTilesetCount = uint64_t(1) << 53;
// Every coordinate, extent, origin and margin of an index lies within
// +-1e12 frame metres (the tile keys' bound times a 1 m tile).
constexpr double kMaxTilesetCoordinate = 1e12;
constexpr const char* kTilesetManifestName = "manifest.json";

struct TileEntry {
  TileKey key;
  Extent square;                      // absolute frame coordinates
  double origin_x = 0, origin_y = 0;  // the package's origin (the square's centre)
  std::string file;                   // relative to the tileset: "tiles/x0_y0.decals"
  uint64_t bytes = 0;
  uint64_t xxh64 = 0;                                   // of the whole file
  uint64_t polygons = 0, lines = 0, dynamic_lines = 0;  // parts in the package
  std::vector<LayerCounts> layers;  // this tile's counts (prep/tile.hpp tile_scene)
};

// One overview level of a tileset (formats/SPEC.md "Overview levels"):
// level L >= 1 has square tiles of tile_size = TilesetIndex::tile_size * 2^L
// on the same grid anchored at the frame CRS's zero, so tile (X, Y) of level
// L covers tiles (2X..2X+1, 2Y..2Y+1) of level L-1. Its parts are simplified
// to `resolution` ground metres, and polygons below `min_area` and lines
// below `min_length` are dropped and counted in `layers`, never silently.
struct TileLevel {
  int level = 0;                    // 1, 2, ...; level 0 (full detail) is TilesetIndex::tiles
  double tile_size = 0;             // metres
  double resolution = 0;            // ground metres per pixel this level is made for
  double min_area = 0;              // m^2: polygons smaller than this are dropped here
  double min_length = 0;            // m: lines shorter than this are dropped here
  std::vector<LayerCounts> layers;  // the level's per-layer counts, drops included
  std::vector<TileEntry> tiles;     // in key order; file "tiles/L<level>/x<X>_y<Y>.decals"
};

struct TilesetIndex {
  int major = kTilesetMajor, minor = kTilesetMinor;
  std::string generator;
  SceneFrame frame;  // origin: the scene's (tiles have their own)
  double tile_size = 0, margin = 0, dynamic_margin = 0;
  Extent extent;  // absolute frame coordinates of every tile's data
  // The scene's manifest: per-layer counts (each feature once, however many
  // tiles it reaches) and notes; the entries are in manifest.json.
  Manifest manifest;
  uint64_t entry_count = 0;
  uint64_t manifest_bytes = 0, manifest_xxh64 = 0;
  std::vector<TileEntry> tiles;   // in key order: x, then y (level 0, full detail)
  double resolution = 0;          // level 0's ground resolution (the build's; 0: exact)
  std::vector<TileLevel> levels;  // overview levels 1, 2, ... in order; empty: none
};

// The index as JSON text (2-space indent, trailing newline; the same index
// gives the same bytes). Throws output_error, before any byte is written,
// when the index would not read back: tileset_index_problem() finds a
// problem, or the text is above kMaxTilesetIndexBytes.
std::string tileset_index_json(const TilesetIndex& index);

// The first range or consistency problem of the index `ix` as "field: what" (the
// field as tileset.json spells it, "manifest.layers[0].read"), or empty.
// read_tileset_index and tileset_index_json both apply it, so a writer
// never writes an index its readers refuse. Checks: the version; the frame
// CRS WKT reads (GDAL/PROJ); origin, extent (not inverted), margins and
// resolution finite and within +-kMaxTilesetCoordinate; the tile size;
// every count at most kMaxTilesetCount; per layer read = kept +
// clipped_away + dropped and repaired <= kept (a tile's layers: read =
// kept); layer names unique; each level's parts_in = parts + dropped_small;
// every layer a level-0 tile names is the manifest's, no tile keeps more of
// a layer than the manifest, and the level-0 tiles together hold at least
// every feature the manifest says was kept.
std::string tileset_index_problem(const TilesetIndex& ix);

// "MAJOR.MINOR", strictly (formats/SPEC.md "tileset.json"): two decimal
// integers of 1 to 9 digits without sign, space or leading zero.
bool parse_tileset_version(const std::string& text, int& major, int& minor);

// True when `path` is a directory holding tileset.json.
bool is_tileset(const std::string& path);

// Reads and checks `dir`/tileset.json as untrusted input: a regular file
// (no FIFO or device) of at most kMaxTilesetIndexBytes, refused before it
// is parsed; types, strict version, every tile's file name
// (tiles/<name>.decals, no other path), keys unique, squares matching keys
// and size, then tileset_index_problem(). Throws format_error naming the
// file and the field at fault; error(ExitCode::input) when it cannot be
// read.
TilesetIndex read_tileset_index(const std::string& dir);

// The tiles whose squares meet `view` (absolute frame coordinates), in index order.
std::vector<const TileEntry*> tiles_in(const TilesetIndex& index, const Extent& view);
// The same for one overview level's tiles.
std::vector<const TileEntry*> tiles_in(const TileLevel& level, const Extent& view);

// Level `level` (>= 1) of a tileset whose level-0 tiles are `tile_size`
// metres, its rule (formats/SPEC.md "Overview levels"): tile_size * 2^level,
// resolution = that / kLevelTilePixels, min_area = resolution^2,
// min_length = resolution; no tiles, no counts.
TileLevel level_parameters(double tile_size, int level);

// The simplification tolerance of a level: an eighth of its resolution, so
// that every point of a simplified part lies within an eighth of a pixel of
// the part (TopologyPreserveSimplify keeps the Douglas-Peucker bound) at
// the finest view the level serves. Half a pixel, the bound the level's
// resolution alone would suggest, moves edges across enough pixel centres
// to show: on 6.4·10^5 generated vertices at 88 m pixels (bench/overview.py's
// data), r/2 changed 8.4% of the pixels of a level-5 view, r/8 4.6%, and
// with the level's coarser grid (kLevelMinCellPixels) r/8 costs the bytes
// r/2 cost without it.
constexpr double kLevelToleranceShare = 1.0 / 8;
inline double level_tolerance(const TileLevel& level) {
  return level.resolution * kLevelToleranceShare;
}

// A static line's tolerance on a level: an eighth of the smaller of the
// level's resolution and the line's width (ground metres). A line narrower
// than a pixel shows as the pixel centres within half its width of it, so
// moving it by a pixel fraction larger than its width moves all of them: on
// the same data, 3 m lines simplified at r/8 = 7.8 m changed 5.0% of the
// pixels of the level-5 view, at an eighth of their width 0.8% (the package
// bytes of the level doubled; its decoded bytes stayed under 4% of the
// full-detail view's). Dynamic lines (width in pixels; pass 0) and
// polygons take level_tolerance.
inline double level_line_tolerance(const TileLevel& level, double width_m) {
  const double t = level_tolerance(level);
  return width_m > 0 ? std::min(t, width_m * kLevelToleranceShare) : t;
}

// "tiles/L<level>/x<X>_y<Y>.decals" (level >= 1), "tiles/x<X>_y<Y>.decals" (0).
std::string tile_file(int level, const TileKey& key);

}  // namespace prep

// ---------------------------------------------------------- tile selection --

namespace prep::render {

// which tiles of a tileset (prep/tile.hpp) a view
// draws: full-detail tiles near the camera, overview levels farther away,
// within a budget of GPU memory (the drawn tiles' blobs, decoded). No GL:
// `decalprep render` runs it before either renderer
// (prep/pipeline.hpp render()).
//
// The rule is a screen-space-error rule, as 3D Tiles refines by geometric
// error: the quadtree of levels is walked from the coarsest level down, and
// a tile of level L is drawn when the level's resolution r_L (ground metres
// its parts were simplified to, TileLevel::resolution) is at most the
// ground size of one screen pixel at the tile's nearest visible point;
// otherwise its four children are visited. Level 0 (full detail) always
// qualifies. The pixel's ground size at distance d from the eye is
// d * 2 tan(fov_y / 2) / height (perspective) and min(ortho_w / width,
// ortho_h / height) (orthographic). A tile's nearest visible point is the
// point of its square, cut to the ground footprint of the view and to the
// tileset's extent, between the terrain heights zmin and zmax, nearest the
// eye. A tile absent from the index has no data: nothing is drawn there.
struct Camera;  // prep/render.hpp

// The bytes a tile's package holds decoded: the sum of its blobs' decoded
// sizes (count x stride), which is what a loaded tile holds in memory and
// bounds what GL uploads of it (several times TileEntry::bytes, which are
// compressed). `decalprep render` reads them from each tile's header and
// blob table (decal::read_package_sizes) and throws format_error naming
// the file when it cannot.
using TileBlobBytes = std::function<uint64_t(int level, const TileEntry& tile)>;

struct TileSelectOptions {
  // Decoded blob bytes (blob_bytes) the drawn tiles may hold; 0: no limit.
  uint64_t gpu_budget = 0;
  // Asked once for each drawn tile and each tile the budget considers
  // drawing instead of its children, no other. Required with a budget;
  // without one it may be empty (the blob byte figures are then 0).
  TileBlobBytes blob_bytes;
  // Draw this level everywhere (0: full detail) instead of choosing.
  std::optional<int> level;
};

struct SelectedTile {
  int level = 0;                     // 0: full detail
  const TileEntry* entry = nullptr;  // into the index
  double pixel_size = 0;             // ground metres per pixel at its nearest visible point
  uint64_t blob_bytes = 0;           // its blobs decoded (TileSelectOptions::blob_bytes)
};

struct TileSelection {
  // Disjoint squares that together cover every tile with data that meets the
  // footprint; by level, then key.
  std::vector<SelectedTile> tiles;
  uint64_t blob_bytes = 0;         // the drawn tiles' blobs decoded: what gpu_budget caps
  uint64_t package_bytes = 0;      // the drawn tiles' package bytes (TileEntry::bytes)
  uint64_t full_detail_bytes = 0;  // package bytes of the level-0 tiles that meet the footprint
  size_t full_detail_tiles = 0;    // how many level-0 tiles meet the footprint
  std::vector<size_t> per_level;   // tiles drawn per level, index = level
  size_t coarsened = 0;            // groups of children the budget replaced by their parent
  // The ground footprint (absolute frame coordinates); none: the camera
  // sees the sky, every tile counts as met.
  std::optional<Extent> footprint;
};

// The tiles of `index` to draw for `camera` (metres relative to the index's
// frame origin) on a width x height image over terrain between zmin and zmax.
// With a budget, while the drawn blob bytes exceed it, the four (or fewer,
// where the others are empty or out of view) drawn children of a tile are
// replaced by that tile, the tile whose own screen-space error (r_L over its
// pixel size) is smallest first, so the view coarsens where it shows least:
// this is raising the error threshold until the view fits. Throws resource_error
// naming the budget and the blob bytes the coarsest tiles need when even
// they exceed it, usage_error when `options.level` names no level of the
// index, and what options.blob_bytes throws.
TileSelection select_tiles(const TilesetIndex& index, const Camera& camera, uint32_t width,
                           uint32_t height, double zmin, double zmax,
                           const TileSelectOptions& options = {});

}  // namespace prep::render

// --------------------------------------------------------- tileset build --

namespace prep::tiling {

// A tileset build in three steps whose state is on disk only, in the work
// folder request.output/.work (tileset_work.hpp), so that each may run in a
// process of its own:
//  1. prepare: the cleaned parts, chunk by chunk in scene order, into the
//     intermediate, the manifest entries into their files, then the plan
//     (which tiles exist, margins, frame, counts, notes, provenance);
//  2. build_tiles: any subset of the plan's tiles, each from its window of
//     the intermediate (tile_scene, build_model, write_model; request.jobs
//     side by side), each with a record of what it made;
//  3. finalize: manifest.json (streamed), then tileset.json last; removes
//     the work folder.

// What write_tileset() did, for the report.
struct TilesetOutcome {
  size_t tiles = 0;   // packages in the index
  size_t built = 0;   // of those, built by this run
  size_t reused = 0;  // of those, kept from an earlier run (they verified)
  size_t empty = 0;   // tiles reached by a part's box but left with no part
  uint64_t bytes = 0;
  double margin = 0;
  // Overview levels (formats/SPEC.md "Overview levels"), all together; the
  // fields above are level 0's.
  int levels = 0;
  size_t level_tiles = 0, level_built = 0, level_reused = 0, level_empty = 0;
  uint64_t level_bytes = 0;
};

// Step 1 out of core: every source read once, in chunks, its features
// spilled to the work folder; the frame chosen from the spill; each layer
// projected (its approximation fitted to the whole layer), cleaned and
// written to the intermediate chunk by chunk; entries streamed. Memory: a
// chunk, the tile keys, the per-layer counts and the read stage's entries.
// The same intermediate, plan and entries as prepare_tileset() of the
// scene read, projected and cleaned in memory.
struct PreparedScene {
  SceneFrame frame;
  Extent extent;  // scene coordinates, as clean sets it
  std::vector<LayerSpec> layers;
  Manifest manifest;  // per-layer counts and notes; no entries
  uint64_t entry_count = 0;
  size_t skipped_failures = 0;  // entries for features skip_failures dropped
  uint64_t polygons = 0, lines = 0, dynamic_lines = 0;
  double read_s = 0, project_s = 0, clean_s = 0;
};

PreparedScene prepare_tileset_streaming(const BuildSpec& spec, const BuildRequest& request,
                                        const std::function<const nlohmann::json&()>& provenance);

// After a failed step: removes the work folder and, when `made_dir` (the
// build created `dir`), `dir`/tiles and `dir` if they are empty; tiles
// already written stay for the next run to keep.
void discard_work(const std::string& dir, bool made_dir);

// Step 2: the plan's tiles i with i % parts == part (parts <= 1: all).
// Each tile to build is checked against request.max_memory once its window
// is cut (estimate_tile); `estimates` (may be null) receives the largest
// tile's estimate, or the one that stopped the build, also when it throws.
struct TileStepOutcome {
  size_t tiles = 0, built = 0, reused = 0, empty = 0;
  // Dynamic-line vertices of the tiles built by this step whose heights
  // came from beyond the DEM, on how many lines, of how many vertices.
  uint64_t dyn_vertices_outside_dem = 0, dyn_lines_outside_dem = 0, dyn_vertices = 0;
};

TileStepOutcome build_tiles(const BuildSpec& spec, const BuildRequest& request, size_t part,
                            size_t parts, std::vector<MemoryEstimate>* estimates = nullptr);

// Step 3: every tile of the plan must have its record. `manifest` (may be
// null) receives the scene's counts and notes.
TilesetOutcome finalize_tileset(const BuildSpec& spec, const BuildRequest& request,
                                Manifest* manifest = nullptr);

// Holds `dir` for one build or one step of it: checks what the folder
// holds (above; output_error, exit 7, naming the folder and what is in the
// way), makes it when `create` and it is absent (made() is then true),
// and takes a lock on it (flock on the folder: exclusive for a whole build,
// prepare and finalize, shared for a tiles step, so that the tiles steps of
// one cluster job run side by side). A lock held elsewhere is an
// output_error that says so; a file system without locks (some network
// file systems) builds without one. The lock goes with the object.
class TilesetDir {
 public:
  enum class Access { exclusive, shared };
  TilesetDir(const std::string& dir, Access access, bool create);
  ~TilesetDir();
  TilesetDir(const TilesetDir&) = delete;
  TilesetDir& operator=(const TilesetDir&) = delete;
  bool made() const { return made_; }

 private:
  std::string dir_;
  int fd_ = -1;
  bool made_ = false;
};

// What SIGINT or SIGTERM leaves of a build (prep/files.hpp): the work
// folder goes, and the tileset folder too when the build made it. Each is
// renamed away first, so that the build's threads, still running, can
// create nothing more in it, then removed. Returns what it removed, for
// the message.
std::string remove_after_interrupt(const std::string& dir, bool made_dir);

}  // namespace prep::tiling
