// Determinism (ARCHITECTURE.md, build): the same scene built with 1 thread and with
// 2 threads gives byte-identical arrays.
#include <gtest/gtest.h>

#include <cstring>

#include "../evaluate/synthetic.hpp"
#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "v12_cells.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace model_determinism {

namespace {

template <class T>
bool same(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Every static blob of the two models (the list a PackageView reads,
// prep/evaluate.hpp) byte for byte, and the grid.
void expect_same_static_blobs(const prep::DecalModel& a, const prep::DecalModel& b) {
  EXPECT_EQ(a.grid.nx, b.grid.nx);
  EXPECT_EQ(a.grid.ny, b.grid.ny);
  EXPECT_EQ(a.grid.cell_w, b.grid.cell_w);
#define PREP_EXPECT_SAME(type, name) EXPECT_TRUE(same(a.name, b.name)) << #name;
  PREP_STATIC_VIEW_BLOBS(PREP_EXPECT_SAME)
  PREP_COMPACT_BLOBS(PREP_EXPECT_SAME)
#undef PREP_EXPECT_SAME
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
  ASSERT_GT(a.cell_poly_entries.size(), 100u);
  expect_same_static_blobs(a, b);
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
  ASSERT_FALSE(m.cell_line_first.empty());
  for (size_t c = 0; c + 1 < m.cell_line_first.size(); ++c) {
    for (uint32_t k = m.cell_line_first[c][0] + 1; k < m.cell_line_first[c + 1][0]; ++k)
      EXPECT_LE(m.line_props[m.line_vertex_line[m.cell_segments[k - 1][0]]].order,
                m.line_props[m.line_vertex_line[m.cell_segments[k][0]]].order);
  }
}

// choose_grid() counts the candidate grids of a large input (2^17
// primitives or more, libprep/model/grid.cpp sample_stride) on a row
// sample, in parallel over the rows, and confirms its choice on exact
// counts: the grid and every array must still be the same at any thread
// count, and the package within the size budget of the thesis grid.
TEST(BuildDeterminism, SampledGridChoiceIsTheSameAtOneAndTwoThreads) {
  auto fixed = [](int n) { return [n](std::mt19937_64&) { return n; }; };
  const prep::SceneFeatures s =
      synth::clustered_scene({.seed = 17,
                              .polygons = 4000,
                              .lines = 6000,
                              .sx = 2000,
                              .sy = 1500,
                              .shell_vertices = fixed(24),
                              .hole_vertices = fixed(8),
                              .walk_points = 30,
                              .step = 15,
                              .turn = 0.4,
                              .corner = decal::CornerStyle::miter,
                              .width = 3,
                              .length = [](int i) { return double(i % 13); }});
  prep::ModelOptions o1, o2, thesis;
  o1.threads = 1;
  o2.threads = 2;
  thesis.grid_nx = thesis.grid_ny = 500;
  const prep::DecalModel a = prep::build_model(s, o1), b = prep::build_model(s, o2);
  ASSERT_GE(a.stats.line_segments, uint64_t(1) << 17);  // the sampled path
  expect_same_static_blobs(a, b);
  // The size contract (kGridSizeBudget) holds on the sampled choice.
  const prep::DecalModel t = prep::build_model(s, thesis);
  // The bytes the chooser's byte model counts: the v1.2 layout.
  auto grid_dependent = [](const prep::DecalModel& m) {
    return double(prep::test::v12_cell_bytes(m));
  };
  auto geometry = [](const prep::DecalModel& m) {
    auto bytes = [](const auto& v) { return double(v.size() * sizeof(v[0])); };
    return bytes(m.line_vertices) + bytes(m.line_vertex_line) + bytes(m.line_props) +
           bytes(m.line_corners) + bytes(m.poly_props) + bytes(m.poly_root_node) +
           bytes(m.qt_node_box) + bytes(m.qt_node) + bytes(m.qt_leaf_loop_range) +
           bytes(m.qt_leaf_loops) + bytes(m.qt_leaf_vertices) +
           bytes(m.qt_leaf_vertices);  // the v1.2 leaf segments the chooser counts, one per vertex
  };
  EXPECT_LE(geometry(a) + grid_dependent(a), 1.2 * (geometry(t) + grid_dependent(t)))
      << a.grid.nx << "x" << a.grid.ny;
  EXPECT_GT(uint64_t(a.grid.nx) * a.grid.ny, 250000u);  // refined past the thesis grid
}

}  // namespace model_determinism
