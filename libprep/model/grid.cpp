// libprep/model/grid.cpp — quantisation and the decal grid (thesis §4.2.1
// "Decal Grid", Eq. 4.3/4.4).
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>

#include "detail.hpp"
#include "prep/error.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace prep::detail {

QPoint quantise(const Point2& p, double& max_err, const WhereFn& where) {
  if (!std::isfinite(p.x) || !std::isfinite(p.y)) {
    std::ostringstream m;
    m << where() << ": non-finite coordinate (" << p.x << ", " << p.y << ")";
    fail<input_error>(kBuildStage, m.str());
  }
  double qx = p.x / decal::kQuantumMetres, qy = p.y / decal::kQuantumMetres;
  if (std::fabs(qx) > double(kMaxQuanta) || std::fabs(qy) > double(kMaxQuanta)) {
    std::ostringstream m;
    m.precision(12);
    m << where() << ": vertex (" << p.x << ", " << p.y
      << ") m lies more than 2147 km from the package origin; int32 millimetre positions "
         "cannot hold it (split the scene into tiles)";
    fail<resource_error>(kBuildStage, m.str());
  }
  QPoint q{std::llround(qx), std::llround(qy)};
  double ex = double(q.x) * decal::kQuantumMetres - p.x;
  double ey = double(q.y) * decal::kQuantumMetres - p.y;
  max_err = std::max(max_err, std::hypot(ex, ey));
  return q;
}

namespace {

// Shaders and the evaluator compute cell corners in int32 quanta
// (formats/SPEC.md "Grid"): the grid ends below 2^31 on each axis. A square
// cell larger than the data across an axis (a strip one row high, at the
// edge of the range) is cut to the data there; what still ends past 2^31
// moves its origin down by the excess.
void fit_axis_in_int32(int64_t& origin, int64_t& cell, uint32_t n, int64_t span) {
  constexpr int64_t kEnd = int64_t(1) << 31;
  if (origin + cell * int64_t(n) < kEnd) return;
  cell = std::max<int64_t>(1, (span + n - 1) / n);
  if (origin + cell * int64_t(n) >= kEnd) origin = kEnd - 1 - cell * int64_t(n);
}

GridParams grid_with_cell(const QBox& e, int64_t cw, int64_t ch) {
  GridParams g;
  g.origin_x = e.x0;
  g.origin_y = e.y0;
  g.cell_w = std::max<int64_t>(cw, 1);
  g.cell_h = std::max<int64_t>(ch, 1);
  int64_t w = e.x1 - e.x0 + 1, h = e.y1 - e.y0 + 1;
  g.nx = uint32_t((w + g.cell_w - 1) / g.cell_w);
  g.ny = uint32_t((h + g.cell_h - 1) / g.cell_h);
  fit_axis_in_int32(g.origin_x, g.cell_w, g.nx, w);
  fit_axis_in_int32(g.origin_y, g.cell_h, g.ny, h);
  return g;
}

// Query-cost weights of the primitives: a line entry costs more per query
// than a polygon entry (segment test and a deeper, less coherent BVH),
// measured with bench_build. grid_row() counts them in thirds (3 and 2).
constexpr float kLineWeight = 1.0f, kPolygonWeight = 2.0f / 3.0f;

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

// Cell entries the primitive boxes make on grid `g` (O(primitives), in
// parallel; an integer sum, so the same at any thread count).
double entry_count(const GridParams& g, const std::vector<QBox>& prims) {
  return double(tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, prims.size(), 1 << 14), uint64_t(0),
      [&](const tbb::blocked_range<size_t>& r, uint64_t acc) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          int64_t x0, y0, x1, y1;
          if (cell_range(g, prims[i], x0, y0, x1, y1)) acc += uint64_t(x1 - x0 + 1) * (y1 - y0 + 1);
        }
        return acc;
      },
      std::plus<uint64_t>()));
}

// Nodes of one cell's implicit BVH with n leaves (bvh.cpp: 2P - 1 for
// P = next power of two >= n).
uint64_t bvh_nodes(uint32_t n) {
  return n == 0 ? 0 : 2 * uint64_t(std::bit_ceil(n)) - 1;
}

// One candidate grid, measured.
struct Candidate {
  GridParams g;
  bool feasible = false;  // within max_cells, the entry budget and the size budget
  double proxy = 0;       // entry-weighted mean of weighted primitives per cell
  double bytes = 0;       // static package bytes (geometry + grid), exact but for holes
  double score = 0;       // the cost minimised (lower is better)
  int64_t stride = 1;     // row sample counted (sample_stride); 1: bytes exact
};

