// decal::lod_draw_map: each LOD point to the dynamic vertex the renderers draw
// it at (formats/SPEC.md "Choosing the threshold"), on hand-made lines whose
// answers are counted by hand: an open line subdivided between its points,
// a closed ring, and a line whose points are not on its dynamic line.
#include <gtest/gtest.h>

#include "lod/lod.hpp"

namespace {

using V4 = std::array<int32_t, 4>;
using PN = std::array<int32_t, 2>;

struct Dyn {
  std::vector<V4> vertices;
  std::vector<PN> prev_next;
  std::vector<uint32_t> start;
  // Adds line `pts`, each piece split into `split` pieces (terrain matching
  // inserts vertices between the input vertices, never moves them).
  void add(const std::vector<prep::ivec2>& pts, bool closed, int split) {
    const auto line = int32_t(start.size());
    const auto first = uint32_t(vertices.size());
    start.push_back(first);
    const size_t n = pts.size(), pieces = closed ? n : n - 1;
    for (size_t k = 0; k < pieces; ++k) {
      const auto& a = pts[k];
      const auto& b = pts[(k + 1) % n];
      for (int s = 0; s < split; ++s)
        vertices.push_back(
            {a[0] + (b[0] - a[0]) * s / split, a[1] + (b[1] - a[1]) * s / split, 7 * s, line});
    }
    if (!closed) vertices.push_back({pts.back()[0], pts.back()[1], 0, line});
    const auto end = uint32_t(vertices.size());
    for (uint32_t v = first; v < end; ++v)
      prev_next.push_back({v > first ? int32_t(v - 1) : (closed ? int32_t(end - 1) : -1),
                           v + 1 < end ? int32_t(v + 1) : (closed ? int32_t(first) : -1)});
  }
};

TEST(LodDrawMap, PointsMapToTheirVerticesAndRingsWrap) {
  const std::vector<prep::ivec2> open{{0, 0}, {1000, 0}, {2000, 500}, {3000, 0}};
  const std::vector<prep::ivec2> ring{{0, 5000}, {1000, 5000}, {1000, 6000}, {0, 6000}};
  const std::vector<prep::ivec2> stray{{0, 9000}, {4000, 9000}, {8000, 9500}};
  Dyn d;
  d.add(open, false, 2);   // vertices 0..6: input vertices at 0, 2, 4, 6
  d.add(ring, true, 3);    // vertices 7..18: input vertices at 7, 10, 13, 16
  d.add(stray, false, 1);  // vertices 19..21
  std::vector<prep::LodInputLine> in{{open, false, 0}, {ring, true, 1}, {stray, false, 2}};
  const prep::LodSet set = prep::build_lod(in);
  ASSERT_EQ(set.points.size(), 4u + 5u + 3u);
  // The stray line's LOD points are moved off its dynamic line.
  auto points = set.points;
  for (uint32_t p = 9; p < 12; ++p) points[p].y += 1;
  const decal::LodDrawMap m =
      decal::lod_draw_map(points, set.segments, set.line_range, d.vertices, d.start, d.prev_next);
  const uint32_t none = decal::kLodNone;
  EXPECT_EQ(m.vertex, (std::vector<uint32_t>{0, 2, 4, 6, 7, 10, 13, 16, 7, none, none, none}));
  EXPECT_EQ(m.end,
            (std::vector<uint32_t>{0, none, none, 3, 8, none, none, none, 4, none, none, none}));
  EXPECT_EQ(m.line_drawn, (std::vector<uint8_t>{1, 1, 0}));
  EXPECT_EQ(m.lines, 2u);
  EXPECT_EQ(m.original_segments, 3u + 4u);
}

// Two LOD lines naming one dynamic line: neither is drawn from LOD segments.
TEST(LodDrawMap, ADynamicLineClaimedTwiceKeepsItsVertexChain) {
  const std::vector<prep::ivec2> a{{0, 0}, {1000, 0}, {2000, 500}};
  Dyn d;
  d.add(a, false, 1);
  std::vector<prep::LodInputLine> in{{a, false, 0}, {a, false, 0}};
  const prep::LodSet set = prep::build_lod(in);
  const decal::LodDrawMap m = decal::lod_draw_map(set.points, set.segments, set.line_range,
                                                  d.vertices, d.start, d.prev_next);
  EXPECT_EQ(m.line_drawn, (std::vector<uint8_t>{0}));
  EXPECT_EQ(m.lines, 0u);
  for (uint32_t v : m.vertex) EXPECT_EQ(v, decal::kLodNone);
}

}  // namespace
