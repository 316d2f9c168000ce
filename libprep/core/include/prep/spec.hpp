// prep/spec.hpp — what a build is asked to do: the layers (LayerSpec), their
// styles, and the scene (SceneSpec): CRS, extent, resolution, repair, DEM,
// tiling. The model stage's knobs are ModelOptions (prep/model.hpp), and a
// whole build's ask is a BuildSpec there. Read, project and clean take a
// SceneSpec.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "decal/format.hpp"

namespace prep {

// point: each point a round dot, drawn as a line of two vertices kPointStep
// apart (formats/SPEC.md "Points"), so every renderer draws it as a line.
enum class DecalKind { polygon, line, outline, point };
// The length of a dot's line: 2 mm, two quanta of a package's coordinates,
// so its ends stay apart; the dot is a disc of the width stretched by it
// (1 mm each way, inside the 2 mm band of the drawing rules).
inline constexpr double kPointStep = 0.002;

// The scene-file word of a kind (the inverse of parse_kind, prep/pipeline.hpp).
inline const char* kind_name(DecalKind kind) {
  switch (kind) {
    case DecalKind::polygon: return "polygon";
    case DecalKind::line: return "line";
    case DecalKind::outline: return "outline";
    case DecalKind::point: return "point";
  }
  return "?";
}

// How `clean` repairs an invalid polygon (GEOS MakeValid's two methods).
//   linework:  GEOS's default (and OGR's): rebuild from all the ring lines,
//              even-odd; a hole sharing an edge with its shell or another
//              hole toggles coverage, and collapsed pieces become lines.
//   structure: union the shells, subtract the holes (GEOS >= 3.10); what a
//              hole is meant to do, and far faster on polygons with very many
//              touching holes when a single MakeValid is needed (polygons
//              with many holes are repaired by parts with either method:
//              libprep/clean/detail/repair_by_parts.hpp).
enum class RepairMethod { linework, structure };

struct ColorStop {
  double value;
  uint32_t rgba;  // R in the low byte
};

// Colour of a layer: a constant, or an attribute mapped through a ramp
// (linear interpolation between stops, clamped at both ends).
struct LayerColor {
  uint32_t rgba = 0xff3366ccu;
  std::string attribute;        // empty: constant colour
  std::vector<ColorStop> ramp;  // sorted by value
};

struct LayerStyle {
  LayerColor color;
  double width = 2.0;  // ground metres (static lines/outlines) or pixels (dynamic)
  decal::CornerStyle corner = decal::CornerStyle::round;
  decal::OutlineMode outline = decal::OutlineMode::normal;
  std::string order_attribute;  // importance; empty: length (lines) / area (polygons)
};

struct LayerSpec {
  std::string name;    // unique within the scene; defaults to the source layer
  std::string source;  // any GDAL path, /vsizip/ included
  std::string layer;   // source layer name; empty: the first layer
  std::string where;   // OGR attribute filter
  std::string sql;     // OGR SQL (replaces layer + where)
  DecalKind kind = DecalKind::polygon;
  bool dynamic = false;  // dynamic lines: width in pixels, terrain-matched
  bool lod = false;      // build LOCALIS LOD segments for this layer's lines
  LayerStyle style;
  int scene_line = 0;  // line in the scene file, for messages (0: command line)
  // Casing (scene file casing_width, casing_color): the scene file's loader
  // puts a copy of the layer just below it, casing_width wider on each side
  // in the casing colour, so that every line of the layer lies on the
  // casings of all of them and crossings of one road class merge cleanly.
  // The copy's casing_of names the layer it lies under.
  double casing_width = 0;  // metres (static) or pixels (dynamic); 0: none
  std::optional<uint32_t> casing_rgba;
  std::string casing_of;
  // Scene file slope_widths: the layer's static line widths are ground
  // widths along the terrain surface, not in plan (formats/SPEC.md "Slope
  // widths"). Recorded in the package's layer table; the package itself
  // stays in plan, and `decalprep render` applies it with its DEM.
  bool slope_widths = false;
  // Scene file light = false: the layer's static decals keep their colour
  // where `render --decal-light on` shades the others by the terrain's
  // light (formats/SPEC.md "Lit decals"). Recorded in the package's layer
  // table; dynamic lines are never lit.
  bool light = true;
  // Scene file min_width_px (static lines, outlines, points): the line is
  // drawn at least this many pixels wide, its width in ground metres raised
  // to N pixels, while a pixel is at most the package's min_width_pixel_m
  // (formats/SPEC.md "Minimum widths"). 0: none.
  double min_width_px = 0;
  // Scene file min_width_m (dynamic lines and points): the line, its width
  // in pixels, is drawn at least this many ground metres wide, so close up
  // a road is never narrower than the ground it stands for. 0: none.
  double min_width_m = 0;
  // Dash pattern (scene file `dash`): [on, off, on, off, ...], lengths > 0
  // along the line from its start, ground metres (static) or pixels
  // (dynamic); empty: solid. A casing copy is solid.
  std::vector<double> dash;
  // Scene file shared_edges = "once" (kind = "outline", outline_mode
  // "normal"): an edge that two rings of the layer share (the same two
  // vertices) is drawn once, by the first ring in scene order; the rings
  // that lost edges are drawn as the open runs they keep. "all" (false):
  // every ring whole.
  bool shared_edges_once = false;
};

struct Extent {
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
  bool empty() const { return !(xmax > xmin && ymax > ymin); }
};

// SceneSpec::levels: "auto", the most levels and when auto stops.
constexpr int kLevelsAuto = -1;
constexpr int kMaxLevels = 16;
constexpr int kAutoLevelTiles = 4;

struct SceneSpec {
  std::vector<LayerSpec> layers;
  std::string crs;               // empty: local Transverse Mercator on the data
  std::string assume_crs;        // CRS for sources that have none
  std::optional<Extent> extent;  // in `extent_crs` (default: scene frame)
  std::string extent_crs;
  double resolution = 0.0;                       // metres; 0 keeps every vertex
  RepairMethod repair = RepairMethod::linework;  // invalid polygons (see RepairMethod)
  std::string dem;                               // GDAL raster path; empty: flat terrain
  // The rasters after the first of a mosaic (scene file dem = [a, b, ...],
  // --dem repeated), joined with `dem` (prep/dem.hpp DemSpec::more_paths);
  // empty: `dem` alone.
  std::vector<std::string> dem_more;
  bool skip_failures = false;
  // A build that keeps no feature from any layer is an error (empty_error,
  // exit 9) and writes no package, unless this is set (`--allow-empty`,
  // the scene file's allow_empty): then the empty package is written.
  bool allow_empty = false;
  // > 0: the output is a tileset of square tiles this many frame metres on a
  // side (prep/tile.hpp; the scene file's [tiling] tile_size); 0: one package.
  double tile_size = 0;
  // Overview levels of a tileset (formats/SPEC.md "Overview levels";
  // --levels, the scene file's [tiling] levels): 0 none, 1..kMaxLevels that
  // many, kLevelsAuto as many as it takes for one level to cover the data
  // with at most kAutoLevelTiles tiles.
  int levels = 0;
  std::string scene_path;  // for messages and provenance
};

// A DEM's rasters for messages: the one path, or "[a, b, ...]" for a mosaic.
inline std::string dem_text(const std::string& dem, const std::vector<std::string>& more) {
  if (more.empty()) return dem;
  std::string s = "[" + dem;
  for (const std::string& p : more) s += ", " + p;
  return s + "]";
}

// Every raster of the scene's DEM, the first first; empty without a DEM.
inline std::vector<std::string> dem_paths(const SceneSpec& scene) {
  if (scene.dem.empty()) return {};
  std::vector<std::string> all{scene.dem};
  all.insert(all.end(), scene.dem_more.begin(), scene.dem_more.end());
  return all;
}

// Where a layer sits in the scene file, for messages: " (scene.toml:12)";
// "" for the file-less form (no file, line 0).
inline std::string layer_place(const SceneSpec& scene, const LayerSpec& layer) {
  if (layer.scene_line <= 0 || scene.scene_path.empty()) return {};
  return " (" + scene.scene_path + ":" + std::to_string(layer.scene_line) + ")";
}

// ------------------------------------------------------------- how to run --

class Progress;  // prep/progress.hpp

struct BuildRequest {
  // Package path, written atomically; for a tileset (scene.tile_size > 0)
  // the directory (created when missing; formats/SPEC.md "Tilesets").
  std::string output;
  std::string report;    // JSON report path; empty: none
  bool dry_run = false;  // stop after clean: write the report, no package
  bool compress = true;
  int zstd_level = 2;  // WriteOptions::zstd_level (prep/write.hpp)
  // --max-memory in bytes (0: none): the build stops with resource_error
  // (exit 6) as soon as an estimate of its peak RSS exceeds it
  // (prep/memory_estimate.hpp); no package is written.
  uint64_t max_memory = 0;
  // --strict: a warning is an error (strict_error, exit 10): a layer that
  // read no feature, dynamic-line heights taken outside the DEM. Without it
  // they are printed on stderr and listed in the report's "warnings".
  bool strict = false;
  // Tilesets: tiles built side by side (0 counts as 1). The bytes do not
  // depend on it.
  unsigned jobs = 1;
  // Progress of every stage, in pipeline order: read, project, clean,
  // build.lines, build.quadtrees, build.grid, build.cells, build.dynamic,
  // write (prep/progress.hpp); for a tileset: read, "prepare" (parts
  // projected, cleaned and written to the work folder), then "tiles"
  // (counted in tiles). Null: silent. Output only.
  Progress* progress = nullptr;
  // Tilesets: run one step of the build only (`--step`), each in a process
  // of its own, possibly on another machine that sees the same output
  // folder (a shared filesystem); the state between steps is the work
  // folder DIR/.work only. prepare: read, project and clean into the work
  // folder, and the plan. tiles: the plan's tiles i with
  // i % step_parts == step_part. finalize: manifest.json, then tileset.json;
  // refuses, naming them, while tiles are missing. Each step run again gives
  // the same bytes; all: the three in one process.
  enum class Step { all, prepare, tiles, finalize };
  Step step = Step::all;
  unsigned step_part = 0, step_parts = 1;
};

}  // namespace prep
