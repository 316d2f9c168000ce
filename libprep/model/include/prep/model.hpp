// prep/model.hpp — stage 4, model: SceneFeatures -> DecalModel (thesis ch. 4.2).
// DecalModel is the input of the write stage: one typed array per package
// blob (formats/SPEC.md §Blob catalogue), plus the grid parameters and build
// statistics.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "decal/format.hpp"
#include "prep/features.hpp"

namespace prep {

class Progress;  // prep/progress.hpp

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
  // Minimum widths (LayerSpec::min_width_px; formats/SPEC.md "Minimum
  // widths"): the resolution the package is made for (the scene's; an
  // overview level's), the side of the square it covers (a tile's; 0: the
  // longer side of the scene extent) and, where no coarser package stands
  // in for it (a single package, a tileset's coarsest level), the longer
  // side of the whole extent (-1: that of the scene extent; 0: none). Not
  // from the scene file.
  double min_width_resolution = 0.0;
  double min_width_side = 0.0;
  double min_width_whole = -1.0;
  uint32_t qt_leaf_capacity = 8;  // thesis default
  uint32_t qt_max_depth = 8;      // thesis default
  double miter_limit_deg = 40.0;  // below this angle, miter falls back to round
  // dynamic lines / terrain
  double lmax = 0.0;               // 0: half the DEM cell size
  double terrain_tolerance = 0.0;  // >0: adaptive subdivision, metres
  double z_scale = 1.0;
  std::optional<double> nodata_fill;  // raw DEM units; none: nearest valid cell (prep/dem.hpp)
  std::string dem_assume_crs;         // CRS of a DEM that has none (the scene's assume_crs)
  // Rasters mosaicked with build_model's `dem` (the scene's dem_more;
  // prep/dem.hpp DemSpec::more_paths).
  std::vector<std::string> dem_more;
  unsigned threads = 0;  // 0: all hardware threads
  // Not from the scene file: where the build stage reports its sub-stages
  // (build.lines, build.quadtrees, build.grid, build.cells, build.dynamic;
  // prep/progress.hpp). Null: silent. Output only.
  Progress* progress = nullptr;
  // Not from the scene file: called once the decal grid is chosen, before
  // the per-cell lists are made (`--max-memory`'s check after the grid,
  // prep/memory_estimate.hpp); it may throw to stop the build. Empty: none.
  std::function<void(const GridFootprint&)> on_grid;
};

// What a whole build is asked: the scene (read, project and clean take the
// SceneSpec part) and the model stage's knobs (the scene file's [build]
// table, the build options of the command line). The scene file and the
// command line make one (prep/pipeline.hpp scene_spec, load_scene_file).
struct BuildSpec : SceneSpec {
  ModelOptions model;
};

using ivec2 = std::array<int32_t, 2>;
using uvec2 = std::array<uint32_t, 2>;
using ivec4 = std::array<int32_t, 4>;
using uvec4 = std::array<uint32_t, 4>;

// The decal grid (thesis §4.2.1, Eq. 4.3/4.4), in quanta relative to origin.
// Cell (ix, iy) covers [origin_x + ix*cell_w, origin_x + (ix+1)*cell_w) x
// [origin_y + iy*cell_h, ...); its index is ix + nx*iy. A point whose
// floor((p - origin) / cell) falls outside [0,nx) x [0,ny) is covered by no
// static decal. nx = ny = 0 when the package has no static decals.
struct GridParams {
  int64_t origin_x = 0, origin_y = 0;  // lower-left corner, quanta
  int64_t cell_w = 1, cell_h = 1;      // cell size, quanta
  uint32_t nx = 0, ny = 0;
};

// What the build stage made, for the manifest, `info` and benchmarks.
struct BuildStats {
  uint64_t line_segments = 0;      // static segments (closed rings wrap)
  uint64_t line_cell_entries = 0;  // (cell, segment) pairs
  uint64_t quadtrees = 0;          // exterior + interior polygons
  uint64_t qt_nodes = 0;
  uint64_t qt_partial_leaves = 0;
  uint64_t qt_depth_capped = 0;  // leaves stopped by max depth above leaf capacity
  uint32_t qt_max_leaf_segments = 0;
  uint64_t poly_cell_entries = 0;  // (cell, exterior polygon) pairs
  uint64_t hole_cell_entries = 0;  // (cell, interior polygon) pairs
};

