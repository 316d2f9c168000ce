// prep/dash.hpp — dashed lines (scene file `dash`, formats/SPEC.md "Dashed
// lines"): the per-layer patterns a package's layer table records, the
// along-line distance a dash is measured in, and the on/off rule every
// renderer applies (the evaluator, dynamic_cpu.cpp and the shaders in
// formats/gl/shaders/dash.glsl mirror dash_signed_distance).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "prep/model.hpp"

namespace prep {

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

}  // namespace prep
