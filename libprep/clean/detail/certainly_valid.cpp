// The validity fast path of clean: detail/certainly_valid.hpp. Filtered
// predicates (Shewchuk's orient2d error bound) and a sweep over monotone
// chains; every step answers "not proven" when it cannot be sure.
#include "detail/certainly_valid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace prep::detail {
namespace {

// Sign of the orientation of (a, b, c): +1 left turn, -1 right turn, 0 when
// the floating-point determinant is too close to zero to trust (Shewchuk's
// orient2d error bound A, which also covers the rounding of the differences).
int orientation(const Point2& a, const Point2& b, const Point2& c) {
  const double l = (b.x - a.x) * (c.y - a.y), r = (b.y - a.y) * (c.x - a.x);
  const double det = l - r;
  const double bound = 3.3306690738754716e-16 * (std::fabs(l) + std::fabs(r));
  if (det > bound) return 1;
  if (det < -bound) return -1;
  return 0;
}

// True when p lies certainly inside `ring` (crossing number, with every
// orientation certain); false when outside or not sure (`sure` says which).
bool inside_ring(const Point2& p, const Ring& ring, bool& sure) {
  bool in = false;
  const size_t n = ring.size();
  for (size_t i = 0; i < n; ++i) {
    const Point2& a = ring[i];
    const Point2& b = ring[(i + 1) % n];
    const bool up = a.y <= p.y && b.y > p.y, down = b.y <= p.y && a.y > p.y;
    if (!up && !down) continue;
    const int o = orientation(a, b, p);
    if (o == 0) {
      sure = false;
      return false;
    }
    if ((up && o > 0) || (down && o < 0)) in = !in;
  }
  return in;
}

// A maximal run of edges of one ring along which x strictly increases (or
// strictly decreases; a vertical edge is a chain of its own). Two edges of
// one chain that are not neighbours lie in disjoint x ranges, so they cannot
// meet; only edges of different chains need testing (the monotone chains of
// GEOS's noder, on plain arrays).
struct Chain {
  double xmin, xmax, ymin, ymax;
  uint32_t ring, first, count;  // edges first .. first+count-1 (mod ring size)
  bool reversed;                // x decreases along the ring
};

struct ValidityScratch {
  std::vector<Chain> chains;
  std::vector<uint32_t> order, active;
};

// Checks that every vertex of ring `ri` turns (certain orientation) and
// appends the ring's monotone chains. False: not provable (fewer than 3
// vertices, a vertex without a certain turn).
bool append_chains(const Ring& r, uint32_t ri, std::vector<Chain>& chains) {
  const uint32_t n = static_cast<uint32_t>(r.size());
  if (n < 3) return false;
  if (orientation(r[n - 1], r[0], r[1]) == 0 || orientation(r[n - 2], r[n - 1], r[0]) == 0)
    return false;
  for (uint32_t i = 1; i + 1 < n; ++i)
    if (orientation(r[i - 1], r[i], r[i + 1]) == 0) return false;
  // Chains: start at an edge whose direction class differs from the
  // previous edge's, so no chain wraps around the ring's start.
  auto dir = [&](uint32_t e) {
    const double dx = r[e + 1 == n ? 0 : e + 1].x - r[e].x;
    return dx > 0 ? 1 : (dx < 0 ? -1 : 0);
  };
  uint32_t start = 0;
  while (start < n && dir(start) != 0 && dir(start) == dir((start + n - 1) % n)) ++start;
  if (start == n) return false;  // x monotone around a closed ring: impossible
  uint32_t e = 0;
  while (e < n) {
    const uint32_t first = start + e >= n ? start + e - n : start + e;
    const int d = dir(first);
    uint32_t count = 1;
    if (d != 0)
      while (e + count < n && dir(first + count >= n ? first + count - n : first + count) == d)
        ++count;
    Chain c{INFINITY, -INFINITY, INFINITY, -INFINITY, ri, first, count, d < 0};
    for (uint32_t k = 0, v = first; k <= count; ++k, v = v + 1 == n ? 0 : v + 1) {
      const Point2& p = r[v];
      c.xmin = std::min(c.xmin, p.x);
      c.xmax = std::max(c.xmax, p.x);
      c.ymin = std::min(c.ymin, p.y);
      c.ymax = std::max(c.ymax, p.y);
    }
    chains.push_back(c);
    e += count;
  }
  return true;
}

// The sweep in x over the chains of all rings: every pair of chains whose
// boxes meet has its edges tested pairwise; one work budget for all tests.
class ChainSweep {
 public:
  ChainSweep(const std::vector<Ring>& rings, const std::vector<Chain>& chains, size_t budget)
      : rings_(rings), chains_(chains), budget_(budget) {}