// The largest pixel (metres) for which a package keeps its min_width_px
// lines that many pixels wide: max(2 r, side / 512, whole / 256)
// (formats/SPEC.md "Minimum widths"); its segments are registered in the
// cells that band reaches.
double min_width_pixel_limit(double resolution, double side, double whole);

struct DecalModel {
  SceneFrame frame;
  Extent extent;  // scene metres
  GridParams grid;
  // min_width_pixel_limit of this package (metadata min_width_pixel_m); 0
  // when no layer has min_width_px.
  double min_width_pixel_m = 0;

  // static lines
  std::vector<ivec2> line_vertices;
  std::vector<uint32_t> line_vertex_line;
  std::vector<decal::LineProps> line_props;
  // Per line: SceneLine::dash_start (metadata "line_dash_start" of a tile
  // whose dashed lines are cut; formats/SPEC.md "Dashed lines").
  std::vector<double> line_dash_start;
  std::vector<decal::LineCorner> line_corners;
  // The per-cell lists and BVHs are in the v1.3 layout (formats/SPEC.md
  // "Compact layout (v1.3)"; decal/layout.hpp): per cell plus one, (first
  // list entry, first BVH node), empty when no cell holds an entry of the
  // kind; per node a cell-relative u16 box.
  std::vector<uvec2> cell_line_first;
  std::vector<uvec2> cell_segments;
  std::vector<uvec2> line_bvh_box16;
  // static polygons
  std::vector<decal::PolyProps> poly_props;
  std::vector<uint32_t> poly_root_node;
  std::vector<ivec4> qt_node_box;
  std::vector<ivec2> qt_node;
  // Leaf polygons as loops (decal/layout.hpp, v1.3): per partial leaf
  // (first, count) into qt_leaf_loops; per loop one past its last vertex in
  // qt_leaf_vertices (loop l: [end[l-1], end[l]), edges v -> v + 1 and the
  // last back to the first).
  std::vector<uvec2> qt_leaf_loop_range;
  std::vector<uint32_t> qt_leaf_loops;
  std::vector<ivec2> qt_leaf_vertices;
  std::vector<uvec2> cell_poly_first;
  std::vector<uvec2> cell_poly_entries;   // per (cell, exterior): (polygon, culling node)
  std::vector<uint32_t> cell_poly_holes;  // per entry plus one: its first in cell_holes
  std::vector<uvec2> cell_holes;          // per (cell, hole): (polygon, culling node)
  std::vector<uvec2> poly_bvh_box16;
  // dynamic lines
  std::vector<ivec4> dyn_vertices;
  std::vector<ivec2> dyn_prev_next;
  std::vector<uint32_t> dyn_line_start;
  std::vector<decal::LineProps> dyn_line_props;
  double terrain_min = 0, terrain_max = 0;  // metres
  // Of them: vertices whose height came from beyond the DEM (its edge
  // cells), and the lines holding at least one such vertex.
  uint64_t dyn_vertices_outside_dem = 0, dyn_lines_outside_dem = 0;
  // LOD
  std::vector<decal::LodPoint> lod_points;
  std::vector<decal::LodSegment> lod_segments;
  std::vector<uvec2> lod_line_range;

  // Largest Euclidean distance, in metres, between an input vertex and its
  // stored int32 quantum position (<= sqrt(2)/2 mm by construction).
  double max_representation_error = 0;
  BuildStats stats;
  Manifest manifest;  // carried from SceneFeatures, plus build notes
};

