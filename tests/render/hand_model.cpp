#include "hand_model.hpp"

#include "v12_cells.hpp"

namespace render_test {

namespace {

int32_t q(double m) {
  return int32_t(m * 1000.0);
}

// Adds polygon `poly` as a one-node quad-tree (a partial leaf holding the
// whole ring) and returns the node index.
uint32_t add_square(prep::DecalModel& m, double lo, double hi) {
  uint32_t node = uint32_t(m.qt_node.size());
  uint32_t first_v = uint32_t(m.qt_leaf_vertices.size());
  const uint32_t first_loop = uint32_t(m.qt_leaf_loops.size());
  m.qt_leaf_vertices.insert(m.qt_leaf_vertices.end(),
                            {{q(lo), q(lo)}, {q(hi), q(lo)}, {q(hi), q(hi)}, {q(lo), q(hi)}});
  m.qt_leaf_loops.push_back(first_v + 4);  // one loop of the four corners
  m.qt_leaf_loop_range.push_back({first_loop, 1});
  m.qt_node_box.push_back({q(lo), q(lo), q(hi), q(hi)});
  m.qt_node.push_back({3, int32_t(m.qt_leaf_loop_range.size() - 1)});
  return node;
}

}  // namespace

prep::DecalModel hand_model() {
  prep::DecalModel m;
  m.extent = {0, 0, 100, 100};
  m.grid = {0, 0, 50000, 50000, 2, 2};
  uint32_t n_ext = add_square(m, 20, 80), n_hole = add_square(m, 40, 60),
           n_island = add_square(m, 45, 55);
  // One rank space (formats/SPEC.md "Drawing order"): the two lines (ranks 0
  // and 1) over the exterior (2, its hole too) over the island (3).
  m.poly_props.push_back({HandShapes::kPolyRgba, 2, -1, 0.f, 0, 0, {0, 0}});
  m.poly_props.push_back({0, 2, 0, 0.f, 0, 0, {0, 0}});
  m.poly_props.push_back({HandShapes::kIslandRgba, 3, -1, 0.f, 0, 1, {0, 0}});
  m.poly_root_node = {n_ext, n_hole, n_island};
  // Every cell holds the exterior (with its hole) then the island, in
  // drawing order; BVH of 2 leaves + 1 internal node per cell.
  m.line_vertices = {{q(10), q(10)}, {q(90), q(90)}, {q(10), q(90)}, {q(90), q(10)}};
  m.line_vertex_line = {0, 0, 1, 1};
  m.line_corners.resize(4, decal::LineCorner{});
  m.line_props.push_back({2.0f, HandShapes::kLineRgba, 0, 0, 0.f, 0, 2, 0});
  m.line_props.push_back({3.0f, HandShapes::kLine2Rgba, 1, 0, 0.f, 0, 3, 0});
  prep::test::V12Cells cells;
  for (uint32_t c = 0; c < 4; ++c) {
    cells.poly_range.push_back({uint32_t(cells.cell_polys.size()), 2});
    m.cell_holes.push_back({1, n_hole});
    cells.cell_polys.push_back({0, n_ext, uint32_t(m.cell_holes.size() - 1), 1});
    cells.cell_polys.push_back({2, n_island, 0, 0});
    uint32_t first = uint32_t(cells.poly_bvh_box.size());
    cells.poly_bvh_box.push_back({q(20), q(20), q(80), q(80)});
    cells.poly_bvh_box.push_back({q(20), q(20), q(80), q(80)});
    cells.poly_bvh_box.push_back({q(45), q(45), q(55), q(55)});
    cells.poly_bvh_range.push_back({first, 2, 1, 0});
    // Both lines in every cell, in drawing order (line 0 on top).
    cells.segment_range.push_back({uint32_t(m.cell_segments.size()), 2});
    m.cell_segments.push_back({0, 1});
    m.cell_segments.push_back({2, 3});
    cells.line_bvh_range.push_back({uint32_t(cells.line_bvh_box.size()), 2, 1, 0});
    cells.line_bvh_box.push_back({q(7), q(7), q(93), q(93)});
    cells.line_bvh_box.push_back({q(8), q(8), q(92), q(92)});
    cells.line_bvh_box.push_back({q(7), q(7), q(93), q(93)});
  }
  prep::test::set_cells(m, cells);  // the model holds the v1.3 layout
  return m;
}

}  // namespace render_test