  // True when no two non-adjacent edges certainly meet; false when two
  // meet, may meet, or the budget ran out. `order` and `active` are scratch.
  bool all_apart(std::vector<uint32_t>& order, std::vector<uint32_t>& active) {
    order.resize(chains_.size());
    for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
      return chains_[a].xmin < chains_[b].xmin || (chains_[a].xmin == chains_[b].xmin && a < b);
    });
    active.clear();
    for (uint32_t ci : order) {
      const Chain& a = chains_[ci];
      size_t w = 0;
      for (size_t k = 0; k < active.size(); ++k) {
        const Chain& b = chains_[active[k]];
        if (b.xmax < a.xmin) continue;  // left behind for good
        active[w++] = active[k];
        if (b.ymax < a.ymin || b.ymin > a.ymax) continue;
        if (budget_-- == 0) return false;
        if (!chains_apart(a, b)) return false;
      }
      active.resize(w);
      active.push_back(ci);
    }
    return true;
  }

 private:
  // Edge k (in increasing x) of chain c, as its two end points.
  void edge(const Chain& c, uint32_t k, const Point2*& p, const Point2*& q, uint32_t& index) const {
    const Ring& r = rings_[c.ring];
    const uint32_t n = static_cast<uint32_t>(r.size());
    index = c.first + (c.reversed ? c.count - 1 - k : k);
    if (index >= n) index -= n;
    p = &r[index];
    q = &r[index + 1 == n ? 0 : index + 1];
  }

  // The first edge of c (in increasing x) whose max x is >= x.
  uint32_t first_reaching(const Chain& c, double x) const {
    uint32_t l = 0, h = c.count;
    while (l < h) {
      const uint32_t m = (l + h) / 2;
      const Point2 *p, *q;
      uint32_t i;
      edge(c, m, p, q, i);
      if (std::max(p->x, q->x) < x)
        l = m + 1;
      else
        h = m;
    }
    return l;
  }

  // Tests every pair of edges of chains a and b whose x ranges meet.
  bool chains_apart(const Chain& a, const Chain& b) {
    // Only the part of each chain inside the other's box can meet it.
    const double lo = std::max(a.xmin, b.xmin), hi = std::min(a.xmax, b.xmax);
    const double ylo = std::max(a.ymin, b.ymin), yhi = std::min(a.ymax, b.ymax);
    uint32_t jb = first_reaching(b, lo);
    for (uint32_t ka = first_reaching(a, lo); ka < a.count; ++ka) {
      const Point2 *p, *q;
      uint32_t ia;
      edge(a, ka, p, q, ia);
      const double axmin = std::min(p->x, q->x), axmax = std::max(p->x, q->x);
      if (axmin > hi) break;
      const double aymin = std::min(p->y, q->y), aymax = std::max(p->y, q->y);
      if (aymax < ylo || aymin > yhi) continue;
      for (;;) {  // skip b's edges wholly left of this one (b is sorted in x)
        if (jb >= b.count) break;
        const Point2 *r, *t;
        uint32_t ib;
        edge(b, jb, r, t, ib);
        if (std::max(r->x, t->x) < axmin)
          ++jb;
        else
          break;
      }
      for (uint32_t kb = jb; kb < b.count; ++kb) {
        const Point2 *r, *t;
        uint32_t ib;
        edge(b, kb, r, t, ib);
        if (std::min(r->x, t->x) > axmax) break;
        if (std::max(r->y, t->y) < aymin || std::min(r->y, t->y) > aymax) continue;
        if (budget_-- == 0) return false;
        if (a.ring == b.ring) {
          const uint32_t n = static_cast<uint32_t>(rings_[a.ring].size());
          // Neighbours share a vertex; the turn test covers them.
          if ((ia + 1) % n == ib || (ib + 1) % n == ia) continue;
        }
        if (!edges_apart(*p, *q, *r, *t)) return false;
      }
    }
    return true;
  }

  // Segments pq and rt certainly do not meet.
  static bool edges_apart(const Point2& p, const Point2& q, const Point2& r, const Point2& t) {
    const int o1 = orientation(p, q, r), o2 = orientation(p, q, t);
    const int o3 = orientation(r, t, p), o4 = orientation(r, t, q);
    if (o1 == 0 || o2 == 0 || o3 == 0 || o4 == 0) return false;
    return o1 == o2 || o3 == o4;  // one strictly on one side of the other; else they cross
  }

  const std::vector<Ring>& rings_;
  const std::vector<Chain>& chains_;
  size_t budget_;
};

