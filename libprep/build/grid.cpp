// libprep/build/grid.cpp — quantisation and the decal grid (thesis §4.2.1
// "Decal Grid", Eq. 4.3/4.4).
#include <algorithm>
#include <cmath>
#include <sstream>

#include "detail.hpp"
#include "prep/error.hpp"

namespace prep::detail {

QPoint quantise(const Point2& p, double& max_err, const std::string& where) {
  if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
    std::ostringstream m;
    m << "build: " << where << ": non-finite coordinate (" << p.x << ", " << p.y << ")";
    throw input_error(m.str());
  }
  double qx = p.x / decal::kQuantumMetres, qy = p.y / decal::kQuantumMetres;
  if (std::fabs(qx) > double(kMaxQuanta) || std::fabs(qy) > double(kMaxQuanta)) {
    std::ostringstream m;
    m.precision(12);
    m << "build: " << where << ": vertex (" << p.x << ", " << p.y
      << ") m lies more than 2147 km from the package origin; int32 millimetre positions "
         "cannot hold it (split the scene into tiles)";
    throw resource_error(m.str());
  }
  QPoint q{std::llround(qx), std::llround(qy)};
  double ex = double(q.x) * decal::kQuantumMetres - p.x;
  double ey = double(q.y) * decal::kQuantumMetres - p.y;
  max_err = std::max(max_err, std::hypot(ex, ey));
  return q;
}

namespace {
int64_t floor_div(int64_t a, int64_t b) {
  int64_t q = a / b;
  if ((a % b != 0) && ((a < 0) != (b < 0))) --q;
  return q;
}
}  // namespace

bool cell_range(const GridParams& g, const QBox& b, int64_t& ix0, int64_t& iy0, int64_t& ix1,
                int64_t& iy1) {
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

namespace {

GridParams grid_with_cell(const QBox& e, int64_t cw, int64_t ch) {
  GridParams g;
  g.origin_x = e.x0;
  g.origin_y = e.y0;
  g.cell_w = std::max<int64_t>(cw, 1);
  g.cell_h = std::max<int64_t>(ch, 1);
  int64_t w = e.x1 - e.x0 + 1, h = e.y1 - e.y0 + 1;
  g.nx = uint32_t((w + g.cell_w - 1) / g.cell_w);
  g.ny = uint32_t((h + g.cell_h - 1) / g.cell_h);
  return g;
}

// Entry-weighted mean number of primitives per cell of grid `g` for the
// primitive boxes, counted with a 2D difference array (O(primitives + cells)).
double weighted_mean_per_cell(const GridParams& g, const std::vector<QBox>& prims,
                              const std::vector<float>& weights) {
  const size_t nx = g.nx, ny = g.ny;
  std::vector<double> diff((nx + 1) * (ny + 1), 0);
  for (size_t i = 0; i < prims.size(); ++i) {
    int64_t x0, y0, x1, y1;
    if (!cell_range(g, prims[i], x0, y0, x1, y1)) continue;
    const double w = weights[i];
    diff[y0 * (nx + 1) + x0] += w;
    diff[y0 * (nx + 1) + x1 + 1] -= w;
    diff[(y1 + 1) * (nx + 1) + x0] -= w;
    diff[(y1 + 1) * (nx + 1) + x1 + 1] += w;
  }
  double entries = 0, squares = 0;
  std::vector<double> row(nx + 1, 0);
  for (size_t y = 0; y < ny; ++y) {
    double run = 0;
    for (size_t x = 0; x < nx; ++x) {
      run += diff[y * (nx + 1) + x];
      row[x] += run;
      entries += row[x];
      squares += row[x] * row[x];
    }
  }
  // Weighted by the entries themselves: the list length a random primitive
  // (so, roughly, a random covered point) shares its cell with. Dense areas
  // dominate, as they dominate the query cost.
  return entries > 0 ? squares / entries : 0.0;
}

// Cell entries the primitive boxes make on grid `g` (O(primitives)).
double entry_count(const GridParams& g, const std::vector<QBox>& prims) {
  double entries = 0;
  for (const QBox& b : prims) {
    int64_t x0, y0, x1, y1;
    if (cell_range(g, b, x0, y0, x1, y1)) entries += double(x1 - x0 + 1) * double(y1 - y0 + 1);
  }
  return entries;
}

}  // namespace

GridParams choose_grid(const QBox& e, const std::vector<QBox>& prims,
                       const std::vector<float>& weights, const BuildOptions& o) {
  if (e.empty()) return GridParams{};
  const double w = double(e.x1 - e.x0 + 1), h = double(e.y1 - e.y0 + 1);
  if (o.grid_nx > 0 && o.grid_ny > 0) {
    // Thesis §4.2.1: a fixed number of cells over the data's AABB (500x500).
    return grid_with_cell(e, int64_t(std::ceil(w / o.grid_nx)), int64_t(std::ceil(h / o.grid_ny)));
  }
  // Adaptive: square cells whose size makes the entry-weighted mean number
  // of (weighted) primitives per cell approach target_per_cell. Start from a uniform-density
  // guess and correct with the measured occupancy (clustered data occupies
  // few cells, so the uniform guess is far too coarse for it).
  const double target = std::max<uint32_t>(o.target_per_cell, 1);
  const double n = std::max<double>(double(prims.size()), 1.0);
  const double max_cells = std::max<uint32_t>(o.max_cells, 1);
  const double min_side = std::sqrt(w * h / max_cells);
  double side = std::max(std::sqrt(w * h * target / n), min_side);
  // Cell-entry budget: where primitives overlap heavily (10^5 collinear
  // 1 cm segments of a 2 m wide line), no cell size reaches the target and
  // shrinking cells only multiplies the entries (each box then covers
  // (box/side)^2 cells: ~10^9 entries, tens of GB). Grids over the budget
  // are refused and the search moves to larger cells.
  const double entry_budget = std::max(64.0 * n, double(1u << 22));
  GridParams best = grid_with_cell(e, int64_t(std::ceil(side)), int64_t(std::ceil(side)));
  double best_score = std::numeric_limits<double>::infinity();
  bool best_in_budget = false;
  for (int it = 0; it < 64 && (it < 8 || !best_in_budget); ++it) {
    GridParams g = grid_with_cell(e, int64_t(std::ceil(side)), int64_t(std::ceil(side)));
    if (double(g.nx) * double(g.ny) > max_cells) {
      side *= 1.05;
      continue;
    }
    if (entry_count(g, prims) > entry_budget) {
      side *= 2;
      continue;
    }
    best_in_budget = true;
    double mean = weighted_mean_per_cell(g, prims, weights);
    double score = mean > 0 ? std::fabs(std::log(mean / target)) : 0.0;
    if (score < best_score) {
      best_score = score;
      best = g;
    }
    if (mean <= 0 || score < 0.1) break;
    double f = std::clamp(std::sqrt(target / mean), 0.5, 2.0);
    side = std::max(side * f, min_side);
    if (side < 1.0) side = 1.0;
  }
  if (!best_in_budget) {
    throw resource_error("build: decal grid: no cell size keeps the segment/cell entries under " +
                         std::to_string(uint64_t(entry_budget)) +
                         " (primitives overlap too much; raise --resolution to simplify the lines)");
  }
  return best;
}

}  // namespace prep::detail