// Calls fn(id, array) for every blob array of the model, in the package's
// table order: the one list of them, used by the writer (model_blobs,
// take_model_blobs) and the renderer (render::source_of). Not
// manifest_entries, which write_model adds, nor the superseded ids. `M` is
// DecalModel or const DecalModel.
template <class M, class Fn>
void for_each_model_array(M& m, Fn&& fn) {
  using decal::BlobId;
  static_assert(std::size(decal::kBlobCatalogue) == 36 && std::size(decal::kSupersededBlobs) == 9,
                "for_each_model_array must list every model blob");
  fn(BlobId::line_vertices, m.line_vertices);
  fn(BlobId::line_vertex_line, m.line_vertex_line);
  fn(BlobId::line_props, m.line_props);
  fn(BlobId::line_corners, m.line_corners);
  fn(BlobId::cell_segments, m.cell_segments);
  fn(BlobId::cell_line_first, m.cell_line_first);
  fn(BlobId::poly_props, m.poly_props);
  fn(BlobId::poly_root_node, m.poly_root_node);
  fn(BlobId::qt_node_box, m.qt_node_box);
  fn(BlobId::qt_node, m.qt_node);
  fn(BlobId::qt_leaf_vertices, m.qt_leaf_vertices);
  fn(BlobId::cell_holes, m.cell_holes);
  fn(BlobId::qt_leaf_loop_range, m.qt_leaf_loop_range);
  fn(BlobId::qt_leaf_loops, m.qt_leaf_loops);
  fn(BlobId::cell_poly_first, m.cell_poly_first);
  fn(BlobId::line_bvh_box16, m.line_bvh_box16);
  fn(BlobId::poly_bvh_box16, m.poly_bvh_box16);
  fn(BlobId::cell_poly_entries, m.cell_poly_entries);
  fn(BlobId::cell_poly_holes, m.cell_poly_holes);
  fn(BlobId::dyn_vertices, m.dyn_vertices);
  fn(BlobId::dyn_prev_next, m.dyn_prev_next);
  fn(BlobId::dyn_line_start, m.dyn_line_start);
  fn(BlobId::dyn_line_props, m.dyn_line_props);
  fn(BlobId::lod_points, m.lod_points);
  fn(BlobId::lod_segments, m.lod_segments);
  fn(BlobId::lod_line_range, m.lod_line_range);
}

// Builds every static structure (grid, line segments with corner data,
// polygon quad-trees, per-cell BVHs) and, through build_dynamic(), the
// terrain-matched dynamic lines and LOD segments. Parallel with oneTBB; the
// result is byte-identical at any thread count. Throws resource_error when a
// budget is exceeded. `dem` is the DEM path ("" for flat terrain).
DecalModel build_model(const SceneFeatures& scene, const ModelOptions& options,
                       const std::string& dem = "");

// Fills the dyn_* and lod_* arrays of `model` from scene.dynamic_lines and
// LOD-enabled layers (libprep/model/terrain, libprep/model/lod). Appends
// notes and counts to model.manifest.
void build_dynamic(const SceneFeatures& scene, const ModelOptions& options, const std::string& dem,
                   DecalModel& model);

// ---------------------------------------------------------- colour ramps --

// a feature's colour from its attribute value through
// a layer's colour ramp (thesis §4.2.1: the value stored per feature, mapped
// through a transfer function). One formula for the build, which bakes the
// colour into LineProps/PolyProps.rgba, and for render --ramp, which maps the
// stored value again when drawing.
// `value` through `ramp` (stops sorted by increasing value): linear per
// channel (R, G, B, A) between the two stops around it, rounded to the
// nearest integer, clamped to the first and last stop's colour outside them.
// `fallback` when the ramp is empty or the value is not finite (no value).
// The value is taken at float precision, as LineProps/PolyProps store it, so
// the build and a draw-time ramp give the same colour for the same stops.
inline uint32_t ramp_rgba(const std::vector<ColorStop>& ramp, double value, uint32_t fallback) {
  const double v = double(float(value));
  if (ramp.empty() || !std::isfinite(v)) return fallback;
  if (v <= ramp.front().value) return ramp.front().rgba;
  if (v >= ramp.back().value) return ramp.back().rgba;
  size_t k = 1;
  while (ramp[k].value < v) ++k;  // ramp.back().value > v ends the search
  const ColorStop& a = ramp[k - 1];
  const ColorStop& b = ramp[k];
  const double t = (v - a.value) / (b.value - a.value);
  uint32_t out = 0;
  for (int c = 0; c < 4; ++c) {
    const double ca = double((a.rgba >> (8 * c)) & 0xffu), cb = double((b.rgba >> (8 * c)) & 0xffu);
    out |= uint32_t(std::clamp(std::lround(ca + t * (cb - ca)), 0L, 255L)) << (8 * c);
  }
  return out;
}

// A layer's colour for one feature: its constant colour, or the feature's
// value through the ramp when the layer is coloured by an attribute.
inline uint32_t resolve_color(const LayerColor& color, double value) {
  return color.attribute.empty() ? color.rgba : ramp_rgba(color.ramp, value, color.rgba);
}

// The `feature` field of LineProps and PolyProps (formats/SPEC.md): the
// source feature id when it fits in [0, 0xfffffffe], else 0xffffffff (no
// id, or one a u32 cannot hold: never a truncated id that names another
// feature).
inline uint32_t stored_feature_id(int64_t fid) {
  return fid >= 0 && fid <= int64_t{0xfffffffe} ? static_cast<uint32_t>(fid) : 0xffffffffu;
}

}  // namespace prep
