// Test helper: turns the visible segments of one LOD line into its vertex
// sequence, checking that they form one connected polyline from the
// line's first to its last point with no gaps and no overlaps.
#pragma once

#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "lod/lod.hpp"

namespace lodtest {

// `visible` are indices into set.segments (any order, any lines).
inline std::optional<std::vector<uint32_t>> visible_chain(const prep::LodSet& set, uint32_t line,
                                                          const std::vector<uint32_t>& visible,
                                                          std::string* why) {
  const auto range = set.line_range[line];
  const auto pts = set.line_points[line];
  std::unordered_map<uint32_t, uint32_t> next;
  size_t used = 0;
  for (uint32_t s : visible) {
    if (s < range[0] || s >= range[0] + range[1]) continue;
    const auto& seg = set.segments[s];
    if (!next.emplace(seg.a, seg.b).second) {
      *why = "two visible segments start at point " + std::to_string(seg.a);
      return std::nullopt;
    }
    ++used;
  }
  std::vector<uint32_t> chain{pts[0]};
  const uint32_t last = pts[0] + pts[1] - 1;
  while (chain.back() != last) {
    auto it = next.find(chain.back());
    if (it == next.end()) {
      *why = "gap after point " + std::to_string(chain.back());
      return std::nullopt;
    }
    if (it->second <= chain.back()) {
      *why = "segment goes backwards";
      return std::nullopt;
    }
    chain.push_back(it->second);
  }
  if (chain.size() - 1 != used) {
    *why = std::to_string(used) + " visible segments but the chain uses " +
           std::to_string(chain.size() - 1);
    return std::nullopt;
  }
  return chain;
}

}  // namespace lodtest
