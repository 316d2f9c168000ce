// prep/pipeline.hpp — the whole build: read -> project -> clean -> build ->
// write, with the JSON report (`decalprep build`): one scene, or a batch of
// scene files each built in its own process.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "prep/error.hpp"
#include "prep/features.hpp"
#include "prep/model.hpp"
#include "prep/progress.hpp"
#include "prep/read.hpp"
#include "prep/render.hpp"
#include "prep/tile.hpp"
#include "prep/write.hpp"

namespace prep {

struct BuildResult {
  SceneFeatures scene;      // what clean produced
  std::string report_json;  // the report (also written to request.report)
  bool package_written = false;
  // Features dropped for a per-feature failure under scene.skip_failures
  // (prep/feature_failure.hpp); > 0 makes the build partial (exit code 4).
  size_t skipped_failures = 0;
};

// Runs the pipeline. Throws prep::error subclasses; on any failure no
// package is written at request.output (the writer is atomic and runs last),
// and request.report (if set) receives {"error", "exit_code",
// "package_written": false} before the exception propagates.
// Throws error(ExitCode::internal) when a package is asked for but this build
// has no build/write stage linked (use dry_run).
BuildResult run_build(const BuildSpec& scene, const BuildRequest& request);

// ------------------------------------------------------- one scene, as asked --
// What `decalprep build` was given for one scene: a scene file, or one GDAL
// source with the single layer of the file-less form, and the values that
// override the scene file's. Values are kept as given and checked by
// scene_spec(), which names the option in its usage_error; in batch mode each
// scene's own process calls it, so a bad value fails every scene with the
// message a single build gives.

// The file-less form's one layer (--layer, --where, --sql, --kind, --width,
// --corner, --outline-mode, --color, --dynamic, and the scene keys --name,
// --color-attribute, --color-ramp "v:#rrggbb,...", --dash "on,off,...",
// --casing-width, --casing-color); empty or unset: not given.
struct FilelessLayer {
  std::string layer, where, sql, kind, corner, outline_mode, color;
  std::string name, color_attribute, color_ramp, dash, casing_color;
  std::optional<double> width, casing_width;
  bool dynamic = false;
};

// Scene-wide values that replace the scene file's; empty or unset: the
// file's. extent "xmin,ymin,xmax,ymax", grid "NXxNY" or "auto", repair
// "linework|structure" as on the command line.
struct SceneOverrides {
  std::string crs, assume_crs, extent, extent_crs, grid, repair;
  std::vector<std::string> dem;  // --dem, repeated for a mosaic
  std::optional<double> resolution, tile_size;
  std::string levels;  // --levels N|auto (formats/SPEC.md "Overview levels")
  std::optional<uint32_t> leaf_capacity, max_depth, threads;
  std::optional<double> lmax, terrain_tolerance, z_scale, nodata_fill;
  bool skip_failures = false;  // true turns it on; false keeps the file's
  bool allow_empty = false;    // --allow-empty: true turns it on; false keeps the file's
};

struct SceneRequest {
  std::string input;  // a scene file (*.toml), else a GDAL source (file-less form)
  FilelessLayer layer;
  SceneOverrides overrides;
};

// The scene to build: the scene file with the overrides, or the file-less
// form's one layer. Throws usage_error naming the option at fault (file-less
// options given with a scene file, a bad or out-of-range value), and what
// load_scene_file() throws.
BuildSpec scene_spec(const SceneRequest& request);

// Exit code of a build that returned: ExitCode::partial when skip_failures
// dropped failing features, else ok.
ExitCode build_exit_code(const SceneSpec& scene, const BuildResult& result);

// ------------------------------------------------------------- batch mode --
// Several scene files (or folders of *.toml) -> output_dir/<stem>.decals
// each. Every scene builds in its own forked process (at most `jobs` at
// once), so a crash or an out-of-memory kill in one leaves the others
// running, and the kernel's rusage gives each scene's peak memory. The
// scene's stderr (its progress, and a last line "decalprep: <error>" when it
// fails) goes to output_dir/<stem>.log, its report to <stem>.report.json.

struct BatchScene;

struct BatchRequest {
  std::vector<std::string> inputs;  // scene files (.toml) and folders of them, in order
  std::string output_dir;           // created if missing
  std::string summary;              // summary JSON path; empty: output_dir/summary.json
  unsigned jobs = 1;                // scenes built side by side (0 counts as 1)
  // Every scene: input is replaced by the scene file.
  SceneRequest scene;
  // Every scene: output, report and progress are replaced per scene;
  // max_memory is ignored (see max_memory below).
  BuildRequest build;
  // Per scene, as given ("2G", "512M"; prep/memory_estimate.hpp); empty:
  // none. jobs is lowered to what the available memory holds at this much
  // per scene.
  std::string max_memory;
  ProgressMode scene_progress = ProgressMode::plain;  // in each scene's log
  // Called in the calling process: when jobs is lowered for max_memory
  // (before any scene starts), and as each scene ends (in the order they
  // end; done counts the ended scenes). Either may be empty.
  std::function<void(unsigned asked, unsigned jobs, double available_gib)> on_jobs_lowered;
  std::function<void(const BatchScene& scene, size_t done, size_t total)> on_scene_done;
};

struct BatchScene {
  std::string scene;                // the scene file
  std::string output, report, log;  // in output_dir
  int exit_code = -1;               // the process's; 128 + signal when killed; -1 not ended
  // The signal that ended the process (SIGKILL from the OOM killer, ...), or
  // SIGINT/SIGTERM for a scene that exited 130/143 (it caught the signal and
  // cleaned up); 0 when it exited by itself.
  int signal = 0;
  // The batch was stopped (SIGINT/SIGTERM) before this scene ended: it was
  // never started, or was stopped with the batch.
  bool interrupted = false;
  double seconds = 0;    // wall time
  long peak_rss_kb = 0;  // the process's peak resident set
  // failed: the log's error line (else its last line); killed: "killed by
  // SIGKILL", and the log's line after it.
  std::string error;

