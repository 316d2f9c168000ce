// lod/lod.hpp — LOCALIS view-dependent LOD segments (seed 001 §3.1-3.5):
// a Douglas-Peucker BLG-tree per line, the exhaustive attributed segment
// set, saturated errors/distances, intersection-avoiding dependees with
// cycles merged into proxy points, and the CPU side of the visibility test.
//
// The stored layout and the exact visibility rule are documented beside
// decal::LodPoint / decal::LodSegment in decal/format.hpp.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "decal/format.hpp"
#include "prep/model.hpp"

namespace prep {

// How a BLG node's own error e0 is derived from its DP distance e.
enum class LodErrorRule {
  // e0 = min(e, e0(parent)): non-increasing down the tree, so a constant
  // threshold selects exactly the Douglas-Peucker result (default).
  dp_exact,
  // e0 = e; the saturation then raises a node to its subtree maximum
  // (LOCALIS §3.3 as printed): never coarser than DP, sometimes finer.
  subtree_max,
};

struct LodOptions {
  bool dependees = true;  // §3.4 intersection-avoiding dependees
  LodErrorRule error_rule = LodErrorRule::dp_exact;
};

// One input line: vertices in quanta relative to the package origin, no
// consecutive duplicates. A closed ring lists each vertex once (the builder
// repeats the first point at the end). `line` is copied to LodPoint::line.
struct LodInputLine {
  std::vector<ivec2> points;
  bool closed = false;
  uint32_t line = 0;
};

struct LodStats {
  uint64_t lines = 0;
  uint64_t original_segments = 0;    // sum of (points - 1), closing segment included
  uint64_t attributed_segments = 0;  // 2n - 1 per line of n segments
  uint64_t dependee_edges = 0;       // (point, dependee) pairs found
  uint64_t cycles = 0;               // strongly connected components of > 1 point
  uint64_t points_in_cycles = 0;
  uint64_t always_points = 0;  // points that are always included
};

// The package blobs of a LOD set.
struct LodSet {
  std::vector<decal::LodPoint> points;
  std::vector<decal::LodSegment> segments;  // per line sorted by (a, b)
  std::vector<uvec2> line_range;            // per input line: (first, count) into segments
  std::vector<uvec2> line_points;           // per input line: (first, count) into points
  LodStats stats;
};

// Builds the LOD set of `lines` (thesis-independent: LOCALIS §3.1-3.5).
// Dependees are searched among the points of all `lines`. Deterministic and
// independent of the thread count. Throws input_error for a line with fewer
// than 2 points (or a closed ring with fewer than 3).
LodSet build_lod(const std::vector<LodInputLine>& lines, const LodOptions& options = {});

// Camera position in scene metres relative to the package origin.
struct LodCamera {
  double x = 0, y = 0, z = 0;
};

// Screen-space error threshold eps(d) in metres as a function of the camera
// distance d (metres). Must be non-decreasing in d (also for d < 0).
using LodThreshold = std::function<double(double)>;

// eps(d) = base + slope * max(d, 0): a simple non-decreasing threshold.
struct LinearThreshold {
  double base = 0, slope = 0;
  double operator()(double d) const { return base + slope * (d > 0 ? d : 0.0); }
};

// Camera distance d of a point as the format defines it (format.hpp).
double lod_distance(const decal::LodPoint& p, const LodCamera& camera);

// True iff the point is included for this camera and threshold (format.hpp
// rule). Thread-safe.
bool lod_point_included(const decal::LodPoint& p, const LodCamera& camera, const LodThreshold& eps);

// Indices (into `segments`) of the visible segments, in increasing order.
// Thread-safe (reads only).
std::vector<uint32_t> visible_segments(std::span<const decal::LodPoint> points,
                                       std::span<const decal::LodSegment> segments,
                                       const LodCamera& camera, const LodThreshold& eps);

// How the renderers draw the visible segments of a package's LOD set on its
// terrain-matched dynamic lines (formats/SPEC.md "Choosing the threshold"):
// a LodPoint has no height, so each point is drawn at the vertex of its
// dynamic line (dyn_vertices) at its position, found once when a package is
// loaded: the line's vertices are walked in order and each point takes the
// first vertex at or after the previous point's with its x and y (terrain
// matching keeps every input vertex and only inserts pieces between them;
// a closed ring's repeated last point takes the line's first vertex). A LOD
// line whose points do not all map, or whose dynamic line another LOD line
// also names, is drawn from its full vertex chain instead.
struct LodDrawMap {
  // Per LOD point: its dyn_vertices index; kLodNone when its line is not
  // drawn from LOD segments.
  std::vector<uint32_t> vertex;
  // Per LOD point: kLodNone for an interior point; the point itself at an
  // open line's first or last point (no neighbour); the other end at a
  // closed ring's first or last point (the ring wraps there).
  std::vector<uint32_t> end;
  std::vector<uint8_t> line_drawn;  // per dynamic line: 1 when drawn from its LOD segments
  uint64_t lines = 0;               // LOD lines drawn from their segments
  uint64_t original_segments = 0;   // their full-detail segments (points - 1 each)
};

LodDrawMap lod_draw_map(std::span<const decal::LodPoint> points,
                        std::span<const decal::LodSegment> segments,
                        std::span<const uvec2> line_range,
                        std::span<const std::array<int32_t, 4>> dyn_vertices,
                        std::span<const uint32_t> dyn_line_start,
                        std::span<const std::array<int32_t, 2>> dyn_prev_next);

}  // namespace prep
