// Disjoint sets over 0..n-1 for clean's detail units (the validity sweep's
// graph of rings and touch points, the repair's hole groups): path halving,
// and the smaller index is always the root, so the sets and their roots do
// not depend on the order the joins come in.
#pragma once

#include <cstdint>
#include <numeric>
#include <vector>

namespace prep::detail {

struct UnionFind {
  std::vector<uint32_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0u); }
  uint32_t find(uint32_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  }
  // Joins the sets of a and b; false when they were one set already.
  bool unite(uint32_t a, uint32_t b) {
    a = find(a);
    b = find(b);
    if (a == b) return false;
    if (a < b)
      parent[b] = a;
    else
      parent[a] = b;
    return true;
  }
};

}  // namespace prep::detail
