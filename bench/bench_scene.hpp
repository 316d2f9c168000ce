// bench_scene.hpp — what the benchmarks share about a scene.
#pragma once

#include <cstdint>

#include "prep/features.hpp"

namespace bench {

// Vertices of a scene's polygons (shells and holes) and lines.
inline uint64_t scene_vertices(const prep::SceneFeatures& s) {
  uint64_t v = 0;
  for (const auto& p : s.polygons) {
    v += p.shell.size();
    for (const auto& h : p.holes) v += h.size();
  }
  for (const auto& l : s.lines) v += l.points.size();
  return v;
}

}  // namespace bench
