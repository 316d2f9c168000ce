// prep/scene.hpp — what a build is asked to do (SceneSpec) and the data that
// flows through the first three stages:
//
//   sources --read--> FeatureSet --project--> --clean--> SceneFeatures
//
// No GDAL, GEOS or CGAL types appear here; stages keep those in their .cpp
// files. Coordinates are double precision throughout these stages.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "decal/format.hpp"
#include "prep/manifest_words.hpp"

namespace prep {

class Progress;  // prep/progress.hpp

// ----------------------------------------------------------------- the ask --

enum class DecalKind { polygon, line, outline };

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
  // Dash pattern (scene file `dash`): [on, off, on, off, ...], lengths > 0
  // along the line from its start, ground metres (static) or pixels
  // (dynamic); empty: solid. A casing copy is solid.
  std::vector<double> dash;
};

struct Extent {
  double xmin = 0, ymin = 0, xmax = 0, ymax = 0;
  bool empty() const { return !(xmax > xmin && ymax > ymin); }
};

// Stage 4 (model) knobs (thesis defaults noted).
// What the decal grid the build chose will cost (ModelOptions::on_grid).
struct GridFootprint {
  uint64_t cells = 0;
  // Bytes of the per-cell lists and BVHs in the v1.2 layout, as the grid
  // chooser counts them (an upper bound on the v1.3 arrays the model holds).
  double cell_bytes = 0;
  // Bytes of the static blobs made before the grid (lines, quad-trees).
  double geometry_bytes = 0;
};

struct ModelOptions {
  uint32_t grid_nx = 0, grid_ny = 0;  // 0: adaptive (default); 500x500 = thesis
  uint32_t target_per_cell = 0;       // adaptive grid: stop refining at this proxy (0: off)
  uint32_t max_cells = 4'000'000;     // grid cell budget
  // Adaptive grid: no cell side below this many metres (0: no floor). A
  // tileset's overview level sets twice its resolution (formats/SPEC.md
  // "Overview levels"); not from the scene file.
  double min_cell_m = 0.0;
  uint32_t qt_leaf_capacity = 8;  // thesis default
  uint32_t qt_max_depth = 8;      // thesis default
  double miter_limit_deg = 40.0;  // below this angle, miter falls back to round
  // dynamic lines / terrain
  double lmax = 0.0;               // 0: half the DEM cell size
  double terrain_tolerance = 0.0;  // >0: adaptive subdivision, metres
  double z_scale = 1.0;
  std::optional<double> nodata_fill;  // raw DEM units; none: nearest valid cell (prep/dem.hpp)
  std::string dem_assume_crs;         // CRS of a DEM that has none (the scene's assume_crs)
  unsigned threads = 0;               // 0: all hardware threads
  // Not from the scene file: where the build stage reports its sub-stages
  // (build.lines, build.quadtrees, build.grid, build.cells, build.dynamic;
  // prep/progress.hpp). Null: silent. Output only.
  Progress* progress = nullptr;
  // Not from the scene file: called once the decal grid is chosen, before
  // the per-cell lists are made (`--max-memory`'s check after the grid,
  // prep/memory_estimate.hpp); it may throw to stop the build. Empty: none.
  std::function<void(const GridFootprint&)> on_grid;
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
  bool skip_failures = false;
  // A build that keeps no feature from any layer is an error (empty_error,
  // exit 9) and writes no package, unless this is set (`--allow-empty`,
  // the scene file's allow_empty): then the empty package is written.
  bool allow_empty = false;
  ModelOptions model;  // stage 4 knobs (the scene file's [build] table)
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

// ---------------------------------------------------------------- manifest --

// One line of the manifest: what happened to one input feature (or part).
struct ManifestEntry {
  std::string layer;
  int64_t fid = -1;
  int part = -1;  // -1: the whole feature
  ManifestAction action = ManifestAction::dropped;
  std::string reason;  // human-readable: what was wrong / what was done
  double area_before = std::numeric_limits<double>::quiet_NaN();
  double area_after = std::numeric_limits<double>::quiet_NaN();
  // Set for a feature dropped for a per-feature failure (feature_failure.hpp):
  // the stage it failed in; `reason` is then the bare "<what>", and the JSON
  // reason reads "failed in <stage>: <what>" (manifest_words.hpp).
  std::optional<FailureStage> failed_in;
};

// Per-layer accounting. Invariant: read == kept + clipped_away + dropped.
struct LayerCounts {
  std::string layer;
  uint64_t read = 0;          // features read from the source
  uint64_t kept = 0;          // features with at least one part in the package
  uint64_t repaired = 0;      // of kept: changed by a repair
  uint64_t clipped_away = 0;  // entirely outside the extent
  uint64_t dropped = 0;       // unusable; one entry each, with a reason
  uint64_t parts = 0;         // parts after splitting multi-geometries
  uint64_t vertices_in = 0;   // before simplification
  uint64_t vertices_out = 0;  // after simplification
  // Overview levels only (prep/tileset.hpp TileLevel::layers): parts left
  // out of the level for being below its min_area / min_length (or
  // collapsing under its simplification). Never written elsewhere.
  uint64_t dropped_small = 0;