// Items (segment shapes or solid quad-tree leaves) binned once by y, in
// buckets of height `height`: each item, with a copy of its box and a tag
// (its shape, or its leaf's ring), in the bucket of its lowest y (its box
// expanded by one quantum, as cell_range expands it), in item order within a
// bucket; and each bucket's list of the items from lower buckets that reach
// into it; items taller than kMaxSpan buckets apart, offered to every row. A
// cell row of any grid with origin y0 then reads the items that can meet it
// nearly in sequence, each once. O(items) to build; `items(fn)` calls
// fn(tag, box) for every item, in item order (twice).
class YBins {
 public:
  struct Item {
    Box32 box;
    uint32_t tag;
  };
  // Items that reach more than kMaxSpan buckets are kept apart, in tall().
  static constexpr size_t kMaxSpan = 4;
  template <class Items>
  YBins(const Items& items, int64_t y0, int64_t y1, int64_t height)
      : y0_(y0), div_(std::max<int64_t>(height, 1)) {
    count_ = size_t(div_(y1 + 1 - y0_)) + 1;
    first_.assign(count_ + 1, 0);
    span_first_.assign(count_ + 1, 0);
    items([&](uint32_t tag, const QBox& b) {
      if (b.empty()) return;
      const size_t b0 = bucket(b.y0 - 1), b1 = bucket(b.y1 + 1);
      if (b1 - b0 >= kMaxSpan) {
        tall_.push_back({box32(b), tag});
        return;
      }
      ++first_[b0 + 1];
      for (size_t k = b0 + 1; k <= b1; ++k) ++span_first_[k + 1];
    });
    for (size_t k = 0; k < count_; ++k) {
      first_[k + 1] += first_[k];
      span_first_[k + 1] += span_first_[k];
    }
    item_.resize(first_[count_]);
    span_.resize(span_first_[count_]);
    std::vector<uint64_t> fill(first_.begin(), first_.end() - 1);
    std::vector<uint64_t> span_fill(span_first_.begin(), span_first_.end() - 1);
    items([&](uint32_t tag, const QBox& b) {
      if (b.empty()) return;
      const size_t b0 = bucket(b.y0 - 1), b1 = bucket(b.y1 + 1);
      if (b1 - b0 >= kMaxSpan) return;
      const uint64_t at = fill[b0]++;
      item_[at] = {box32(b), tag};
      for (size_t k = b0 + 1; k <= b1; ++k) span_[span_fill[k]++] = at;
    });
  }
  size_t bucket(int64_t y) const {
    const int64_t k = div_(y - y0_);
    return size_t(std::clamp<int64_t>(k, 0, int64_t(count_) - 1));
  }
  // Calls fn(item) once for every item whose expanded box meets the y-range
  // [ylo, yhi] (by buckets: the caller tests the box exactly).
  template <class Fn>
  void for_each(int64_t ylo, int64_t yhi, Fn&& fn) const {
    const size_t bl = bucket(ylo), bh = bucket(yhi);
    for (uint64_t j = span_first_[bl]; j < span_first_[bl + 1]; ++j) fn(item_[span_[j]]);
    for (uint64_t j = first_[bl]; j < first_[bh + 1]; ++j) fn(item_[j]);
    for (const Item& t : tall_) fn(t);
  }
  size_t tall() const { return tall_.size(); }
  template <class Fn>
  void for_each_tall(Fn&& fn) const {
    for (const Item& t : tall_) fn(t);
  }

 private:
  int64_t y0_;
  FloorDiv div_;
  size_t count_ = 0;
  std::vector<uint64_t> first_, span_first_;
  std::vector<Item> item_;
  std::vector<uint64_t> span_;  // positions in item_
  std::vector<Item> tall_;      // items over kMaxSpan buckets, met by every row
};

// What choose_grid() counts grids on: the segment shapes and the solid
// leaves (tagged with their ring) binned by y once. The primitives of the
// query-cost proxy are the shapes' boxes and the exterior rings' leaves.
struct GridBins {
  const GridInput* in = nullptr;
  std::optional<YBins> shapes, leaves;
  size_t n_leaves = 0, n_exterior_leaves = 0, tall_exterior_leaves = 0;
  // Few tall items (shapes, primitives and leaves counted apart, as the
  // proxy's primitives repeat the shapes and the exterior leaves): a
  // sampled row then reads about its share of the items.
  bool sampling() const {
    const size_t ns = in->shapes->size();
    const size_t n = ns + (ns + n_exterior_leaves) + n_leaves;
    const size_t tall = shapes->tall() + (shapes->tall() + tall_exterior_leaves) + leaves->tall();
    return 16 * tall <= n;
  }
};

GridBins bin_inputs(const GridInput& in, int64_t height) {
  GridBins b;
  b.in = &in;
  const int64_t y0 = in.extent.y0, y1 = in.extent.y1;
  const std::vector<SegmentShape>& shapes = *in.shapes;
  b.shapes.emplace(
      [&](auto&& fn) {
        for (size_t i = 0; i < shapes.size(); ++i) fn(uint32_t(i), shapes[i].box);
      },
      y0, y1, height);
  const std::vector<ivec4>& node_box = *in.node_box;
  b.leaves.emplace(
      [&](auto&& fn) {
        for (size_t r = 0; r < in.ring_leaves->size(); ++r)
          for (uint32_t n : (*in.ring_leaves)[r]) {
            const ivec4& nb = node_box[n];
            fn(uint32_t(r), QBox{nb[0], nb[1], nb[2], nb[3]});
          }
      },
      y0, y1, height);
  for (size_t r = 0; r < in.ring_leaves->size(); ++r) {
    const size_t k = (*in.ring_leaves)[r].size();
    b.n_leaves += k;
    if (!(*in.ring_is_hole)[r]) b.n_exterior_leaves += k;
  }
  // The exterior leaves among the tall ones.
  b.leaves->for_each_tall([&](const YBins::Item& it) {
    if (!(*in.ring_is_hole)[it.tag]) ++b.tall_exterior_leaves;
  });
  return b;
}

