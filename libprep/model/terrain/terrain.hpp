// terrain/terrain.hpp — terrain matching of dynamic lines (thesis §3.2.2,
// §4.2.2): the subdivision of dynamic lines into 3D vertices on the DEM
// surface of prep/dem.hpp (the one the renderer draws), fixed (lmax) or
// adaptive (--terrain-tolerance).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "prep/dem.hpp"
#include "prep/features.hpp"
#include "prep/model.hpp"

namespace prep {

struct MatchOptions {
  double lmax = 0;       // maximum horizontal piece length, metres (>= 0.01;
                         // infinity: no subdivision)
  double tolerance = 0;  // > 0: adaptive subdivision with this bound, metres
};

// Terrain-matched dynamic lines, ready for the dyn_* blobs.
struct MatchedLines {
  std::vector<ivec4> vertices;       // (x, y, z quanta, line index)
  std::vector<ivec2> prev_next;      // -1 at open ends; closed lines wrap
  std::vector<uint32_t> line_start;  // first vertex per line
  uint64_t vertices_in = 0;          // input vertices
  uint64_t vertices_fixed = 0;       // after subdivision to lmax
  uint64_t vertices_out = 0;         // stored (== vertices_fixed unless adaptive)
  double max_piece_length = 0;       // longest stored piece, horizontal metres
  double max_deviation = 0;          // max |3D piece - DEM surface| along stored pieces, metres
  uint64_t tolerance_misses = 0;     // adaptive pieces that reached 1 cm and still miss the bound
  uint64_t lines_outside = 0;  // lines with a vertex outside the DEM (terrain.samples_outside)
  TerrainStats terrain;
};

// Matches `lines` (scene coordinates, width ignored) to the terrain:
// thesis Algorithm 3.1 with the output offsets from a parallel prefix sum,
// then one bilinear height per vertex, sampled at the stored (quantised)
// position. Pieces are at most lmax long horizontally after quantisation.
// With options.tolerance > 0 only vertices needed to keep every straight
// 3D piece within the tolerance of the DEM surface are kept (original
// vertices always stay); the bound is checked exactly on the piecewise
// quadratic restriction of the bilinear surface, with 5 mm held back for
// quantisation. `dem` null: flat terrain, z = 0. Lines need >= 2 points
// (closed: >= 3); throws input_error otherwise. Deterministic at any thread
// count.
MatchedLines match_terrain(const std::vector<SceneLine>& lines, DemSampler* dem,
                           const MatchOptions& options);

// A point of a piece's path in DEM pixel space: parameter s in [0, 1]
// along the piece and its pixel position.
struct PixelPathPoint {
  double s = 0;
  Point2 pixel;
};

// Maximum |z(s) - h(s)| along a straight 3D piece with heights za at s = 0
// and zb at s = 1, h the DEM's bilinear surface along `path` (pixel
// positions at increasing s, first s = 0, last s = 1, linear between
// them). Each path part is cut where it crosses a line through cell
// centres and each quadratic part is maximised exactly. Returns the
// maximum and, in *arg, the s where it occurs. Thread-safe after load().
double piece_deviation(const DemSampler& dem, std::span<const PixelPathPoint> path, double za,
                       double zb, double* arg = nullptr);

}  // namespace prep
