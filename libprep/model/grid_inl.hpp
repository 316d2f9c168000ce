// libprep/model/grid_inl.hpp — for_each_cell(): exact-or-conservative
// assignment of a widened segment to the decal grid cells it touches
// (thesis §4.2.1 "Line Segments"). Included by detail.hpp only.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace prep::detail {
namespace grid_detail {

// Clips the polygon (px, py, n) against y >= lim (keep_above) or y <= lim,
// Sutherland-Hodgman; returns the new vertex count.
inline int clip_y(double* px, double* py, int n, double lim, bool keep_above) {
  double ox[16], oy[16];
  int m = 0;
  for (int i = 0; i < n; ++i) {
    int j = (i + 1) % n;
    double ya = py[i], yb = py[j];
    bool ina = keep_above ? ya >= lim : ya <= lim;
    bool inb = keep_above ? yb >= lim : yb <= lim;
    if (ina) {
      ox[m] = px[i];
      oy[m] = ya;
      ++m;
    }
    if (ina != inb) {
      double t = (lim - ya) / (yb - ya);
      ox[m] = px[i] + t * (px[j] - px[i]);
      oy[m] = lim;
      ++m;
    }
  }
  std::copy(ox, ox + m, px);
  std::copy(oy, oy + m, py);
  return m;
}

// x-extent of a triangle inside the horizontal band [y0, y1].
inline void triangle_band_extent(const std::array<double, 6>& t, double y0, double y1, double& xmin,
                                 double& xmax) {
  double px[16] = {t[0], t[2], t[4]}, py[16] = {t[1], t[3], t[5]};
  int n = clip_y(px, py, 3, y0, true);
  if (n == 0) return;
  n = clip_y(px, py, n, y1, false);
  for (int i = 0; i < n; ++i) {
    xmin = std::min(xmin, px[i]);
    xmax = std::max(xmax, px[i]);
  }
}

// Conservative x-extent of the capsule (a, b, hw) inside the band [y0, y1]:
// the part of a-b within [y0 - hw, y1 + hw], widened by hw.
inline void capsule_band_extent(double ax, double ay, double bx, double by, double hw, double y0,
                                double y1, double& xmin, double& xmax) {
  if (ay > by) {
    std::swap(ax, bx);
    std::swap(ay, by);
  }
  double lo = y0 - hw, hi = y1 + hw;
  if (by < lo || ay > hi) return;
  double t0 = 0, t1 = 1;
  if (by > ay) {
    if (ay < lo) t0 = (lo - ay) / (by - ay);
    if (by > hi) t1 = (hi - ay) / (by - ay);
  }
  double xs = ax + t0 * (bx - ax), xe = ax + t1 * (bx - ax);
  xmin = std::min(xmin, std::min(xs, xe) - hw);
  xmax = std::max(xmax, std::max(xs, xe) + hw);
}

// floor(a / b) for b > 0 and |a| < 2^52: one double division, corrected
// to the exact integer quotient (cell_range runs per primitive and per
// candidate grid; a 64-bit integer division or a libm floor call costs
// several times more).
inline int64_t floor_div(int64_t a, int64_t b) {
  int64_t q = int64_t(double(a) / double(b));  // truncated: floor, or one above it
  while (q * b > a) --q;
  while ((q + 1) * b <= a) ++q;
  return q;
}

}  // namespace grid_detail

inline bool cell_range(const GridParams& g, const QBox& b, int64_t& ix0, int64_t& iy0, int64_t& ix1,
                       int64_t& iy1) {
  using grid_detail::floor_div;
  if (g.nx == 0 || g.ny == 0 || b.empty()) return false;
  ix0 = floor_div(b.x0 - 1 - g.origin_x, g.cell_w);
  ix1 = floor_div(b.x1 + 1 - g.origin_x, g.cell_w);
  iy0 = floor_div(b.y0 - 1 - g.origin_y, g.cell_h);
  iy1 = floor_div(b.y1 + 1 - g.origin_y, g.cell_h);
  if (ix1 < 0 || iy1 < 0 || ix0 >= int64_t(g.nx) || iy0 >= int64_t(g.ny)) return false;
  ix0 = std::max<int64_t>(ix0, 0);
  iy0 = std::max<int64_t>(iy0, 0);
  ix1 = std::min<int64_t>(ix1, g.nx - 1);
  iy1 = std::min<int64_t>(iy1, g.ny - 1);
  return true;
}