// What one cell row of a grid holds (grid_row()).
struct RowCounts {
  uint64_t seg_entries = 0, poly_entries = 0, holes = 0, boxes = 0;
  uint64_t prim_entries = 0, weighted = 0;  // primitive-box entries; their weights in thirds
  __extension__ unsigned __int128 weighted_squares = 0;
};

// Per-thread buffers of grid_row(): per-column counts and a set of the
// (ring, column) pairs a row has counted (open addressing; a slot is free
// unless its stamp is the row's).
struct RowScratch {
  std::vector<uint32_t> seg, poly, weight;
  std::vector<uint64_t> key;
  std::vector<uint32_t> stamp;
  uint32_t now = 0;
  size_t used = 0;
  void start_row(size_t nx) {
    seg.assign(nx, 0);
    poly.assign(nx, 0);
    weight.assign(nx, 0);
    if (key.empty()) {
      key.assign(1024, 0);
      stamp.assign(1024, 0);
    }
    if (++now == 0) {  // stamps wrapped: clear them
      std::fill(stamp.begin(), stamp.end(), 0u);
      now = 1;
    }
    used = 0;
  }
  static size_t slot_of(uint64_t k, size_t mask) {
    return size_t((k * 0x9E3779B97F4A7C15ULL) >> 20) & mask;
  }
  // True when `k` was not yet in the set (and adds it).
  bool insert(uint64_t k) {
    if (2 * (used + 1) > key.size()) grow();
    const size_t mask = key.size() - 1;
    for (size_t s = slot_of(k, mask);; s = (s + 1) & mask) {
      if (stamp[s] != now) {
        stamp[s] = now;
        key[s] = k;
        ++used;
        return true;
      }
      if (key[s] == k) return false;
    }
  }
  // Doubles the table, keeping the row's keys.
  void grow() {
    std::vector<uint64_t> old_key(2 * key.size(), 0);  // swapped below: then the old keys
    std::vector<uint32_t> old_stamp(2 * key.size(), 0);
    old_key.swap(key);
    old_stamp.swap(stamp);
    const size_t mask = key.size() - 1;
    for (size_t i = 0; i < old_key.size(); ++i) {
      if (old_stamp[i] != now) continue;
      size_t s = slot_of(old_key[i], mask);
      while (stamp[s] == now) s = (s + 1) & mask;
      stamp[s] = now;
      key[s] = old_key[i];
    }
  }
};

// Counts row iy of grid `g` exactly, the way build_model() assigns
// primitives: segments by their exact shapes (for_each_cell), each ring's
// solid leaves to the distinct cells they touch; and the primitive boxes per
// cell weighted in thirds (a line box 3, an exterior polygon leaf 2; the
// query-cost weights 1 and 2/3 of choose_model_grid: integer sums, the same
// at any thread count).
RowCounts grid_row(const GridMap& map, const GridBins& bins, int64_t iy, RowScratch& s) {
  const GridInput& in = *bins.in;
  const GridParams& g = map.g;
  const size_t nx = g.nx;
  // Rows are closed and expanded by one quantum: a box meets row iy when
  // its y-range meets [ylo, yhi].
  const int64_t ylo = g.origin_y + iy * g.cell_h, yhi = ylo + g.cell_h - 1;
  s.start_row(nx);
  RowCounts rc;
  bins.shapes->for_each(ylo, yhi, [&](const YBins::Item& it) {
    int64_t y0, y1, x0, x1;
    map.rows(it.box, y0, y1);
    if (iy < y0 || iy > y1 || !map.columns(it.box, x0, x1)) return;
    rc.prim_entries += uint64_t(x1 - x0 + 1);
    for (int64_t ix = x0; ix <= x1; ++ix) s.weight[size_t(ix)] += 3;
    y0 = std::max<int64_t>(y0, 0);
    y1 = std::min<int64_t>(y1, int64_t(g.ny) - 1);
    // A shape whose box lies in one cell meets exactly that cell (the shape
    // is inside its box): no band clipping.
    if (x0 == x1 && y0 == iy && y1 == iy) {
      ++s.seg[size_t(x0)];
      return;
    }
    for_each_cell_in_rows(g, (*in.shapes)[it.tag], iy, iy,
                          [&](uint32_t c) { ++s.seg[c - size_t(iy) * nx]; });
  });
  const std::vector<uint8_t>& is_hole = *in.ring_is_hole;
  bins.leaves->for_each(ylo, yhi, [&](const YBins::Item& it) {
    int64_t y0, y1, x0, x1;
    map.rows(it.box, y0, y1);
    if (iy < y0 || iy > y1 || !map.columns(it.box, x0, x1)) return;
    const bool hole = is_hole[it.tag];
    if (!hole) {
      rc.prim_entries += uint64_t(x1 - x0 + 1);
      for (int64_t ix = x0; ix <= x1; ++ix) s.weight[size_t(ix)] += 2;
    }
    for (int64_t ix = x0; ix <= x1; ++ix) {
      if (!s.insert(uint64_t(it.tag) << 32 | uint64_t(ix))) continue;
      if (hole)
        ++rc.holes;
      else
        ++s.poly[size_t(ix)];
    }
  });
  for (size_t x = 0; x < nx; ++x) {
    rc.seg_entries += s.seg[x];
    rc.poly_entries += s.poly[x];
    rc.boxes += bvh_nodes(s.seg[x]) + bvh_nodes(s.poly[x]);
    rc.weighted += s.weight[x];
    rc.weighted_squares += uint64_t(s.weight[x]) * s.weight[x];
  }
  return rc;
}

