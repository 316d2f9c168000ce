// Determinism (ARCHITECTURE.md, build): the same scene built with 1 thread and with
// 2 threads gives byte-identical arrays.
#include <gtest/gtest.h>

#include <cstring>

#include "../evaluate/synthetic.hpp"
#include "prep/model.hpp"

namespace {

template <class T>
bool same(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

prep::SceneFeatures mixed_scene() {
  synth::PolygonSet set = synth::polygon_set(11, 12, 60.0, -300.0, 200.0, 9, 600);
  prep::SceneFeatures s = set.scene;
  s.layers.push_back(
      synth::layer("roads", prep::DecalKind::line, 0xff00ffffu, decal::CornerStyle::round));
  s.layers.push_back(synth::layer("edges", prep::DecalKind::outline, 0x80000000u,
                                  decal::CornerStyle::miter, decal::OutlineMode::inset, 1.5));
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(0, 720);
  for (int i = 0; i < 300; ++i) {
    prep::SceneLine l;
    l.layer = 1;
    l.width = 4;
    l.fid = i;
    l.length = double(i % 17);  // many ties: broken by fid
    double x = -300 + U(rng), y = 200 + U(rng);
    for (int k = 0; k < 6; ++k) l.points.push_back({x += U(rng) / 20 - 18, y += U(rng) / 20 - 18});
    s.lines.push_back(l);
  }
  for (const auto& p : set.scene.polygons) {
    prep::SceneLine l;
    l.layer = 2;
    l.width = 1.5;
    l.closed = true;
    l.points = p.shell;
    l.fid = p.fid;
    s.lines.push_back(l);
  }
  return s;
}

}  // namespace

TEST(BuildDeterminism, OneThreadAndTwoThreadsGiveIdenticalBytes) {
  const prep::SceneFeatures scene = mixed_scene();
  prep::ModelOptions o1, o2;
  o1.threads = 1;
  o2.threads = 2;
  const prep::DecalModel a = prep::build_model(scene, o1), b = prep::build_model(scene, o2);
  ASSERT_GT(a.cell_segments.size(), 1000u);
  ASSERT_GT(a.cell_polys.size(), 100u);
  EXPECT_EQ(a.grid.nx, b.grid.nx);
  EXPECT_EQ(a.grid.ny, b.grid.ny);
  EXPECT_TRUE(same(a.line_vertices, b.line_vertices));
  EXPECT_TRUE(same(a.line_vertex_line, b.line_vertex_line));
  EXPECT_TRUE(same(a.line_props, b.line_props));
  EXPECT_TRUE(same(a.line_corners, b.line_corners));
  EXPECT_TRUE(same(a.cell_segment_range, b.cell_segment_range));
  EXPECT_TRUE(same(a.cell_segments, b.cell_segments));
  EXPECT_TRUE(same(a.poly_props, b.poly_props));
  EXPECT_TRUE(same(a.poly_root_node, b.poly_root_node));
  EXPECT_TRUE(same(a.qt_node_box, b.qt_node_box));
  EXPECT_TRUE(same(a.qt_node, b.qt_node));
  EXPECT_TRUE(same(a.qt_leaf_range, b.qt_leaf_range));
  EXPECT_TRUE(same(a.qt_leaf_segments, b.qt_leaf_segments));
  EXPECT_TRUE(same(a.qt_leaf_vertices, b.qt_leaf_vertices));
  EXPECT_TRUE(same(a.cell_poly_range, b.cell_poly_range));
  EXPECT_TRUE(same(a.cell_polys, b.cell_polys));
  EXPECT_TRUE(same(a.cell_holes, b.cell_holes));
  EXPECT_TRUE(same(a.line_bvh_range, b.line_bvh_range));
  EXPECT_TRUE(same(a.line_bvh_box, b.line_bvh_box));
  EXPECT_TRUE(same(a.poly_bvh_range, b.poly_bvh_range));
  EXPECT_TRUE(same(a.poly_bvh_box, b.poly_bvh_box));
  EXPECT_EQ(a.manifest.notes, b.manifest.notes);
}

TEST(BuildDrawingOrder, LinesAndPolygonsShareOneLayerMajorRankSpace) {
  const prep::SceneFeatures scene = mixed_scene();
  const prep::DecalModel m = prep::build_model(scene, {});
  // Every static line and exterior polygon holds one rank of 0..N-1.
  struct Item {
    uint32_t order, layer;
    bool line;
  };
  std::vector<Item> items;
  for (size_t i = 0; i < m.line_props.size(); ++i)
    items.push_back({m.line_props[i].order, m.line_props[i].layer, true});
  for (const auto& p : m.poly_props)
    if (p.exterior < 0) items.push_back({p.order, p.layer, false});
  ASSERT_GT(items.size(), m.line_props.size() + 100u);
  std::vector<bool> seen(items.size(), false);
  for (const Item& it : items) {
    ASSERT_LT(it.order, seen.size());
    EXPECT_FALSE(seen[it.order]);
    seen[it.order] = true;
  }
  // Layer-major: a later scene layer (edges 2, roads 1, polygons 0) is on
  // top of every feature of an earlier one, lines or polygons.
  std::vector<Item> by_rank(items.size());
  for (const Item& it : items) by_rank[it.order] = it;
  for (size_t r = 1; r < by_rank.size(); ++r)
    EXPECT_GE(by_rank[r - 1].layer, by_rank[r].layer) << "rank " << r;
  EXPECT_EQ(by_rank.front().layer, 2u);
  EXPECT_FALSE(by_rank.back().line);
  // Within the roads layer the longest line is on top (lengths fid % 17).
  uint32_t top = 0, best = ~0u;
  for (uint32_t i = 0; i < m.line_props.size(); ++i)
    if (m.line_props[i].layer == 1 && m.line_props[i].order < best)
      best = m.line_props[i].order, top = i;
  EXPECT_EQ(scene.lines[top].length, 16.0);
  // Within every cell, segments are sorted by their line's rank.
  for (size_t c = 0; c < m.cell_segment_range.size(); ++c) {
    const auto r = m.cell_segment_range[c];
    for (uint32_t k = r[0] + 1; k < r[0] + r[1]; ++k)
      EXPECT_LE(m.line_props[m.line_vertex_line[m.cell_segments[k - 1][0]]].order,
                m.line_props[m.line_vertex_line[m.cell_segments[k][0]]].order);
  }
}
