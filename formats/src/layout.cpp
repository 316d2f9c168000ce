// layout.cpp — v1.2 <-> v1.3 layouts of the per-cell ranges and the leaf
// polygons (decal/layout.hpp, SPEC.md "Compact layout (v1.3)").
#include "decal/layout.hpp"

#include <algorithm>
#include <cstring>

namespace decal::layout {

CellEncoding encode_cells(std::span<const u2> range, std::span<const u4> bvh,
                          std::span<const std::byte> list_src, size_t list_elem,
                          std::span<const std::byte> box_src, size_t box_elem) {
  CellEncoding e;
  const size_t cells = range.size();
  // In order: each cell's list and tree start where the previous cell's end.
  bool in_order = true;
  uint64_t entries = 0, nodes = 0;
  if (bvh.size() != cells) {
    e.ok = false;
    return e;
  }
  const uint64_t list_n = list_elem ? list_src.size() / list_elem : 0,
                 box_n = box_elem ? box_src.size() / box_elem : 0;
  for (size_t c = 0; c < cells; ++c) {
    const uint64_t n = range[c][1], tree = n ? uint64_t(bvh[c][1]) + bvh[c][2] : 0;
    const uint64_t p = bvh[c][1];
    // The v1.2 constraints (a full tree inside the boxes, the list inside
    // its blob): anything else cannot be encoded.
    if (uint64_t(range[c][0]) + n > list_n ||
        (n && (uint64_t(bvh[c][0]) + tree > box_n || (p & (p - 1)) != 0 || p < n ||
               bvh[c][2] + 1 != p))) {
      e.ok = false;
      return e;
    }
    if (range[c][0] != entries || (n && bvh[c][0] != nodes)) in_order = false;
    entries += n;
    nodes += tree;
  }
  // No entries in any cell: the kind is absent, and so is its blob.
  if (entries == 0) return e;
  e.first.resize(cells + 1);
  if (in_order && entries * list_elem == list_src.size() && nodes * box_elem == box_src.size()) {
    uint32_t fx = 0, fy = 0;
    for (size_t c = 0; c < cells; ++c) {
      e.first[c] = {fx, fy};
      fx += range[c][1];
      fy += range[c][1] ? bvh[c][1] + bvh[c][2] : 0;
    }
    e.first[cells] = {fx, fy};
    return e;
  }
  e.list.resize(entries * list_elem);
  e.boxes.resize(nodes * box_elem);
  uint64_t fx = 0, fy = 0;
  for (size_t c = 0; c < cells; ++c) {
    e.first[c] = {uint32_t(fx), uint32_t(fy)};
    const uint64_t n = range[c][1];
    if (n == 0) continue;
    const uint64_t tree = uint64_t(bvh[c][1]) + bvh[c][2];
    std::memcpy(e.list.data() + fx * list_elem, list_src.data() + uint64_t(range[c][0]) * list_elem,
                n * list_elem);
    std::memcpy(e.boxes.data() + fy * box_elem, box_src.data() + uint64_t(bvh[c][0]) * box_elem,
                tree * box_elem);
    fx += n;
    fy += tree;
  }
  e.first[cells] = {uint32_t(fx), uint32_t(fy)};
  return e;
}

void decode_cells(std::span<const u2> first, std::vector<u2>& range, std::vector<u4>& bvh) {
  range.clear();
  bvh.clear();
  if (first.empty()) return;
  const size_t cells = first.size() - 1;
  range.resize(cells);
  bvh.resize(cells);
  for (size_t c = 0; c < cells; ++c) {
    const uint32_t p = leaf_slots_of(first[c + 1][1] - first[c][1]);
    range[c] = {first[c][0], first[c + 1][0] - first[c][0]};
    bvh[c] = {first[c][1], p, p ? p - 1 : 0, 0};
  }
}

bool encode_leaves(std::span<const u2> leaf_range, std::span<const u2> segments,
                   uint64_t vertex_count, std::vector<u2>& loop_range,
                   std::vector<uint32_t>& loop_end) {
  loop_range.clear();
  loop_end.clear();
  loop_range.reserve(leaf_range.size());
  uint64_t end = 0;  // end of the last loop
  for (const u2& r : leaf_range) {
    uint32_t first_loop = uint32_t(loop_end.size());
    uint64_t s = r[0];
    const uint64_t stop = uint64_t(r[0]) + r[1];
    if (stop > segments.size()) return false;
    while (s < stop) {
      // A loop: (a, a+1), (a+1, a+2), ..., (b, a) with b >= a + 1.
      const uint64_t a = segments[s][0];
      uint64_t v = a;
      while (s < stop && segments[s][0] == v && segments[s][1] == v + 1) {
        ++v;
        ++s;
      }
      if (s >= stop || segments[s][0] != v || segments[s][1] != a || v == a) return false;
      ++s;
      // The loop must start where the last one ended. A gap of one vertex
      // (an orphan vertex) becomes a loop of one vertex (a degenerate edge
      // that no ray crosses), allowed only between leaves.
      if (a < end) return false;
      if (a > end) {
        if (a - end > 1 || uint32_t(loop_end.size()) != first_loop) return false;
        loop_end.push_back(uint32_t(a));
        ++first_loop;
      }
      loop_end.push_back(uint32_t(v + 1));
      end = v + 1;
    }
    loop_range.push_back({first_loop, uint32_t(loop_end.size()) - first_loop});
  }
  return end <= vertex_count;
}

void decode_leaves(std::span<const u2> loop_range, std::span<const uint32_t> loop_end,
                   std::vector<u2>& leaf_range, std::vector<u2>& segments) {
  leaf_range.clear();
  segments.clear();
  leaf_range.reserve(loop_range.size());
  for (const u2& r : loop_range) {
    const uint32_t first = uint32_t(segments.size());
    const uint64_t stop = std::min<uint64_t>(uint64_t(r[0]) + r[1], loop_end.size());
    for (uint64_t l = r[0]; l < stop; ++l) {
      const uint32_t s = l == 0 ? 0 : loop_end[l - 1], e = loop_end[l];
      for (uint32_t v = s; v < e; ++v) segments.push_back({v, v + 1 < e ? v + 1 : s});
    }
    leaf_range.push_back({first, uint32_t(segments.size()) - first});
  }
}

PolyEntryEncoding encode_poly_entries(std::span<const u4> cell_polys,
                                      std::span<const u2> cell_holes) {
  PolyEntryEncoding e;
  if (cell_polys.empty()) return e;
  bool in_order = true;
  uint64_t h = 0;
  for (const u4& p : cell_polys) {
    if (uint64_t(p[2]) + p[3] > cell_holes.size()) {
      e.ok = false;
      return e;
    }
    if (p[3] && p[2] != h) in_order = false;
    h += p[3];
  }
  in_order = in_order && h == cell_holes.size();
  e.entries.reserve(cell_polys.size());
  e.hole_first.reserve(cell_polys.size() + 1);
  uint32_t at = 0;
  for (const u4& p : cell_polys) {
    e.entries.push_back({p[0], p[1]});
    e.hole_first.push_back(at);
    if (!in_order)
      for (uint32_t k = 0; k < p[3]; ++k) e.holes.push_back(cell_holes[p[2] + k]);
    at += p[3];
  }
  e.hole_first.push_back(at);
  return e;
}

void decode_poly_entries(std::span<const u2> entries, std::span<const uint32_t> hole_first,
                         std::vector<u4>& cell_polys) {
  cell_polys.clear();
  if (hole_first.size() <= entries.size()) return;
  cell_polys.reserve(entries.size());
  for (size_t k = 0; k < entries.size(); ++k)
    cell_polys.push_back(
        {entries[k][0], entries[k][1], hole_first[k], hole_first[k + 1] - hole_first[k]});
}

uint32_t box16_shift(int64_t cell_w, int64_t cell_h) {
  const int64_t side = cell_w > cell_h ? cell_w : cell_h;
  uint32_t s = 0;
  while (s < 31 && side + (int64_t(2) << s) > (int64_t(65535) << s)) ++s;
  return s;
}

namespace {
// Base corner (quanta) of cell c: its lower-left corner minus one step.
std::array<int64_t, 2> box16_base(const CellGrid& g, uint64_t c, uint32_t s) {
  const uint64_t ix = g.nx ? c % g.nx : 0, iy = g.nx ? c / g.nx : 0;
  return {g.origin_x + int64_t(ix) * g.cell_w - (int64_t(1) << s),
          g.origin_y + int64_t(iy) * g.cell_h - (int64_t(1) << s)};
}
int64_t floor_shift(int64_t v, uint32_t s) {
  return v >= 0 ? v >> s : -((-v + (int64_t(1) << s) - 1) >> s);
}
uint32_t clamp16(int64_t v) {
  return uint32_t(v < 0 ? 0 : v > 65535 ? 65535 : v);
}
}  // namespace

Box16Encoder::Box16Encoder(const CellGrid& grid)
    : grid_(grid), shift_(box16_shift(grid.cell_w, grid.cell_h)) {
  // Upper bounds at most the grown cell's top (its size in steps).
  const int64_t step = int64_t(1) << shift_;
  top_x_ = (grid.cell_w + 2 * step + step - 1) >> shift_;
  top_y_ = (grid.cell_h + 2 * step + step - 1) >> shift_;
}

u2 Box16Encoder::operator()(uint64_t cell, const std::array<int32_t, 4>& b) const {
  if (b[0] > b[2] || b[1] > b[3]) return kEmpty;
  const uint32_t s = shift_;
  const int64_t step = int64_t(1) << s;
  const auto base = box16_base(grid_, cell, s);
  const uint32_t x0 = clamp16(floor_shift(b[0] - base[0], s)),
                 y0 = clamp16(floor_shift(b[1] - base[1], s)),
                 x1 = clamp16(std::min(floor_shift(b[2] - base[0] + step - 1, s), top_x_)),
                 y1 = clamp16(std::min(floor_shift(b[3] - base[1] + step - 1, s), top_y_));
  return {x0 | (y0 << 16), x1 | (y1 << 16)};
}

u2 box16_union(const u2& a, const u2& b) {
  if (a == Box16Encoder::kEmpty) return b;
  if (b == Box16Encoder::kEmpty) return a;
  auto lo = [](uint32_t p, uint32_t q) {
    return std::min(p & 0xffffu, q & 0xffffu) | (std::min(p >> 16, q >> 16) << 16);
  };
  auto hi = [](uint32_t p, uint32_t q) {
    return std::max(p & 0xffffu, q & 0xffffu) | (std::max(p >> 16, q >> 16) << 16);
  };
  return {lo(a[0], b[0]), hi(a[1], b[1])};
}

std::vector<u2> encode_boxes16(std::span<const u2> first,
                               std::span<const std::array<int32_t, 4>> boxes,
                               const CellGrid& grid) {
  std::vector<u2> out(boxes.size(), Box16Encoder::kEmpty);
  const Box16Encoder encode(grid);
  for (size_t c = 0; c + 1 < first.size(); ++c)
    for (uint64_t i = first[c][1]; i < std::min<uint64_t>(first[c + 1][1], boxes.size()); ++i)
      out[i] = encode(c, boxes[i]);
  return out;
}

std::vector<std::array<int32_t, 4>> decode_boxes16(std::span<const u2> first,
                                                   std::span<const u2> boxes,
                                                   const CellGrid& grid) {
  constexpr int32_t kMax = 2147483647, kMin = -kMax - 1;
  std::vector<std::array<int32_t, 4>> out(boxes.size(), {kMax, kMax, kMin, kMin});
  const uint32_t s = box16_shift(grid.cell_w, grid.cell_h);
  for (size_t c = 0; c + 1 < first.size(); ++c) {
    const auto base = box16_base(grid, c, s);
    const uint64_t stop = std::min<uint64_t>(first[c + 1][1], boxes.size());
    for (uint64_t i = first[c][1]; i < stop; ++i) {
      const u2 b = boxes[i];
      const int64_t x0 = b[0] & 0xffffu, y0 = b[0] >> 16, x1 = b[1] & 0xffffu, y1 = b[1] >> 16;
      if (x0 > x1 || y0 > y1) continue;  // empty node
      auto i32 = [](int64_t v) { return int32_t(std::clamp<int64_t>(v, kMin, kMax)); };
      out[i] = {i32(base[0] + (x0 << s)), i32(base[1] + (y0 << s)), i32(base[0] + (x1 << s)),
                i32(base[1] + (y1 << s))};
    }
  }
  return out;
}

}  // namespace decal::layout