// A grid's counts from its rows (grid_bytes()).
struct GridCount {
  double bytes = 0;    // static bytes of the grid-dependent blobs (scaled when sampled)
  double proxy = 0;    // entry-weighted mean of weighted primitive boxes per cell
  double entries = 0;  // primitive-box cell entries (scaled when sampled)
};

// Static bytes the grid-dependent blobs take on grid `g`: per cell,
// cell_segment_range + cell_poly_range (uvec2 each) and line/poly BVH ranges
// (uvec4 each); per entry: cell_segments (uvec2), cell_polys (uvec4),
// cell_holes (uvec2, counted for every (cell, hole) pair: an upper bound);
// per cell and kind: the implicit BVH's 2P - 1 boxes (ivec4). Rows counted
// by grid_row(), in parallel, summed in row order; with stride 1 the exact
// count of exact_grid_bytes.
//
// With stride > 1 only the rows iy % stride == 0 are counted (those cells'
// lists and BVHs exactly) and the entries and boxes are scaled by rows /
// sampled rows: an estimate at about 1/stride of the work. On the same rows:
// the entry-weighted mean of weighted primitive boxes per cell (the
// counterpart of weighted_mean_per_cell) and the scaled count of
// primitive-box cell entries (the counterpart of entry_count).
GridCount grid_bytes(const GridParams& g, const GridBins& bins, int64_t stride) {
  const size_t rows = (size_t(g.ny) + size_t(stride) - 1) / size_t(stride);
  std::vector<RowCounts> per_row(rows);
  const GridMap map(g);
  tbb::enumerable_thread_specific<RowScratch> scratch;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rows), [&](const tbb::blocked_range<size_t>& r) {
    RowScratch& s = scratch.local();
    for (size_t k = r.begin(); k != r.end(); ++k)
      per_row[k] = grid_row(map, bins, int64_t(k) * stride, s);
  });
  RowCounts t;
  for (const RowCounts& r : per_row) {
    t.seg_entries += r.seg_entries;
    t.poly_entries += r.poly_entries;
    t.holes += r.holes;
    t.boxes += r.boxes;
    t.prim_entries += r.prim_entries;
    t.weighted += r.weighted;
    t.weighted_squares += r.weighted_squares;
  }
  const double scale = double(g.ny) / double(rows);
  GridCount c;
  c.proxy = t.weighted > 0 ? double(t.weighted_squares) / double(t.weighted) / 3.0 : 0.0;
  c.entries = double(t.prim_entries) * scale;
  c.bytes = double(g.nx) * g.ny * (8 + 8 + 16 + 16) +
            scale * (double(t.seg_entries) * 8 + double(t.poly_entries) * 16 + double(t.holes) * 8 +
                     double(t.boxes) * 16);
  return c;
}

