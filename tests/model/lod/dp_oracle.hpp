// Test oracle: plain recursive Douglas-Peucker in double precision, written
// independently of libprep/model/lod (tests/model/lod/test_lod_dp.cpp,
// tests/render/test_lod_gpu.cpp).
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace lodtest {

using Pt = std::array<double, 2>;

// Distance from p to the segment a-b.
inline double oracle_distance(const Pt& p, const Pt& a, const Pt& b) {
  const double abx = b[0] - a[0], aby = b[1] - a[1];
  const double len2 = abx * abx + aby * aby;
  if (len2 == 0) return std::hypot(p[0] - a[0], p[1] - a[1]);
  double t = ((p[0] - a[0]) * abx + (p[1] - a[1]) * aby) / len2;
  if (t < 0) t = 0;
  if (t > 1) t = 1;
  return std::hypot(p[0] - (a[0] + t * abx), p[1] - (a[1] + t * aby));
}

// Keeps the points DP keeps at tolerance eps; records every split distance
// it looks at in *seen (so a test can keep eps away from them).
inline void oracle_dp(const std::vector<Pt>& p, size_t first, size_t last, double eps,
                      std::vector<bool>& keep, std::vector<double>* seen) {
  if (last <= first + 1) return;
  size_t best = first + 1;
  double best_d = -1;
  for (size_t i = first + 1; i < last; ++i) {
    const double d = oracle_distance(p[i], p[first], p[last]);
    if (d > best_d) {
      best_d = d;
      best = i;
    }
  }
  if (seen) seen->push_back(best_d);
  if (best_d > eps) {
    keep[best] = true;
    oracle_dp(p, first, best, eps, keep, seen);
    oracle_dp(p, best, last, eps, keep, seen);
  }
}

}  // namespace lodtest
