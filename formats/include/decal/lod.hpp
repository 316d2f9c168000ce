// decal/lod.hpp — the runtime side of a package's LOD segments: which
// points and segments a camera shows (the visibility rule of formats/SPEC.md
// "LOD segments"), and how a renderer maps the visible segments onto the
// package's terrain-matched dynamic lines. Beside the reader, so that every
// renderer (the GL renderer, the CPU evaluator of dynamic lines, a viewer)
// uses the one rule; the build side (the BLG trees and the segment set) is
// libprep/model/lod.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "decal/format.hpp"

namespace decal {

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
double lod_distance(const LodPoint& p, const LodCamera& camera);

// True iff the point is included for this camera and threshold (format.hpp
// rule). Thread-safe.
bool lod_point_included(const LodPoint& p, const LodCamera& camera, const LodThreshold& eps);

// Indices (into `segments`) of the visible segments, in increasing order.
// Thread-safe (reads only).
std::vector<uint32_t> visible_segments(std::span<const LodPoint> points,
                                       std::span<const LodSegment> segments,
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

LodDrawMap lod_draw_map(std::span<const LodPoint> points, std::span<const LodSegment> segments,
                        std::span<const std::array<uint32_t, 2>> line_range,
                        std::span<const std::array<int32_t, 4>> dyn_vertices,
                        std::span<const uint32_t> dyn_line_start,
                        std::span<const std::array<int32_t, 2>> dyn_prev_next);

}  // namespace decal
