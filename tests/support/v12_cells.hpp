// v12_cells.hpp — hand-made models (the format fixtures, the render tests)
// spell their per-cell lists and BVHs in the v1.2 layout, one (first,
// count) range and one full box per node, which reads most plainly; set_cells
// stores them in the model's v1.3 arrays through decal/layout.hpp (the
// format library's conversion, not the build stage's). Header-only: for
// tests that link prep_core.
#pragma once

#include <cstring>
#include <span>
#include <stdexcept>
#include <vector>

#include <decal/layout.hpp>

#include "prep/model.hpp"

namespace prep::test {

struct V12Cells {
  // lines: per cell (first, count) into model.cell_segments; per cell
  // (first node, leaf slots, internal nodes, 0); per node a box
  std::vector<uvec2> segment_range;
  std::vector<uvec4> line_bvh_range;
  std::vector<ivec4> line_bvh_box;
  // polygons: per cell (first, count) into cell_polys; per entry (polygon,
  // culling node, first hole, hole count) into model.cell_holes
  std::vector<uvec2> poly_range;
  std::vector<uvec4> cell_polys;
  std::vector<uvec4> poly_bvh_range;
  std::vector<ivec4> poly_bvh_box;
};

// Sets m.cell_line_first, line_bvh_box16, cell_poly_first, poly_bvh_box16,
// cell_poly_entries and cell_poly_holes from `c` on m.grid (and reorders
// m.cell_segments and m.cell_holes into cell order when `c` lists them
// otherwise). Throws std::invalid_argument when `c` breaks the v1.2 index
// constraints.
inline void set_cells(DecalModel& m, const V12Cells& c) {
  namespace L = decal::layout;
  const L::CellGrid grid{m.grid.origin_x, m.grid.origin_y, m.grid.cell_w, m.grid.cell_h, m.grid.nx};
  auto kind = [&](const std::vector<uvec2>& range, const std::vector<uvec4>& bvh,
                  std::span<const std::byte> list, size_t list_elem,
                  const std::vector<ivec4>& boxes, std::vector<uvec2>& first,
                  std::vector<uvec2>& boxes16) {
    L::CellEncoding e = L::encode_cells(range, bvh, list, list_elem,
                                        std::as_bytes(std::span(boxes)), sizeof(ivec4));
    if (!e.ok) throw std::invalid_argument("set_cells: ranges break the v1.2 constraints");
    std::span<const ivec4> src(boxes);
    if (!e.boxes.empty())
      src = {reinterpret_cast<const ivec4*>(e.boxes.data()), e.boxes.size() / sizeof(ivec4)};
    boxes16 = e.first.empty() ? std::vector<uvec2>{} : L::encode_boxes16(e.first, src, grid);
    first = std::move(e.first);
    return std::move(e.list);
  };
  std::vector<std::byte> segs =
      kind(c.segment_range, c.line_bvh_range, std::as_bytes(std::span(m.cell_segments)),
           sizeof(uvec2), c.line_bvh_box, m.cell_line_first, m.line_bvh_box16);
  if (!segs.empty()) {
    m.cell_segments.resize(segs.size() / sizeof(uvec2));
    std::memcpy(m.cell_segments.data(), segs.data(), segs.size());
  }
  std::vector<std::byte> polys_copy =
      kind(c.poly_range, c.poly_bvh_range, std::as_bytes(std::span(c.cell_polys)), sizeof(uvec4),
           c.poly_bvh_box, m.cell_poly_first, m.poly_bvh_box16);
  std::span<const uvec4> polys(c.cell_polys);
  if (!polys_copy.empty())
    polys = {reinterpret_cast<const uvec4*>(polys_copy.data()), polys_copy.size() / sizeof(uvec4)};
  if (m.cell_poly_first.empty()) polys = {};
  L::PolyEntryEncoding e = L::encode_poly_entries(polys, m.cell_holes);
  if (!e.ok) throw std::invalid_argument("set_cells: hole ranges run past cell_holes");
  m.cell_poly_entries = std::move(e.entries);
  m.cell_poly_holes = std::move(e.hole_first);
  if (!e.holes.empty()) m.cell_holes = std::move(e.holes);
}

// The bytes m's per-cell ranges, lists and BVHs take in the v1.2 layout,
// which the grid chooser's byte model counts (libprep/model/grid.cpp): per
// cell a (first, count) range and a BVH range of each kind, 48 bytes; per
// entry cell_segments 8, cell_polys 16 and cell_holes 8; per BVH node a
// 16-byte box.
inline uint64_t v12_cell_bytes(const DecalModel& m) {
  return 48 * uint64_t(m.grid.nx) * m.grid.ny + 8 * uint64_t(m.cell_segments.size()) +
         16 * uint64_t(m.cell_poly_entries.size()) + 8 * uint64_t(m.cell_holes.size()) +
         16 * uint64_t(m.line_bvh_box16.size() + m.poly_bvh_box16.size());
}

}  // namespace prep::test