  // Adds every count of `o` (not the layer name).
  LayerCounts& operator+=(const LayerCounts& o) {
    for (uint64_t LayerCounts::*m :
         {&LayerCounts::read, &LayerCounts::kept, &LayerCounts::repaired,
          &LayerCounts::clipped_away, &LayerCounts::dropped, &LayerCounts::parts,
          &LayerCounts::vertices_in, &LayerCounts::vertices_out, &LayerCounts::dropped_small})
      this->*m += o.*m;
    return *this;
  }
};

struct Manifest {
  std::vector<LayerCounts> layers;
  std::vector<ManifestEntry> entries;
  std::vector<std::string> notes;  // scene-wide facts ("Z values dropped", "flat terrain")
};

// ------------------------------------------------------------- geometries --

struct Point2 {
  double x = 0, y = 0;
};
using Ring = std::vector<Point2>;  // not closed: first point is not repeated

// A box that holds no point yet (minima +inf, maxima -inf); extend() grows
// a box to take in points.
inline Extent no_points() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return {inf, inf, -inf, -inf};
}
inline void extend(Extent& b, const Point2& p) {
  b.xmin = std::min(b.xmin, p.x);
  b.ymin = std::min(b.ymin, p.y);
  b.xmax = std::max(b.xmax, p.x);
  b.ymax = std::max(b.ymax, p.y);
}
inline void extend(Extent& b, const Ring& r) {
  for (const Point2& p : r) extend(b, p);
}

// What a part carries from its source feature into the package: the
// feature id, the part index after splitting multi-geometries, and the
// attribute values for the drawing order and the colour (NaN when none).
struct FeatureKeys {
  int64_t fid = -1;
  int part = 0;
  double order_value = std::numeric_limits<double>::quiet_NaN();
  double color_value = std::numeric_limits<double>::quiet_NaN();
};

// Output of `read`: geometry in the source CRS, multi-geometries split.
struct SourceFeature : FeatureKeys {
  uint64_t feature = 0;                   // index of the input feature in its layer (read order)
  std::string repairs;                    // what read/project already fixed ("closed an open ring")
  std::string drop_reason;                // non-empty: unusable; clean records it as dropped
  std::optional<FailureStage> failed_in;  // set: drop_reason is a per-feature failure
  bool is_polygon = false;
  std::vector<Ring> rings;  // polygon: [0] shell, then holes; line: [0]
};

struct SourceLayer {
  LayerSpec spec;
  std::string srs_wkt;  // empty when the source has none
  std::vector<SourceFeature> features;
};

struct FeatureSet {
  std::vector<SourceLayer> layers;
  Manifest manifest;
};

// The local scene frame. Scene coordinates are metres relative to `origin`,
// expressed in `crs_wkt` (a projected CRS).
struct SceneFrame {
  std::string crs_wkt;
  std::string description;            // e.g. "local TM lon0=7.42 lat0=43.73"
  double origin_x = 0, origin_y = 0;  // in the frame CRS
  // Local TM frames only (else NaN): the central meridian and the latitude of
  // origin, degrees, WGS84 ellipsoid, scale 1 on the central meridian.
  double tm_lon0 = std::numeric_limits<double>::quiet_NaN();
  double tm_lat0 = std::numeric_limits<double>::quiet_NaN();
};

// Output of `clean`: valid, oriented (shell CCW, holes CW), clipped and
// simplified; coordinates in metres relative to frame.origin.
struct ScenePolygon : FeatureKeys {
  Ring shell;
  std::vector<Ring> holes;
  uint32_t layer = 0;  // index into SceneFeatures::layers
  double area = 0;     // m², for drawing order
};

struct SceneLine : FeatureKeys {
  Ring points;
  bool closed = false;  // polygon ring used as an outline
  uint32_t layer = 0;
  double length = 0;  // ground metres (geodesic), for drawing order
  double width = 0;   // ground metres (static) corrected by the frame scale; pixels (dynamic)
  // A dashed static line cut by a tile: the whole line's length up to
  // points[0], summed over its vertices quantised as a package quantises
  // them (formats/SPEC.md "Dashed lines"); 0 otherwise.
  double dash_start = 0;
};

struct SceneFeatures {
  SceneFrame frame;
  Extent extent;  // scene coordinates (relative to origin)
  std::vector<LayerSpec> layers;
  std::vector<ScenePolygon> polygons;
  std::vector<SceneLine> lines;          // static lines and outlines
  std::vector<SceneLine> dynamic_lines;  // terrain-matched, width in pixels
  Manifest manifest;
};

}  // namespace prep