// No two rings meet, so each hole lies wholly inside or outside the shell
// (and any other hole): one vertex decides. True when every hole is
// certainly inside the shell and outside the other holes. A few holes are
// tested against every ring; many are indexed (`holes_placed_indexed`).
bool holes_placed_pairwise(const std::vector<Ring>& rings) {
  for (size_t h = 1; h < rings.size(); ++h) {
    bool sure = true;
    if (!inside_ring(rings[h][0], rings[0], sure) || !sure) return false;
    for (size_t o = 1; o < rings.size(); ++o) {
      if (o == h) continue;
      if (inside_ring(rings[h][0], rings[o], sure) || !sure) return false;
    }
  }
  return true;
}

struct Box {
  double xmin = INFINITY, ymin = INFINITY, xmax = -INFINITY, ymax = -INFINITY;
};
Box box_of(const Ring& r) {
  Box b;
  for (const Point2& p : r) {
    b.xmin = std::min(b.xmin, p.x);
    b.ymin = std::min(b.ymin, p.y);
    b.xmax = std::max(b.xmax, p.x);
    b.ymax = std::max(b.ymax, p.y);
  }
  return b;
}

// Items (edges or rings) registered in the rows (y) or cells (x, y) of a
// uniform grid that their boxes meet; false when that would take more than
// `cap` registrations (the proof then gives up).
struct BucketIndex {
  Box extent;
  uint32_t nx = 1, ny = 1;
  std::vector<uint32_t> start, items;

  bool build(const std::vector<Box>& boxes, const Box& e, uint32_t cols, uint32_t rows,
             size_t cap) {
    extent = e;
    nx = cols;
    ny = rows;
    std::vector<uint32_t> count(size_t(nx) * ny + 1, 0);
    size_t total = 0;
    for (const Box& b : boxes) {
      const auto [i0, i1, j0, j1] = span(b);
      total += size_t(i1 - i0 + 1) * (j1 - j0 + 1);
      if (total > cap) return false;
      for (uint32_t j = j0; j <= j1; ++j)
        for (uint32_t i = i0; i <= i1; ++i) ++count[size_t(j) * nx + i + 1];
    }
    for (size_t c = 1; c < count.size(); ++c) count[c] += count[c - 1];
    start = count;
    items.resize(total);
    for (uint32_t k = 0; k < boxes.size(); ++k) {
      const auto [i0, i1, j0, j1] = span(boxes[k]);
      for (uint32_t j = j0; j <= j1; ++j)
        for (uint32_t i = i0; i <= i1; ++i) items[count[size_t(j) * nx + i]++] = k;
    }
    return true;
  }
  uint32_t col(double x) const {
    const double w = (extent.xmax - extent.xmin) / nx;
    const double c = w > 0 ? std::floor((x - extent.xmin) / w) : 0.0;
    return uint32_t(std::clamp(c, 0.0, double(nx - 1)));
  }
  uint32_t row(double y) const {
    const double h = (extent.ymax - extent.ymin) / ny;
    const double r = h > 0 ? std::floor((y - extent.ymin) / h) : 0.0;
    return uint32_t(std::clamp(r, 0.0, double(ny - 1)));
  }
  std::array<uint32_t, 4> span(const Box& b) const {
    return {col(b.xmin), col(b.xmax), row(b.ymin), row(b.ymax)};
  }
  // The items whose boxes may hold (x, y).
  std::span<const uint32_t> at(double x, double y) const {
    const size_t c = size_t(row(y)) * nx + col(x);
    return {items.data() + start[c], items.data() + start[c + 1]};
  }
};

