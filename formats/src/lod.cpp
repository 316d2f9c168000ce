// The runtime LOD rule (decal/lod.hpp).
#include "decal/lod.hpp"

#include <algorithm>
#include <cmath>

namespace decal {

double lod_distance(const LodPoint& p, const LodCamera& camera) {
  const double dx = p.eval_x * kQuantumMetres - camera.x;
  const double dy = p.eval_y * kQuantumMetres - camera.y;
  return std::sqrt(dx * dx + dy * dy + camera.z * camera.z);
}

bool lod_point_included(const LodPoint& p, const LodCamera& camera, const LodThreshold& eps) {
  if (p.flags & kLodPointAlways) return true;
  return double(p.e_star) > eps(lod_distance(p, camera) - double(p.d_star));
}

std::vector<uint32_t> visible_segments(std::span<const LodPoint> points,
                                       std::span<const LodSegment> segments,
                                       const LodCamera& camera, const LodThreshold& eps) {
  std::vector<char> included(points.size());
  for (size_t i = 0; i < points.size(); ++i)
    included[i] = lod_point_included(points[i], camera, eps);
  std::vector<uint32_t> out;
  for (size_t s = 0; s < segments.size(); ++s) {
    const auto& seg = segments[s];
    // Eq. (2)/(4): generated and not split.
    const bool generated = seg.generator == kLodNone || included[seg.generator];
    const bool split = seg.splitter != kLodNone && included[seg.splitter];
    if (generated && !split) out.push_back(static_cast<uint32_t>(s));
  }
  return out;
}

LodDrawMap lod_draw_map(std::span<const LodPoint> points, std::span<const LodSegment> segments,
                        std::span<const std::array<uint32_t, 2>> line_range,
                        std::span<const std::array<int32_t, 4>> dyn_vertices,
                        std::span<const uint32_t> dyn_line_start,
                        std::span<const std::array<int32_t, 2>> dyn_prev_next) {
  constexpr uint32_t kNone = kLodNone;
  LodDrawMap m;
  m.vertex.assign(points.size(), kNone);
  m.end.assign(points.size(), kNone);
  m.line_drawn.assign(dyn_line_start.size(), 0);
  const size_t nv = dyn_vertices.size();
  if (nv == 0 || dyn_prev_next.size() != nv) return m;
  // Per LOD line: its points [first, last] and the dynamic line they name.
  struct Line {
    uint32_t first, last, dyn;
  };
  std::vector<Line> lines;
  std::vector<uint32_t> claims(dyn_line_start.size(), 0);
  for (const std::array<uint32_t, 2>& r : line_range) {
    if (r[1] == 0 || uint64_t(r[0]) + r[1] > segments.size()) continue;
    uint32_t first = kNone, last = 0;
    for (uint32_t s = r[0]; s < r[0] + r[1]; ++s) {
      first = std::min({first, segments[s].a, segments[s].b});
      last = std::max({last, segments[s].a, segments[s].b});
    }
    if (last >= points.size() || first >= last) continue;
    const uint32_t dyn = points[first].line;
    bool same = dyn < dyn_line_start.size();
    for (uint32_t p = first; same && p <= last; ++p) same = points[p].line == dyn;
    if (!same) continue;
    ++claims[dyn];
    lines.push_back({first, last, dyn});
  }
  for (const Line& l : lines) {
    if (claims[l.dyn] != 1) continue;
    const size_t start = dyn_line_start[l.dyn];
    const size_t stop = l.dyn + 1 < dyn_line_start.size() ? dyn_line_start[l.dyn + 1] : nv;
    if (start >= stop || stop > nv) continue;
    const bool closed = dyn_prev_next[start][0] >= 0;
    auto same_xy = [&](size_t v, uint32_t p) {
      return dyn_vertices[v][0] == points[p].x && dyn_vertices[v][1] == points[p].y;
    };
    std::vector<uint32_t> found;
    size_t v = start;
    for (uint32_t p = l.first; p <= l.last; ++p) {
      if (closed && p == l.last) {  // the ring's repeated first point
        if (same_xy(start, p)) found.push_back(uint32_t(start));
        break;
      }
      while (v < stop && !same_xy(v, p)) ++v;
      if (v == stop) break;
      found.push_back(uint32_t(v));
    }
    if (found.size() != size_t(l.last - l.first) + 1) continue;
    for (uint32_t p = l.first; p <= l.last; ++p) m.vertex[p] = found[p - l.first];
    m.end[l.first] = closed ? l.last : l.first;
    m.end[l.last] = closed ? l.first : l.last;
    m.line_drawn[l.dyn] = 1;
    ++m.lines;
    m.original_segments += l.last - l.first;
  }
  return m;
}

}  // namespace decal
