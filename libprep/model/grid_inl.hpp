// libprep/model/grid_inl.hpp — for_each_cell(): exact-or-conservative
// assignment of a widened segment to the decal grid cells it touches
// (thesis §4.2.1 "Line Segments"). Included by detail.hpp only.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

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

}  // namespace grid_detail

template <class Fn>
void for_each_cell(const GridParams& g, const SegmentShape& s, Fn&& fn) {
  int64_t ix0, iy0, ix1, iy1;
  if (!cell_range(g, s.box, ix0, iy0, ix1, iy1)) return;
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

}  // namespace prep::detail