// Static bytes the grid-dependent blobs take on grid `g`, counted the way
// build_model() assigns primitives: exact segment shapes (for_each_cell) and
// the distinct cells of each ring's solid quad-tree leaves. Per cell:
// cell_segment_range + cell_poly_range (uvec2 each) and line/poly BVH ranges
// (uvec4 each); per entry: cell_segments (uvec2), cell_polys (uvec4),
// cell_holes (uvec2, counted for every (cell, hole) pair: an upper bound);
// per cell and kind: the implicit BVH's 2P - 1 boxes (ivec4). One pass over
// every primitive and every cell. A ring's cells are told apart in a bitmap
// of the cell rectangle its leaves reach (as ring_cell_entries in
// build_model.cpp), else by a sort. `prim_entries`, when not null, receives
// the cell entries of the primitive boxes (entry_count()).
double exact_grid_bytes(const GridParams& g, const GridInput& in,
                        uint64_t* prim_entries = nullptr) {
  const size_t cells = size_t(g.nx) * g.ny;
  std::vector<uint32_t> seg(cells, 0), poly(cells, 0);
  const GridMap map(g);
  const std::vector<SegmentShape>& shapes = *in.shapes;
  const uint64_t shape_entries = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, shapes.size(), 1024), uint64_t(0),
      [&](const tbb::blocked_range<size_t>& r, uint64_t acc) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          // A shape whose box lies in one cell meets exactly that cell (the
          // shape is inside its box): skip the band clipping of for_each_cell.
          const Box32 b = box32(shapes[i].box);
          int64_t x0, y0, x1, y1;
          if (shapes[i].box.empty() || !map.range(b, x0, y0, x1, y1)) continue;
          acc += uint64_t(x1 - x0 + 1) * uint64_t(y1 - y0 + 1);
          if (x0 == x1 && y0 == y1) {
            std::atomic_ref<uint32_t>(seg[size_t(x0 + int64_t(g.nx) * y0)])
                .fetch_add(1, std::memory_order_relaxed);
            continue;
          }
          for_each_cell(g, shapes[i], [&](uint32_t c) {
            std::atomic_ref<uint32_t>(seg[c]).fetch_add(1, std::memory_order_relaxed);
          });
        }
        return acc;
      },
      std::plus<uint64_t>());
  struct Scratch {
    std::vector<std::array<int64_t, 4>> range;  // per leaf: x0, y0, x1, y1
    std::vector<uint8_t> seen;
    std::vector<uint32_t> hit;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  const auto& leaves = *in.ring_leaves;
  const auto [holes, leaf_entries] = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, leaves.size(), 64), std::pair<uint64_t, uint64_t>(0, 0),
      [&](const tbb::blocked_range<size_t>& r, std::pair<uint64_t, uint64_t> acc) {
        Scratch& s = scratch.local();
        for (size_t ring = r.begin(); ring != r.end(); ++ring) {
          const bool hole = (*in.ring_is_hole)[ring];
          s.range.clear();
          int64_t rx0 = std::numeric_limits<int64_t>::max(), ry0 = rx0, rx1 = -1, ry1 = -1;
          uint64_t touched = 0;
          for (uint32_t n : leaves[ring]) {
            const ivec4& nb = (*in.node_box)[n];
            if (nb[0] > nb[2] || nb[1] > nb[3]) continue;
            std::array<int64_t, 4> c;
            if (!map.range({nb[0], nb[1], nb[2], nb[3]}, c[0], c[1], c[2], c[3])) continue;
            s.range.push_back(c);
            rx0 = std::min(rx0, c[0]);
            ry0 = std::min(ry0, c[1]);
            rx1 = std::max(rx1, c[2]);
            ry1 = std::max(ry1, c[3]);
            touched += uint64_t(c[2] - c[0] + 1) * uint64_t(c[3] - c[1] + 1);
          }
          if (touched == 0) continue;
          if (!hole) acc.second += touched;
          auto count = [&](uint32_t cell) {
            if (hole)
              ++acc.first;
            else
              std::atomic_ref<uint32_t>(poly[cell]).fetch_add(1, std::memory_order_relaxed);
          };
          const uint64_t w = uint64_t(rx1 - rx0 + 1), area = w * uint64_t(ry1 - ry0 + 1);
          if (area <= std::max<uint64_t>(4 * touched, 64)) {
            s.seen.assign(area, 0);
            for (const auto& c : s.range)
              for (int64_t iy = c[1]; iy <= c[3]; ++iy)
                for (int64_t ix = c[0]; ix <= c[2]; ++ix) {
                  uint8_t& seen = s.seen[uint64_t(iy - ry0) * w + uint64_t(ix - rx0)];
                  if (seen) continue;
                  seen = 1;
                  count(uint32_t(ix + int64_t(g.nx) * iy));
                }
            continue;
          }
          s.hit.clear();
          for (const auto& c : s.range)
            for (int64_t iy = c[1]; iy <= c[3]; ++iy)
              for (int64_t ix = c[0]; ix <= c[2]; ++ix)
                s.hit.push_back(uint32_t(ix + int64_t(g.nx) * iy));
          std::sort(s.hit.begin(), s.hit.end());
          s.hit.erase(std::unique(s.hit.begin(), s.hit.end()), s.hit.end());
          for (uint32_t cell : s.hit) count(cell);
        }
        return acc;
      },
      [](std::pair<uint64_t, uint64_t> a, std::pair<uint64_t, uint64_t> b) {
        return std::pair<uint64_t, uint64_t>(a.first + b.first, a.second + b.second);
      });
  if (prim_entries) *prim_entries = shape_entries + leaf_entries;
  struct Sums {
    uint64_t seg = 0, poly = 0, boxes = 0;
  };
  const Sums t = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, cells, 1 << 14), Sums{},
      [&](const tbb::blocked_range<size_t>& r, Sums acc) {
        for (size_t c = r.begin(); c != r.end(); ++c) {
          acc.seg += seg[c];
          acc.poly += poly[c];
          acc.boxes += bvh_nodes(seg[c]) + bvh_nodes(poly[c]);
        }
        return acc;
      },
      [](Sums a, const Sums& b) {
        a.seg += b.seg;
        a.poly += b.poly;
        a.boxes += b.boxes;
        return a;
      });
  return double(cells) * (8 + 8 + 16 + 16) + double(t.seg) * 8 + double(t.poly) * 16 +
         double(holes) * 8 + double(t.boxes) * 16;
}