  bool built() const { return !interrupted && exit_code == 0; }
  bool partial() const { return !interrupted && exit_code == static_cast<int>(ExitCode::partial); }
  bool failed() const { return !built() && !partial(); }  // interrupted included
  // "built" | "partial" (package written, skip_failures dropped features) |
  // "failed" | "interrupted"
  const char* status() const {
    return interrupted ? "interrupted" : built() ? "built" : partial() ? "partial" : "failed";
  }
};

struct BatchResult {
  std::vector<BatchScene> scenes;  // input order
  unsigned jobs = 1;               // as run (after lowering)
  // built: scenes.size() - failed (partial included); failed counts the
  // interrupted scenes too.
  size_t failed = 0, partial = 0, interrupted = 0;
  std::string summary;  // the summary JSON's path
  int signal = 0;       // SIGINT or SIGTERM when the batch itself was stopped, else 0
  // ExitCode::interrupted / terminated when the batch was stopped by SIGINT /
  // SIGTERM; else the first failed scene's exit code (input order), a scene
  // ended by a signal counting as ExitCode::killed; else ExitCode::partial
  // when a scene is partial; else 0.
  int exit_code = 0;
};

// Builds every scene and writes the summary JSON: per scene its status, exit
// code, seconds, peak RSS, and the output, report and manifest totals
// ("counts") when written, else the error (and "signal" when a signal ended
// it) and the log; then built, failed, partial, interrupted, jobs and the
// batch's "state". The summary is replaced atomically (a temp file renamed
// over it) when the batch starts ("running", scenes "pending"), as each
// scene ends, and at the end ("finished", or "interrupted").
//
// Signals: while scenes run, SIGINT and SIGTERM (unless ignored when the
// batch began) are passed on to the running scenes; the batch then waits for
// them (SIGKILL after 10 s), records the unfinished scenes as interrupted and
// returns exit_code 130 / 143. Each scene's process dies with the batch's
// (PR_SET_PDEATHSIG), so a batch killed outright leaves no scene running.
//
// Output: the batch writes only OUTDIR/<stem>.decals, .report.json, .log
// and the summary (and a temp file beside the summary), and before creating
// anything refuses with output_error an OUTDIR that exists and is not a
// folder, and any of those names that exists and is not a regular file or
// is an input (a scene file, a source, a DEM; prep/files.hpp). Throws
// usage_error (no output_dir, an input that is neither a .toml nor a folder
// of them, two scenes with the same stem), output_error (the above, the
// folder or the summary cannot be written), error when fork fails; a scene's
// own failure is only reported.
BatchResult run_batch(const BatchRequest& request);

// ---------------------------------------------------------- the scene file --

// Parses scene-file text. `path` is used for messages and to resolve relative
// source and DEM paths (against the file's directory, also inside /vsizip/
// and friends). Unknown keys, wrong types and bad values throw scene_error
// whose message names the file, the key and its line:
//   scene.toml:12: layer[2].kind: expected polygon|line|outline|point, got "poly"
// Thread-safe (no shared state).
BuildSpec parse_scene(const std::string& text, const std::string& path);

// Reads and parses a scene file. Throws scene_error if it cannot be read.
BuildSpec load_scene_file(const std::string& path);

// Resolves a GDAL path written in a scene file against `base_dir`: a plain
// relative path becomes base_dir/path, and a /vsizip/, /vsigzip/, /vsitar/ or
// /vsi7z/ path with a relative archive path gets base_dir inserted after the
// prefix. Absolute paths, URLs and other /vsi prefixes are returned as given.
std::string resolve_scene_path(const std::string& path, const std::string& base_dir);

// Parses a colour: "#rrggbb", "#rrggbbaa" or a CSS-like name list is not
// supported. Returns RGBA with R in the low byte. Throws usage_error.
uint32_t parse_color(const std::string& text);

// Parses "value:#rrggbb[aa],value:#rrggbb[aa],..." (values increasing): a
// colour ramp's stops, as `render --ramp` and `build --color-ramp` take
// them. Throws usage_error saying what is wrong.
std::vector<ColorStop> parse_color_stops(const std::string& text);

// "a,b,c": comma-separated finite numbers with nothing else; nullopt when
// an item is not one (render's --extent/--eye/--target, build's --dash).
std::optional<std::vector<double>> parse_number_list(const std::string& text);

// What is wrong with dash lengths [on, off, ...] (an even count >= 2 of
// finite lengths > 0), or "" when nothing is.
std::string dash_problem(const std::vector<double>& dash);

// The casing layer of a layer with casing_width > 0: the same features,
// casing_width wider on each side, in casing_rgba (default: the layer's
// colour at 60% brightness), solid, named NAME.casing (LayerSpec::casing_of).
LayerSpec casing_layer(const LayerSpec& layer);

// Parses "round|miter|bevel", "normal|inset|offset", "polygon|line|outline|point".
// Throw usage_error naming the accepted values.
decal::CornerStyle parse_corner(const std::string& text);
decal::OutlineMode parse_outline_mode(const std::string& text);
// Parses "linework|structure" (SceneSpec::repair).
RepairMethod parse_repair_method(const std::string& text);
DecalKind parse_kind(const std::string& text);

}  // namespace prep

