// libprep/model/bvh.cpp — per-cell BVHs (thesis §4.2.1 "Bounding Volume
// Hierarchies"): an implicit full binary tree per cell. With n leaves the
// tree has P = next power of two >= n leaf slots and 2P - 1 nodes; node i has
// children 2i+1 and 2i+2 (Eq. 4.5/4.6); leaf k is node (P - 1) + k and refers
// to the k-th entry of the cell's list (cell_segments / cell_poly_entries).
// Boxes are the cell-relative u16 boxes of the v1.3 layout; empty slots, and
// internal nodes with only empty slots below, have the empty box
// (decal::layout::Box16Encoder::kEmpty).
#include <tbb/parallel_for.h>

#include <bit>

#include <decal/layout.hpp>

#include "detail.hpp"
#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep::detail {

namespace {
// 64-bit, so a cell of more than 2^31 entries (which fill_cells allows) gets
// its 2^32 slots counted and refused below instead of wrapping to 0.
uint64_t leaf_slots(uint32_t n) {
  return n == 0 ? 0 : std::bit_ceil(uint64_t(n));
}
}  // namespace

void build_bvhs(const std::vector<uint32_t>& first, const LeafBoxes& leaf_boxes,
                std::vector<uvec2>& cell_first, std::vector<uvec2>& boxes) {
  namespace L = decal::layout;
  const size_t cells = first.size() - 1;
  cell_first.resize(cells + 1);
  uint64_t total = 0;
  for (size_t c = 0; c < cells; ++c) {
    cell_first[c] = {first[c], uint32_t(total)};
    const uint64_t p = leaf_slots(first[c + 1] - first[c]);
    total += p ? 2 * p - 1 : 0;
    if (total > 0xffffffffULL)
      fail<resource_error>(kBuildStage, "per-cell BVHs need more than 2^32 nodes");
  }
  cell_first[cells] = {first[cells], uint32_t(total)};
  boxes.assign(total, L::Box16Encoder::kEmpty);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cells, 256),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t c = r.begin(); c != r.end(); ++c) {
                        const uint32_t n = first[c + 1] - first[c];
                        if (n == 0) continue;
                        const uint64_t p = leaf_slots(n);  // <= 2^31 after the check
                        uvec2* node = boxes.data() + cell_first[c][1];
                        leaf_boxes(c, first[c], n, node + (p - 1));
                        for (int64_t i = int64_t(p) - 2; i >= 0; --i)
                          node[i] = L::box16_union(node[2 * i + 1], node[2 * i + 2]);
                      }
                    });
}

}  // namespace prep::detail