// Row stride of the sample choose_grid() counts a candidate on, from 2^17
// primitives up (kSampleMinPrimitives; below, and where more than a
// sixteenth of the items are tall, every candidate is counted exactly by
// exact_grid_bytes): every 2nd to 32nd row, at least 64 rows (stride 1:
// exact). kSampleMargin: the share of the size budget a sampled count may
// fill.
constexpr double kSampleMargin = 0.99;
constexpr size_t kSampleMinPrimitives = size_t(1) << 17;
int64_t sample_stride(const GridParams& g) {
  return std::clamp<int64_t>(int64_t(g.ny) / 64, 1, 32);
}

constexpr double kBytesWeight = 0.1;    // of log(package bytes) in a grid's cost
constexpr uint32_t kThesisCells = 500;  // per side of the thesis grid

// The adaptive search of choose_grid() (the rule is documented there):
// what it counts candidates against (the budgets, the thesis grid, the
// bins or the primitive list) and every candidate counted.
class GridSearch {
 public:
  GridSearch(const GridInput& in, const ModelOptions& o, ProgressStage& stage)
      : in_(in), o_(o), stage_(stage), e_(in.extent) {
    const double w = double(e_.x1 - e_.x0 + 1), h = double(e_.y1 - e_.y0 + 1);
    // The query-cost primitives: segment boxes and exterior solid-leaf boxes.
    n_prims_ = in.shapes->size();
    for (size_t r = 0; r < in.ring_leaves->size(); ++r)
      if (!(*in.ring_is_hole)[r]) n_prims_ += (*in.ring_leaves)[r].size();
    const double n = std::max<double>(double(n_prims_), 1.0);
    max_cells_ = std::max<uint32_t>(o.max_cells, 1);
    // Cell-entry budget: where primitives overlap heavily (10^5 collinear
    // 1 cm segments of a 2 m wide line), no cell size reaches a low proxy and
    // shrinking cells only multiplies the entries (each box then covers
    // (box/side)^2 cells: ~10^9 entries, tens of GB). Such grids are refused.
    entry_budget_ = std::max(64.0 * n, double(1u << 22));
    // The cell floor (quanta): a candidate finer than it is refused like one
    // over the budgets, so the coarser walk goes on past it.
    min_side_ = o.min_cell_m > 0 ? std::ceil(o.min_cell_m / decal::kQuantumMetres) : 0;
    // Size budget from the thesis grid on the same data.
    thesis_ = grid_with_cell(e_, int64_t(std::ceil(w / kThesisCells)),
                             int64_t(std::ceil(h / kThesisCells)));
    // Large inputs binned by y in buckets of half the thesis cell: a
    // sampled row of any candidate finds its items without a pass over all.
    if (n_prims_ >= kSampleMinPrimitives) {
      bins_.emplace(bin_inputs(in, std::max<int64_t>(1, thesis_.cell_h / 2)));
      if (!bins_->sampling()) bins_.reset();
    }
    // Under a cell cap of a quarter of the thesis cells (a tileset's small
    // tiles, libprep/tile/tileset_build.cpp), every candidate has cells of at
    // least four times the thesis cell's area: fewer cell ranges and fewer
    // duplicated entries than the thesis grid, so the size budget, 1.2x the
    // thesis package, does not bind. Its exact count, one pass over the
    // primitives that cost more than the rest of a 2 km tile's search, is
    // skipped and the budget left open (the tile bytes of
    // bench/tileset_scale.py are the same either way).
    if (4.0 * max_cells_ >= double(thesis_.nx) * double(thesis_.ny)) {
      uint64_t entries = 0;
      thesis_bytes_ = exact_grid_bytes(thesis_, in, &entries);
      if (double(entries) <= entry_budget_)
        byte_budget_ = kGridSizeBudget * (double(in.geometry_bytes) + thesis_bytes_);
    }
    side0_ = std::sqrt(double(thesis_.cell_w) * double(thesis_.cell_h));
  }

  const GridParams& thesis() const { return thesis_; }
  double thesis_bytes() const { return thesis_bytes_; }
  double entry_budget() const { return entry_budget_; }

  // The walks of the ladder: coarser from the thesis side, then finer
  // (with the bisection under the size budget); the best candidate.
  Candidate walk() {
    double best_k = 0;
    Candidate best = walk_coarser(best_k);
    if (best.feasible && !reached(best)) walk_finer(best, best_k);
    return best;
  }

  // A choice made on sampled counts confirmed on exact ones: the chosen
  // candidate, else the next by score, whose exact bytes keep the size
  // budget (one exact count when the sample was right). False, with `best`
  // infeasible, when none does (the thesis grid is then the choice, within
  // the budget by definition).
  bool confirm_exact(Candidate& best) {
    if (!(best.feasible && best.stride > 1 && std::isfinite(byte_budget_))) return true;
    std::vector<Candidate> order;
    for (const Candidate& c : measured_)
      if (c.feasible && (c.g.cell_w != best.g.cell_w)) order.push_back(c);
    std::stable_sort(order.begin(), order.end(),
                     [&](const Candidate& a, const Candidate& b) { return better(a, b); });
    order.insert(order.begin(), best);
    best.feasible = false;
    for (Candidate c : order) {
      if (c.stride > 1) {
        c.bytes = double(in_.geometry_bytes) + exact_grid_bytes(c.g, in_);
        c.stride = 1;
        stage_.add();
      }
      if (c.bytes <= byte_budget_) {
        best = c;
        break;
      }
    }
    return best.feasible;
  }