// holes_placed for many holes. Each hole's first vertex against the shell:
// the crossing number over the shell edges of that vertex's row of a y
// grid (every edge the ray from the vertex can cross spans its y); against
// the other holes: only those whose boxes hold the vertex (a cell grid of
// the hole boxes). The same certain-orientation rule as inside_ring.
bool holes_placed_indexed(const std::vector<Ring>& rings) {
  const Ring& shell = rings[0];
  const size_t n = shell.size(), holes = rings.size() - 1;
  const Box shell_box = box_of(shell);
  std::vector<Box> edge_boxes(n);
  for (size_t i = 0; i < n; ++i) {
    const Point2 &a = shell[i], &b = shell[(i + 1) % n];
    edge_boxes[i] = {std::min(a.x, b.x), std::min(a.y, b.y), std::max(a.x, b.x),
                     std::max(a.y, b.y)};
  }
  BucketIndex rows_index;
  const uint32_t rows = uint32_t(std::clamp<size_t>(n / 4, 1, 1u << 16));
  if (!rows_index.build(edge_boxes, shell_box, 1, rows, 16 * n + 1024)) return false;
  std::vector<Box> hole_boxes(holes);
  for (size_t h = 0; h < holes; ++h) hole_boxes[h] = box_of(rings[h + 1]);
  BucketIndex cells;
  const uint32_t side = uint32_t(std::clamp(std::sqrt(double(holes)), 1.0, 1024.0));
  if (!cells.build(hole_boxes, shell_box, side, side, 16 * holes + 1024)) return false;
  for (size_t h = 0; h < holes; ++h) {
    const Point2& p = rings[h + 1][0];
    if (p.x <= shell_box.xmin || p.x >= shell_box.xmax || p.y <= shell_box.ymin ||
        p.y >= shell_box.ymax)
      return false;
    bool in = false;
    for (uint32_t e : rows_index.at(p.x, p.y)) {
      const Point2 &a = shell[e], &b = shell[(e + 1) % n];
      const bool up = a.y <= p.y && b.y > p.y, down = b.y <= p.y && a.y > p.y;
      if (!up && !down) continue;
      const int o = orientation(a, b, p);
      if (o == 0) return false;
      if ((up && o > 0) || (down && o < 0)) in = !in;
    }
    if (!in) return false;
    for (uint32_t o : cells.at(p.x, p.y)) {
      if (o == h) continue;
      const Box& b = hole_boxes[o];
      if (p.x < b.xmin || p.x > b.xmax || p.y < b.ymin || p.y > b.ymax) continue;
      bool sure = true;
      if (inside_ring(p, rings[o + 1], sure) || !sure) return false;
    }
  }
  return true;
}

bool holes_placed(const std::vector<Ring>& rings) {
  constexpr size_t kPairwiseHoles = 8;
  return rings.size() <= 1 + kPairwiseHoles ? holes_placed_pairwise(rings)
                                            : holes_placed_indexed(rings);
}

}  // namespace

bool certainly_valid(const std::vector<Ring>& rings) {
  thread_local ValidityScratch scratch;
  scratch.chains.clear();
  size_t total = 0;
  for (uint32_t ri = 0; ri < rings.size(); ++ri) {
    if (!append_chains(rings[ri], ri, scratch.chains)) return false;
    total += rings[ri].size();
  }
  ChainSweep sweep(rings, scratch.chains, 32 * total + 4096);
  if (!sweep.all_apart(scratch.order, scratch.active)) return false;
  return holes_placed(rings);
}

}  // namespace prep::detail
