// lod/lod.hpp — LOCALIS view-dependent LOD segments (seed 001 §3.1-3.5):
// a Douglas-Peucker BLG-tree per line, the exhaustive attributed segment
// set, saturated errors/distances, intersection-avoiding dependees with
// cycles merged into proxy points. The visibility test a renderer runs on
// them is decal/lod.hpp, beside the package reader.
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
#include "decal/lod.hpp"
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

}  // namespace prep