 private:
  // a strictly better than b
  static bool better(const Candidate& a, const Candidate& b) {
    return a.feasible && (!b.feasible || a.score < b.score);
  }
  bool reached(const Candidate& c) const {
    return o_.target_per_cell > 0 && c.feasible && c.proxy <= o_.target_per_cell;
  }

  // The primitive boxes and weights, listed (once) where a grid is counted
  // without the bins.
  void list_prims() {
    if (!prims_.empty() || n_prims_ == 0) return;
    prims_.reserve(n_prims_);
    weights_.reserve(n_prims_);
    for (const SegmentShape& sh : *in_.shapes) {
      prims_.push_back(sh.box);
      weights_.push_back(kLineWeight);
    }
    for (size_t r = 0; r < in_.ring_leaves->size(); ++r) {
      if ((*in_.ring_is_hole)[r]) continue;
      for (uint32_t nd : (*in_.ring_leaves)[r]) {
        const ivec4& b = (*in_.node_box)[nd];
        prims_.push_back({b[0], b[1], b[2], b[3]});
        weights_.push_back(kPolygonWeight);
      }
    }
  }

  // The candidate of ladder step k (side side0 * 2^(-k/4)): refused
  // (infeasible, not recorded) over max_cells, under the cell floor or over
  // the entry budget; else counted, scored and recorded in `measured_`.
  Candidate measure(double k) {
    Candidate c;
    const int64_t side = std::max<int64_t>(1, int64_t(std::ceil(side0_ * std::pow(2.0, -k / 4.0))));
    c.g = grid_with_cell(e_, side, side);
    if (double(c.g.nx) * double(c.g.ny) > max_cells_ ||
        (double(side) < min_side_ && (c.g.nx > 1 || c.g.ny > 1)))
      return c;
    // Small inputs: exact counts. Large ones: counts on a row sample, the
    // choice confirmed on exact bytes at the end.
    c.stride = bins_ ? sample_stride(c.g) : 1;
    if (c.stride == 1) {
      list_prims();
      if (entry_count(c.g, prims_) > entry_budget_) return Candidate{c.g};
      c.bytes = double(in_.geometry_bytes) + exact_grid_bytes(c.g, in_);
      c.proxy = weighted_mean_per_cell(c.g, prims_, weights_);
    } else {
      const GridCount gc = grid_bytes(c.g, *bins_, c.stride);
      if (gc.entries > entry_budget_) return Candidate{c.g};
      c.bytes = double(in_.geometry_bytes) + gc.bytes;
      c.proxy = gc.proxy;
    }
    c.score = std::log(1.0 + c.proxy) + kBytesWeight * std::log(std::max(c.bytes, 1.0));
    // A sampled count must stay 1% under the budget (its error on the sets
    // of bench/gen_synthetic.py: -0.3% to -0.4%), so that the exact
    // confirmation (confirm_exact) usually passes at the first try.
    c.feasible = c.bytes <= (c.stride > 1 ? kSampleMargin : 1.0) * byte_budget_;
    measured_.push_back(c);
    stage_.add();
    return c;
  }

  // From the thesis side coarser while that is cheaper, while the
  // candidate is refused, or while the target is still met; `best_k`
  // receives the best candidate's step.
  Candidate walk_coarser(double& best_k) {
    Candidate best = measure(0);
    best_k = 0;
    for (int k = -1;; --k) {
      const Candidate c = measure(k);
      const bool go_on = !best.feasible || reached(c);
      if (better(c, best) || reached(c)) {
        best = c;
        best_k = k;
      } else if (!go_on) {
        break;
      }
      if (c.g.nx <= 1 && c.g.ny <= 1) break;
    }
    return best;
  }

  // Finer from step best_k while that is cheaper and the target is not yet
  // reached. When the size budget stops the walk, bisects the last step to
  // land close under it.
  void walk_finer(Candidate& best, double best_k) {
    for (double k = best_k + 1; k < best_k + 64; k += 1) {
      const Candidate c = measure(k);
      if (double(c.g.nx) * double(c.g.ny) > max_cells_) break;
      if (!c.feasible && c.bytes > 0) {  // over the size budget (not refused)
        double lo = k - 1, hi = k;
        for (int it = 0; it < 4; ++it) {
          const double mid = 0.5 * (lo + hi);
          const Candidate m = measure(mid);
          if (m.feasible) {
            if (better(m, best)) best = m;
            lo = mid;
          } else {
            hi = mid;
          }
        }
        break;
      }
      if (!better(c, best)) break;
      best = c;
      if (reached(c) || c.g.cell_w <= 1) break;
    }
  }

  const GridInput& in_;
  const ModelOptions& o_;
  ProgressStage& stage_;
  const QBox& e_;
  size_t n_prims_ = 0;
  double max_cells_ = 1, entry_budget_ = 0, min_side_ = 0;
  GridParams thesis_;
  std::optional<GridBins> bins_;
  std::vector<QBox> prims_;
  std::vector<float> weights_;
  double byte_budget_ = std::numeric_limits<double>::infinity();
  double thesis_bytes_ = 0;
  double side0_ = 0;
  std::vector<Candidate> measured_;  // every candidate counted, in search order
};

}  // namespace

