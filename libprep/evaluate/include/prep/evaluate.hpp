// prep/evaluate.hpp — the CPU evaluator: the same per-pixel query the static
// decal shader runs (thesis Algorithm 3.5, §4.4.1), in C++. Tests use it for
// accuracy against GEOS, the smoke test compares GL output with it, and
// benchmarks read query-cost counters from it.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "decal/format.hpp"
#include "prep/model.hpp"

namespace decal {
class Package;
}

namespace prep {

// ---------------------------------------------------------------- dashes --

// dashed lines (scene file `dash`, formats/SPEC.md "Dashed
// lines"): the per-layer patterns a package's layer table records, the
// along-line distance a dash is measured in, and the on/off rule every
// renderer applies (the evaluator, dynamic_cpu.cpp and the shaders in
// formats/gl/shaders/dash.glsl mirror dash_signed_distance).
// One dash pattern per layer of the package's layer table (index =
// LineProps::layer): [on, off, on, off, ...], all > 0; empty: solid.
// Static lines: ground metres of the frame; dynamic lines: screen pixels.
struct DashTable {
  std::vector<std::vector<double>> layers;
  bool any() const;
  // The layer's pattern; empty (solid) for a layer past the table.
  std::span<const double> of(uint32_t layer) const;
};

// The patterns of the metadata's "layers"[i]["dash"]; a layer without the
// key is solid. Throws format_error naming the layer when a pattern is not
// an even count >= 2 of finite numbers > 0.
DashTable dash_table(std::string_view metadata_json);

// The metadata's "line_dash_start" (a tile's cut dashed lines: each line's
// length before its first stored vertex), empty when absent. Throws
// format_error unless it holds `lines` finite numbers >= 0.
std::vector<double> line_dash_start(std::string_view metadata_json, size_t lines);

// Along-line distance of every static-line vertex: the line's length from
// its first vertex (the first entry of its run in line_vertices, whose
// vertices are consecutive per line) to it, metres, summed in double.
// `line_start` (metadata "line_dash_start", one per line, or empty): the
// whole line's length before a tile's cut, added to its vertices.
std::vector<double> line_vertex_distances(std::span<const ivec2> line_vertices,
                                          std::span<const uint32_t> line_vertex_line,
                                          std::span<const double> line_start = {});

// True when `s` falls in an "on" interval [a, a + on) of the pattern
// repeated from s = 0 (r = s - P floor(s / P), P the period). Empty
// pattern: true (solid).
bool dash_on(std::span<const double> pattern, double s);
// Distance from `s` to the nearest on/off boundary, positive where dash_on,
// negative elsewhere (coverage anti-aliasing along the line); +infinity for
// an empty pattern.
double dash_signed_distance(std::span<const double> pattern, double s);

// The table as the shaders read it (formats/gl/shaders/dash.glsl): u32
// words, [0] = layer count N; layer L: [1 + 3L] = first word of its
// pattern, [2 + 3L] = its length (0: solid), [3 + 3L] = the period's f32
// bits; then the patterns as f32 bits.
std::vector<uint32_t> dash_gpu_words(const DashTable& table);

// What the evaluator needs for dashed static lines: the table and the
// per-vertex distances (empty when no layer is dashed).
struct LineDashes {
  DashTable table;
  std::vector<double> vertex_distance;
};

// ------------------------------------------------------------- evaluator --

// The element type of blob `id`: the one the catalogue gives it
// (decal/format.hpp DECAL_BLOB_CATALOGUE), e.g. what Package::array<id>()
// returns a span of.
template <decal::BlobId id>
using blob_element_t = typename decal::BlobTraits<id>::type;

// X(element type, name) for one blob `name`, its type from the catalogue.
#define PREP_BLOB(X, name) X(::prep::blob_element_t<::decal::BlobId::name>, name)

// The static blobs as X(element type, name) that the model and every
// package version hold alike. Each name is a StaticView member, a
// DecalModel member and a decal::BlobId alike; both view_of overloads fill
// the view from this one list. The per-cell ranges, BVH boxes, cell_polys
// and leaf segments are not in it: the model and v1.3 packages hold the
// compact layout, decoded into them.
// clang-format off
#define PREP_STATIC_VIEW_BLOBS(X)                                                              \
  PREP_BLOB(X, line_vertices) PREP_BLOB(X, line_vertex_line) PREP_BLOB(X, line_props)          \
  PREP_BLOB(X, line_corners) PREP_BLOB(X, cell_segments) PREP_BLOB(X, poly_props)              \
  PREP_BLOB(X, poly_root_node) PREP_BLOB(X, qt_node_box) PREP_BLOB(X, qt_node)                 \
  PREP_BLOB(X, qt_leaf_vertices) PREP_BLOB(X, cell_holes)
// The compact blobs (formats/SPEC.md "Compact layout (v1.3)") the model and
// v1.3 packages hold in place of the v1.2 per-cell ranges, BVH boxes,
// cell_polys and leaf segments, as X(element type, name): DecalModel
// members and decal::BlobIds.
#define PREP_COMPACT_BLOBS(X)                                                                  \
  PREP_BLOB(X, cell_line_first) PREP_BLOB(X, line_bvh_box16) PREP_BLOB(X, cell_poly_first)     \
  PREP_BLOB(X, poly_bvh_box16) PREP_BLOB(X, cell_poly_entries) PREP_BLOB(X, cell_poly_holes)   \
  PREP_BLOB(X, qt_leaf_loop_range) PREP_BLOB(X, qt_leaf_loops)
// clang-format on

// Non-owning view of the static blobs: built from a DecalModel in memory or
// from a decal::Package read from disk, so the same code answers for both.
struct StaticView {
  GridParams grid;
  // The blobs of PREP_STATIC_VIEW_BLOBS (line_vertices ... cell_holes), each
  // a span of its catalogue element type.
#define PREP_STATIC_VIEW_MEMBER(T, name) std::span<const T> name;
  PREP_STATIC_VIEW_BLOBS(PREP_STATIC_VIEW_MEMBER)
#undef PREP_STATIC_VIEW_MEMBER
  // The v1.2 layout: stored by packages before v1.3, decoded from the
  // compact blobs otherwise.
  std::span<const uvec2> cell_segment_range;
  std::span<const uvec2> qt_leaf_range, qt_leaf_segments;
  std::span<const uvec2> cell_poly_range;
  std::span<const uvec4> cell_polys;
  std::span<const uvec4> line_bvh_range, poly_bvh_range;
  std::span<const ivec4> line_bvh_box, poly_bvh_box;
  // Added to PolyProps.order when merging the line and polygon streams: 0
  // for format 1.2 and later (one rank space), the number of lines for older
  // packages (every line over every polygon).
  uint64_t polygon_rank_bias = 0;
  // Arrays the view owns: the compact blobs of the model or a v1.3 package
  // decoded into the ranges, boxes and leaf segments above.
  std::shared_ptr<const void> storage;
  // Dashed lines (prep/evaluate.hpp): the layer table's patterns and the
  // static-line vertices' along-line distances, computed when the package
  // is loaded; null or no dashed layer: every line solid.
  std::shared_ptr<const LineDashes> dashes;
};

StaticView view_of(const DecalModel& model);

// The drawing order (formats/SPEC.md "Drawing order") as runs: maximal
// intervals of consecutive ranks held by one kind, top first. A renderer
// that draws one kind per pass draws the runs in this order, each pass
// restricted to ranks [lo, hi) of its kind (PolyProps.order without
// polygon_rank_bias), compositing front to back; the result equals
// evaluate()'s merge. At most two runs per scene layer.
struct DrawRun {
  enum class Kind : uint8_t { lines, polygons } kind;
  uint32_t lo = 0, hi = 0;  // ranks of that kind, half-open
};
std::vector<DrawRun> draw_runs(const StaticView& view);
// Reads grid parameters from the package metadata; throws format_error when
// they are missing or inconsistent with the blobs.
StaticView view_of(const decal::Package& package);
// The grid a package's metadata states (its "grid" object); throws
// format_error when it is missing or malformed.
GridParams grid_of_metadata(std::string_view metadata);

// Query-cost counters, accumulated per call.
struct EvalCounters {
  uint64_t bvh_nodes = 0;
  uint64_t qt_nodes = 0;
  uint64_t edge_tests = 0;     // leaf-polygon edge crossings tested
  uint64_t segment_tests = 0;  // line point-in-segment tests
};

// Result for one world point: colour composited front to back in drawing
// order (formats/SPEC.md "Drawing order"; early exit at alpha >= 0.999),
// plus what covered it.
struct EvalSample {
  float rgba[4] = {0, 0, 0, 0};  // PREMULTIPLIED, 0..1
  bool polygon_covered = false;  // inside some exterior polygon and no hole of it
  bool line_covered = false;
  int32_t top_polygon = -1;  // topmost covering polygon index
  int32_t top_line = -1;     // topmost covering line index
  // The part of rgba[0..2] from the layers evaluate() was told are unlit
  // (premultiplied; zero without such layers): the renderer lights rgba
  // less this part (formats/SPEC.md "Lit decals").
  float unlit_rgb[3] = {0, 0, 0};
};

// Evaluates the point (x, y), in metres relative to the package origin, with
// the query algorithm documented at the top of libprep/evaluate/evaluate.cpp
// (the GLSL mirrors it). Thread-safe (reads only).
EvalSample evaluate(const StaticView& view, double x, double y, EvalCounters* counters = nullptr);

// Slope widths (formats/SPEC.md "Slope widths"): the terrain gradient
// (dh/dx, dh/dy) under the point and the layers whose static lines are
// measured along it, one flag per layer-table index (LineProps::layer;
// nonzero: along the surface), an index past the end taking the last flag
// ({1}: every layer). Lines of other layers, and every line where the
// gradient is zero, are measured in plan as above.
struct SurfaceSlope {
  double gx = 0, gy = 0;
  std::span<const uint8_t> layers;
};
// evaluate() with the static line widths of the flagged layers measured
// along the plane of gradient `slope` (step 6b of the query block).
EvalSample evaluate(const StaticView& view, double x, double y, const SurfaceSlope& slope,
                    EvalCounters* counters = nullptr);
// What a renderer knows of the pixel beyond its point: the slope above;
// `unlit`, layers whose share is also summed in EvalSample::unlit_rgb (one
// flag per layer-table index, an index past the end taking the last); and
// for minimum widths (formats/SPEC.md "Minimum widths") the ground size of
// the pixel, each layer's min_width_px (the same indexing) and the
// package's pixel limit: a static line of such a layer is drawn with half
// width max(hw, f N min(pixel_m, limit)), f = 1/2 (1 for inset and offset,
// whose stored half width is their visible width), its corner vectors
// scaled alike.
struct EvalPixel {
  SurfaceSlope slope;
  std::span<const uint8_t> unlit;
  double pixel_m = 0;
  std::span<const float> min_width_px;
  double min_width_pixel_m = 0;
  // Metres by which the line BVH's boxes are grown: a min_width_px line is
  // found beyond its stored width's box (prep::render::min_width_reach times
  // min(pixel_m, min_width_pixel_m)).
  double line_box_margin_m = 0;
};
EvalSample evaluate(const StaticView& view, double x, double y, const EvalPixel& pixel,
                    EvalCounters* counters = nullptr);
// The factor (>= 1) by which line `line` is drawn wider at this pixel.
double min_width_scale(const StaticView& view, uint32_t line, const EvalPixel& pixel);

// Coverage queries of single primitives, as evaluate() applies them (for
// tests and tools). `x, y` in metres relative to the origin.
// True when the point is inside polygon `poly` alone (its own quad-tree from
// the root; interior polygons are not subtracted).
bool polygon_ring_covers(const StaticView& view, uint32_t poly, double x, double y);
// True when segment (start vertex, end vertex) of a static line covers the
// point, with the line's corner style and outline mode.
bool segment_covers(const StaticView& view, uint32_t start, uint32_t end, double x, double y);

// Top-down orthographic image: pixel (i, j) has its centre at
// (xmin + (i + 0.5) * (xmax - xmin) / W, ymax - (j + 0.5) * (ymax - ymin) / H),
// as gdal_rasterize -te xmin ymin xmax ymax -ts W H places them. Returns
// W*H*4 floats, straight alpha, row 0 at the top.
// Parallel (oneTBB) over rows. `extent` is in metres relative to the origin.
std::vector<float> render_topdown(const StaticView& view, const Extent& extent, uint32_t width,
                                  uint32_t height);

// Writes an 8-bit RGBA PNG (libpng), rows top to bottom, straight alpha,
// whole or not at all (prep/files.hpp write_file_atomically: only over a
// regular file or nothing). Throws output_error naming the path on failure.
void write_png_rgba(const std::string& path, uint32_t width, uint32_t height,
                    std::span<const uint8_t> rgba8);

// Converts render_topdown() output to 8-bit (rounded, clamped).
std::vector<uint8_t> to_rgba8(std::span<const float> rgba);

// Writes `<png without extension>.pgw` (ESRI world file: pixel size, zero
// rotation, negative row size, centre of the top-left pixel) and
// `<png>.aux.xml` (GDAL PAM with the CRS WKT), so GDAL and QGIS place the
// image. `extent` is in the CRS's own (absolute) coordinates, i.e. scene
// extent + frame origin. Throws output_error on failure.
void write_world_file(const std::string& png_path, const Extent& extent, uint32_t width,
                      uint32_t height, const std::string& crs_wkt);
// The two files write_world_file writes for `png_path`: the .pgw, then the
// .aux.xml (so a caller can check them before it draws).
std::vector<std::string> world_file_paths(const std::string& png_path);

}  // namespace prep