// ------------------------------------------------------ decalprep render --

namespace prep::render {

// `decalprep render` as one request: the options
// as the command line gives them, checked once (check_render_request) and
// drawn (render): the package or the tileset's tiles of the view, the
// terrain, the camera, the PNG and its side files. The command only fills
// the request and prints the outcome (tools/decalprep/cmd_render.cpp).
// What `decalprep render` is asked; each member is its option as given,
// with the default the command's help names.
struct RenderRequest {
  std::string package;     // a .decals package or a tileset folder
  std::string output;      // -o: the PNG
  std::string raw;         // --raw: the static decal layer as float32 RGBA
  std::string decals_png;  // --decals: the decal layer alone as PNG
  // Terrain: --dem (repeated: a mosaic), else the package's build DEM;
  // --flat forces none.
  std::vector<std::string> dem;
  std::string assume_crs;
  // A terrain file (formats/SPEC.md "Terrain files") to draw instead of a
  // DEM: the mesh the browser draws (`view --screenshot` places its camera
  // over it). Not a render option; the DEM options are then unused.
  std::string terrain_file;
  bool flat = false;
  std::optional<double> z_scale, nodata_fill;  // none: the package's
  // The view: a top-down --extent (in --extent-crs or the frame CRS), else
  // --eye and --target (metres relative to the origin), else --fit.
  std::string extent, extent_crs, eye, target;
  // WxH; with --extent also W or Wx: the height from the extent's aspect
  std::string size = "640x360";
  // A top-down --extent whose aspect is not --size's is widened about its
  // centre to square pixels (stated on stderr); stretch keeps it as given.
  bool stretch = false;
  double fov = 45.0, pitch = 45.0;
  bool ortho = false, fit = false;
  bool cpu = false;  // the CPU evaluator instead of GL
  // --aa; empty: the default, msaa4 in GL with the decal method, none with
  // --cpu and the volume and texture methods, which draw aliased
  // (bench/aa_default.py measured the choice; bench/REPORT.md "Anti-aliasing").
  std::string aa, binding = "ssbo", method = "decal";
  std::string only;                   // polygons,lines,dynamic; empty: all
  std::string slope_widths = "auto";  // auto|on|off
  std::string decal_light = "on";     // on|off: static decals lit by the terrain's light
  double texture_resolution = 0;      // 0: the renderer's default
  std::string lod = "on";             // on|off
  double lod_tolerance = 0.5;         // pixels
  std::string level = "auto";         // tilesets: auto|L
  std::string gpu_budget;             // tilesets: a size (512M, 2G); empty: no limit
  std::vector<std::string> ramps;     // LAYER=value:#rrggbb,...
  uint32_t frames = 1;
  bool strict = false;  // a warning is an error (strict_error, exit 10)
  // Lines for the user, each without its newline: the warnings ("render:
  // warning: ..."), the build DEM used, the tiles drawn. Empty: stderr.
  std::function<void(const std::string&)> note;
};

// One --ramp: a layer of the package's layer table and the stops its
// features' stored values go through when drawing.
struct RampRequest {
  std::string text, layer;
  std::vector<ColorStop> stops;
};

// The request's options parsed and checked, before any file is opened.
struct CheckedRender {
  // Size, anti-aliasing, binding, method, kinds, LOD, slope widths, texture
  // resolution, frames; the camera comes with the terrain (render).
  RenderOptions options;
  TileSelectOptions select;         // --level, --gpu-budget (blob_bytes: render's)
  std::optional<Extent> extent;     // --extent as given: absolute, in --extent-crs or the frame CRS
  std::optional<Vec3> eye, target;  // --eye and --target (not with --extent)
  std::vector<RampRequest> ramps;
};

// Parses and checks every option that needs no file, each in its own words
// ("render: --size '0x5': the width 0 is not within 1..16384"); throws
// usage_error at the first that is wrong. What needs the package (--level
// and --gpu-budget with one package, --extent-crs with a frame that has no
// CRS, --extent in degrees, a --ramp layer the package lacks) render checks.
CheckedRender check_render_request(const RenderRequest& request);

// What render() would draw, up to the drawing (`decalprep view
// --screenshot` draws it in a browser): the checked options with the camera
// placed, the terrain mesh it was placed over, and the scene's frame.
struct RenderView {
  RenderOptions options;                   // as render() draws them, the camera included
  Heightfield terrain;                     // the mesh render() draws (flat with --flat)
  SceneFrame frame;                        // the package's (a tileset's scene) frame
  Extent extent;                           // the data's, metres relative to the origin
  std::optional<Extent> topdown_absolute;  // --extent in the frame CRS (the world file's)
  LayerRamps ramps;                        // --ramp by layer table index; empty: none
};

// Does what render() does before it draws, with the same checks, notes,
// warnings and errors (the outputs are checked, not written): opens the
// package or tileset (a tileset's first tile names the layers and DEM),
// loads the terrain and places the camera. Draws and writes nothing.
RenderView place_render_view(const RenderRequest& request);

// What render drew, for `--stats`.
struct RenderOutcome {
  Image image;
  RenderOptions options;  // as drawn, the camera included
  // The terrain mesh: vertices per axis and its bound on the distance to the
  // DEM surface (Heightfield::surface_error_bound).
  uint32_t terrain_nx = 0, terrain_ny = 0;
  double surface_error_bound = 0;
  size_t ramps = 0;         // --ramp options
  uint64_t recoloured = 0;  // features the ramps recoloured
  bool tileset = false;
  // A tileset: the tiles drawn (prep/tile.hpp; their entries are
  // cleared: the index is gone), the index's level-0 tiles, and the drawn
  // tiles' blobs decoded (what --gpu-budget measures).
  TileSelection selection;
  size_t index_tiles = 0;
  uint64_t blob_bytes = 0;
  uint64_t gpu_budget = 0;  // --gpu-budget in bytes; 0: none
  double frame_ms = 0;      // the render call (a tileset's tiles are opened in it)
  // --lod off over a package that has LOD segments.
  bool lod_data_unused = false;
};

// Checks the request (check_render_request), opens the package or tileset,
// checks the outputs (only a regular file or nothing, never an input),
// loads the terrain, places the camera, chooses the tiles of a tileset that
// the view draws (select_tiles within --gpu-budget), draws with GL (or the
// CPU evaluator with --cpu), opening each tile as it is drawn, restyled by
// the ramps, and letting it go before the next (host memory holds one
// tile's blobs, not the view's), and writes the PNG, the
// world file of a top-down view, --decals and --raw. A warning (a view or
// DEM that misses the data, a build DEM that cannot be read) goes to
// `note`, or with --strict is a strict_error. Throws what the stages throw:
// usage_error, format_error, input_error, output_error, render_error,
// resource_error (a --gpu-budget that even the coarsest tiles exceed).
RenderOutcome render(const RenderRequest& request);

}  // namespace prep::render