// The adaptive rule (measured with bench/bench_build):
//
// Cost of a grid = log(1 + proxy) + kBytesWeight * log(package bytes). The
// proxy is the entry-weighted mean number of weighted primitives per cell
// (the list a random primitive, so roughly a random covered point, shares
// its cell with: it drives the BVH nodes and, through the culling offsets,
// the quad-tree nodes a query visits); the 1 stands for the work every
// query does whatever the grid (cell fetch, BVH root, the quad-tree leaf).
// The package bytes are the grid-independent blobs plus the cell lists and
// per-cell BVHs counted exactly for that grid (grid_bytes). Finer cells
// lower the proxy until the overlap of the data sets a floor, while the
// bytes grow with the cells (48 B of ranges each, even where empty) and with
// the primitives duplicated across cells (an entry plus its BVH boxes each).
// With kBytesWeight = 0.1 a refinement is taken while it cuts (1 + proxy) by
// more than a tenth of the relative size it adds: sparse data (one polygon)
// stops at a few thousand cells, dense data refines up to the size budget.
//
// Size budget: a candidate is refused when its package would be larger than
// kGridSizeBudget (1.2) times the package of the thesis 500x500 grid on the
// same data (counted the same way), when it has more than max_cells cells,
// or more segment/leaf-cell entries than the entry budget. The thesis grid is
// the reference the package is compared against (the goal: fewer tests per
// point than 500x500 at no more than 1.2x its size). The budget is what
// binds on large dense inputs: with 10^7 clustered polygon vertices, the
// polygons' proxy never falls to a fixed target (their overlap alone keeps
// it above), and the former target-only rule refined to millions of cells,
// where each polygon spans many cells and the duplicated cell_polys entries
// and their BVH boxes plus the per-cell ranges made the package 1.7x the
// thesis grid's.
//
// Search: a ladder of square cell sizes (side steps of 2^(1/4), about 1.41x
// in cells) from the side that gives the thesis's 250 000 cells; coarser
// while the cost falls (or while the candidate is refused), then finer while
// it falls; when the size budget stops the finer walk, the last step is
// bisected four times to land just under the budget.
// Counting: below 2^17 primitives (or with many tall ones) every candidate
// is counted exactly, one pass over the primitives each (exact_grid_bytes).
// Above, the inputs are binned by y once (YBins) and a candidate is counted
// row by row in parallel (grid_row) on every stride-th row (at least 64
// rows, sample_stride) and scaled; a sampled count must keep kSampleMargin
// (99%) of the budget, and the choice is then confirmed on exact bytes
// (falling back to the next candidate by score, else to the thesis grid).
// So the budget holds on exact counts, and the search costs the thesis
// grid's exact count, the confirmation and the sampled counts (at 10^7
// polygon vertices of bench/gen_synthetic.py: the binning about 0.09 s of
// CPU, each exact count 0.08-0.11 s, 13 sampled candidates about 0.01 s
// each).
// options.target_per_cell, when set (> 0; default off), stops refining at
// the first (coarsest) candidate whose proxy reaches it: a smaller package
// for a chosen query cost. options.min_cell_m, when set, refuses every
// candidate with a finer cell side (but a one-cell grid): an overview level
// of a tileset is drawn at pixels no finer than its resolution, so cells
// finer than that buy no pixel a shorter list and cost their ranges and
// duplicated entries.
GridParams choose_grid(const GridInput& in, const ModelOptions& o, double* cell_bytes) {
  // Candidates measured; how many the search takes is known at its end.
  ProgressStage stage(o.progress, "build.grid", 0, "candidates", ProgressTotal::estimate);
  const QBox& e = in.extent;
  if (cell_bytes) *cell_bytes = 0;
  if (e.empty()) return GridParams{};
  if (o.grid_nx > 0 && o.grid_ny > 0) {
    stage.add();
    // Thesis §4.2.1: a fixed number of cells over the data's AABB (500x500).
    const double w = double(e.x1 - e.x0 + 1), h = double(e.y1 - e.y0 + 1);
    const GridParams g =
        grid_with_cell(e, int64_t(std::ceil(w / o.grid_nx)), int64_t(std::ceil(h / o.grid_ny)));
    if (cell_bytes) *cell_bytes = exact_grid_bytes(g, in);
    return g;
  }
  GridSearch search(in, o, stage);
  Candidate best = search.walk();
  if (!search.confirm_exact(best)) {
    if (cell_bytes) *cell_bytes = search.thesis_bytes();
    return search.thesis();
  }
  if (!best.feasible) {
    fail<resource_error>(
        kBuildStage,
        "decal grid: no cell size keeps the segment/cell entries under " +
            std::to_string(uint64_t(search.entry_budget())) +
            " (primitives overlap too much; raise --resolution to simplify the lines)");
  }
  if (cell_bytes) *cell_bytes = best.bytes - double(in.geometry_bytes);
  return best.g;
}

}  // namespace prep::detail
