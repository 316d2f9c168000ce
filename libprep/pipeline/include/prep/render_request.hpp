// prep/render_request.hpp — `decalprep render` as one request: the options
// as the command line gives them, checked once (check_render_request) and
// drawn (render): the package or the tileset's tiles of the view, the
// terrain, the camera, the PNG and its side files. The command only fills
// the request and prints the outcome (tools/decalprep/cmd_render.cpp).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "prep/render.hpp"
#include "prep/tile.hpp"

namespace prep::render {

// What `decalprep render` is asked; each member is its option as given,
// with the default the command's help names.
struct RenderRequest {
  std::string package;     // a .decals package or a tileset folder
  std::string output;      // -o: the PNG
  std::string raw;         // --raw: the static decal layer as float32 RGBA
  std::string decals_png;  // --decals: the decal layer alone as PNG
  // Terrain: --dem, else the package's build DEM; --flat forces none.
  std::string dem, assume_crs;
  bool flat = false;
  std::optional<double> z_scale, nodata_fill;  // none: the package's
  // The view: a top-down --extent (in --extent-crs or the frame CRS), else
  // --eye and --target (metres relative to the origin), else --fit.
  std::string extent, extent_crs, eye, target;
  std::string size = "640x360";  // WxH
  double fov = 45.0, pitch = 45.0;
  bool ortho = false, fit = false;
  bool cpu = false;  // the CPU evaluator instead of GL
  std::string aa = "none", binding = "ssbo", method = "decal";
  std::string only;                   // polygons,lines,dynamic; empty: all
  std::string slope_widths = "auto";  // auto|on|off
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
  // A tileset: the tiles drawn (prep/tile_select.hpp; their entries are
  // cleared: the index is gone), the index's level-0 tiles, and the drawn
  // tiles' blobs decoded (what --gpu-budget measures).
  TileSelection selection;
  size_t index_tiles = 0;
  uint64_t blob_bytes = 0;
  uint64_t gpu_budget = 0;  // --gpu-budget in bytes; 0: none
  double frame_ms = 0;      // the render call (tile loading not included)
  // --lod off over a package that has LOD segments.
  bool lod_data_unused = false;
};

// Checks the request (check_render_request), opens the package or tileset,
// checks the outputs (only a regular file or nothing, never an input),
// loads the terrain, places the camera, loads the tiles of a tileset that
// the view draws (select_tiles within --gpu-budget), applies the ramps,
// draws with GL (or the CPU evaluator with --cpu) and writes the PNG, the
// world file of a top-down view, --decals and --raw. A warning (a view or
// DEM that misses the data, a build DEM that cannot be read) goes to
// `note`, or with --strict is a strict_error. Throws what the stages throw:
// usage_error, format_error, input_error, output_error, render_error,
// resource_error (a --gpu-budget that even the coarsest tiles exceed).
RenderOutcome render(const RenderRequest& request);

}  // namespace prep::render