// floor(a / b) for a fixed b > 0 (|a| < 2^52): a product with 1/b, corrected
// to the exact integer quotient (grid_detail::floor_div, without its
// division: the grid counts take it four times per item and grid).
struct FloorDiv {
  int64_t b = 1;
  double inv = 1.0;
  explicit FloorDiv(int64_t divisor) : b(divisor), inv(1.0 / double(divisor)) {}
  int64_t operator()(int64_t a) const {
    int64_t q = int64_t(double(a) * inv);
    while (q * b > a) --q;
    while ((q + 1) * b <= a) ++q;
    return q;
  }
};

// A box of quanta in 32 bits (every stored position fits, kMaxQuanta).
struct Box32 {
  int32_t x0, y0, x1, y1;
};

// A grid with its divisions prepared: the cell range of a box as
// cell_range() gives it.
struct GridMap {
  const GridParams& g;
  FloorDiv dx, dy;
  explicit GridMap(const GridParams& grid) : g(grid), dx(grid.cell_w), dy(grid.cell_h) {}
  // Rows [iy0, iy1] of the expanded box b, unclamped.
  void rows(const Box32& b, int64_t& iy0, int64_t& iy1) const {
    iy0 = dy(int64_t(b.y0) - 1 - g.origin_y);
    iy1 = dy(int64_t(b.y1) + 1 - g.origin_y);
  }
  // cell_range(): the clamped cells of the expanded box b; false when outside.
  bool range(const Box32& b, int64_t& ix0, int64_t& iy0, int64_t& ix1, int64_t& iy1) const {
    if (g.nx == 0 || g.ny == 0 || b.x0 > b.x1 || b.y0 > b.y1) return false;
    rows(b, iy0, iy1);
    if (iy1 < 0 || iy0 >= int64_t(g.ny) || !columns(b, ix0, ix1)) return false;
    iy0 = std::max<int64_t>(iy0, 0);
    iy1 = std::min<int64_t>(iy1, int64_t(g.ny) - 1);
    return true;
  }
  // Columns [ix0, ix1] of the expanded box b, clamped; false when outside.
  bool columns(const Box32& b, int64_t& ix0, int64_t& ix1) const {
    ix0 = dx(int64_t(b.x0) - 1 - g.origin_x);
    ix1 = dx(int64_t(b.x1) + 1 - g.origin_x);
    if (ix1 < 0 || ix0 >= int64_t(g.nx)) return false;
    ix0 = std::max<int64_t>(ix0, 0);
    ix1 = std::min<int64_t>(ix1, int64_t(g.nx) - 1);
    return true;
  }
};

// A QBox in 32 bits (boxes of stored positions, |coordinate| <= kMaxQuanta).
inline Box32 box32(const QBox& b) {
  return {int32_t(b.x0), int32_t(b.y0), int32_t(b.x1), int32_t(b.y1)};
}

template <class Fn>
void for_each_cell_in_rows(const GridParams& g, const SegmentShape& s, int64_t row0, int64_t row1,
                           Fn&& fn) {
  int64_t ix0, iy0, ix1, iy1;
  if (!cell_range(g, s.box, ix0, iy0, ix1, iy1)) return;
  iy0 = std::max(iy0, row0);
  iy1 = std::min(iy1, row1);
  for (int64_t iy = iy0; iy <= iy1; ++iy) {
    // Cell rows are closed boxes expanded by one quantum (the margin that
    // absorbs the evaluator's rounding when it locates a point).
    double y0 = double(g.origin_y + iy * g.cell_h) - 1.0;
    double y1 = double(g.origin_y + (iy + 1) * g.cell_h) + 1.0;
    double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
    for (int k = 0; k < s.ntri; ++k)
      grid_detail::triangle_band_extent(s.tri[k], y0, y1, xmin, xmax);
    if (s.capsule)
      grid_detail::capsule_band_extent(s.ax, s.ay, s.bx, s.by, s.hw, y0, y1, xmin, xmax);
    if (!(xmin <= xmax)) continue;
    int64_t a = int64_t(std::floor((xmin - 1.0 - double(g.origin_x)) / double(g.cell_w)));
    int64_t b = int64_t(std::floor((xmax + 1.0 - double(g.origin_x)) / double(g.cell_w)));
    a = std::max(a, ix0);
    b = std::min(b, ix1);
    for (int64_t ix = a; ix <= b; ++ix) fn(uint32_t(ix + int64_t(g.nx) * iy));
  }
}

template <class Fn>
void for_each_cell(const GridParams& g, const SegmentShape& s, Fn&& fn) {
  for_each_cell_in_rows(g, s, 0, int64_t(g.ny) - 1, std::forward<Fn>(fn));
}

}  // namespace prep::detail
