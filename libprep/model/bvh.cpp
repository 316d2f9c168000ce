// libprep/model/bvh.cpp — per-cell BVHs (thesis §4.2.1 "Bounding Volume
// Hierarchies"): an implicit full binary tree per cell. With n leaves the
// tree has P = next power of two >= n leaf slots and 2P - 1 nodes; node i has
// children 2i+1 and 2i+2 (Eq. 4.5/4.6); leaf k is node (P - 1) + k and refers
// to the k-th entry of the cell's list (cell_segments / cell_polys). Empty
// slots, and internal nodes with only empty slots below, have the empty box
// (INT32_MAX, INT32_MAX, INT32_MIN, INT32_MIN), i.e. xmin > xmax.
#include <tbb/parallel_for.h>

#include <limits>

#include "detail.hpp"

namespace prep::detail {

namespace {
constexpr ivec4 kEmptyBox{std::numeric_limits<int32_t>::max(), std::numeric_limits<int32_t>::max(),
                          std::numeric_limits<int32_t>::min(), std::numeric_limits<int32_t>::min()};
uint32_t leaf_slots(uint32_t n) {
  if (n == 0) return 0;
  uint32_t p = 1;
  while (p < n) p <<= 1;
  return p;
}
}  // namespace

void build_bvhs(const std::vector<uint32_t>& first, const std::vector<ivec4>& leaf_boxes,
                std::vector<uvec4>& range, std::vector<ivec4>& boxes) {
  const size_t cells = first.size() - 1;
  range.assign(cells, uvec4{0, 0, 0, 0});
  uint64_t total = 0;
  for (size_t c = 0; c < cells; ++c) {
    const uint32_t p = leaf_slots(first[c + 1] - first[c]);
    range[c] = {uint32_t(total), p, p ? p - 1 : 0, 0};
    total += p ? 2 * uint64_t(p) - 1 : 0;
  }
  boxes.assign(total, kEmptyBox);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, cells, 256),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t c = r.begin(); c != r.end(); ++c) {
                        const uint32_t n = first[c + 1] - first[c];
                        if (n == 0) continue;
                        const uint32_t p = range[c][1];
                        ivec4* node = boxes.data() + range[c][0];
                        for (uint32_t k = 0; k < n; ++k) node[p - 1 + k] = leaf_boxes[first[c] + k];
                        for (int64_t i = int64_t(p) - 2; i >= 0; --i) {
                          const ivec4& a = node[2 * i + 1];
                          const ivec4& b = node[2 * i + 2];
                          node[i] = {std::min(a[0], b[0]), std::min(a[1], b[1]),
                                     std::max(a[2], b[2]), std::max(a[3], b[3])};
                        }
                      }
                    });
}

}  // namespace prep::detail
