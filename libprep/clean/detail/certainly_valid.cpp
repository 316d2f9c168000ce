// The validity fast path of clean: detail/certainly_valid.hpp. Exact
// predicates (Shewchuk's orient2d error bound as the filter, CGAL's exact
// orientation behind it), a sweep over monotone chains that classifies
// every meeting of two edges, the touch points checked as GEOS checks them
// (PolygonNodeTopology's crossing test at the node, a ring-and-touch-point
// graph that must stay a forest), and the holes placed through row and
// cell indexes. Every step answers `unsure` when it cannot decide.
#include "detail/certainly_valid.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <span>
#include <vector>

#include "detail/exact_orientation.hpp"
#include "detail/union_find.hpp"

namespace prep::detail {
namespace {

// Set when an orientation was decided where GEOS may decide otherwise
// (below); polygon_validity then answers `unsure`.
thread_local bool fragile = false;

bool same_point(const Point2& a, const Point2& b) {
  return a.x == b.x && a.y == b.y;
}

// True when a - b is exact in double (Knuth's two-sum error is zero).
bool exact_difference(double a, double b) {
  const double d = a - b, bv = a - d, av = d + bv;
  return (a - av) + (bv - b) == 0;
}

// A double-double number (hi + lo, |lo| <= ulp(hi) / 2).
struct DD {
  double hi, lo;
};
DD two_sum(double a, double b) {
  const double s = a + b, bv = s - a, av = s - bv;
  return {s, (a - av) + (b - bv)};
}
DD normalized(double hi, double lo) {
  const double s = hi + lo;
  return {s, lo - (s - hi)};
}
DD dd_mul(DD a, DD b) {
  const double p = a.hi * b.hi, e = std::fma(a.hi, b.hi, -p);
  return normalized(p, e + (a.hi * b.lo + a.lo * b.hi));
}
DD dd_sub(DD a, DD b) {
  const DD s = two_sum(a.hi, -b.hi);
  return normalized(s.hi, s.lo + (a.lo - b.lo));
}

// True when GEOS's double-double orientation of (a, b, c) surely has the
// exact sign `o` (CGAL's). Its differences of two doubles are exact;
// products and sums of double-doubles err by about 2^-104 of the terms,
// so its sign is the exact one when the determinant is not within 10^-26
// of the terms (measured here in double-double too), and its zero is
// exact when the differences are exact doubles (the products then are
// too).
bool geos_agrees(const Point2& a, const Point2& b, const Point2& c, int o) {
  if (exact_difference(b.x, a.x) && exact_difference(c.x, a.x) && exact_difference(c.x, b.x) &&
      exact_difference(b.y, a.y) && exact_difference(c.y, a.y) && exact_difference(c.y, b.y))
    return true;
  if (o == 0) return false;
  const DD dx1 = two_sum(b.x, -a.x), dy1 = two_sum(b.y, -a.y);
  const DD dx2 = two_sum(c.x, -b.x), dy2 = two_sum(c.y, -b.y);
  const DD l = dd_mul(dx1, dy2), r = dd_mul(dy1, dx2), det = dd_sub(l, r);
  const double terms = std::fabs(l.hi) + std::fabs(r.hi);
  return std::fabs(det.hi) > 1e-26 * terms;
}

// Sign of the orientation of (a, b, c): +1 left turn, -1 right turn, 0
// collinear. Exact: the floating-point determinant where Shewchuk's
// orient2d error bound A (which covers the rounding of the differences)
// trusts it, CGAL's exact predicate where it does not (and near underflow,
// where the bound does not hold). GEOS (CGAlgorithmsDD::orientationIndex)
// decides that second case in double-double arithmetic, which may differ
// from the exact sign for (nearly) collinear points: such a case is
// `fragile` (geos_agrees).
int orientation(const Point2& a, const Point2& b, const Point2& c) {
  const double l = (b.x - a.x) * (c.y - a.y), r = (b.y - a.y) * (c.x - a.x);
  const double det = l - r, sum = std::fabs(l) + std::fabs(r);
  const double bound = 3.3306690738754716e-16 * sum;
  if (sum > 1e-280) {
    if (det > bound) return 1;
    if (det < -bound) return -1;
  }
  // Two equal points (a touch at a shared vertex): collinear, for GEOS too.
  if (same_point(a, b) || same_point(a, c) || same_point(b, c)) return 0;
  const int o = exact_orientation(a, b, c);
  if (!geos_agrees(a, b, c, o)) fragile = true;
  return o;
}

bool same(const Point2& a, const Point2& b) {
  return a.x == b.x && a.y == b.y;
}
// Lexicographic order (x, then y): along any line, the order of its points.
bool before(const Point2& a, const Point2& b) {
  return a.x < b.x || (a.x == b.x && a.y < b.y);
}

// Where p lies against `ring` (crossing number, exact): `on` when p is on
// an edge the ray test meets (a point off the ring is never `on`; a point
// on it may be reported in or out).
enum class Side { in, out, on };

// One edge a->b of the crossing number at p: flips `in` when the ray from
// p to +x crosses it; false when p lies on it.
bool cross_step(const Point2& a, const Point2& b, const Point2& p, bool& in) {
  const bool up = a.y <= p.y && b.y > p.y, down = b.y <= p.y && a.y > p.y;
  if (!up && !down) return true;
  const int o = orientation(a, b, p);
  if (o == 0) return false;
  if ((up && o > 0) || (down && o < 0)) in = !in;
  return true;
}

Side side_of(const Point2& p, const Ring& ring) {
  bool in = false;
  const size_t n = ring.size();
  for (size_t i = 0; i < n; ++i)
    if (!cross_step(ring[i], ring[i + 1 == n ? 0 : i + 1], p, in)) return Side::on;
  return in ? Side::in : Side::out;
}

// How two closed segments pq and rt (each of two distinct points) meet.
enum class Meet {
  apart,  // not at all
  touch,  // at one point, `at`, an end point of one of them
  cross   // a proper crossing or an overlap along a segment
};

Meet meet(const Point2& p, const Point2& q, const Point2& r, const Point2& t, Point2& at) {
  const int o1 = orientation(p, q, r), o2 = orientation(p, q, t);
  if (o1 * o2 > 0) return Meet::apart;
  const int o3 = orientation(r, t, p), o4 = orientation(r, t, q);
  if (o3 * o4 > 0) return Meet::apart;
  if (o1 == 0 && o2 == 0) {  // one line: compare the intervals along it
    const bool pq = before(p, q), rt = before(r, t);
    const Point2 &a0 = pq ? p : q, &a1 = pq ? q : p, &b0 = rt ? r : t, &b1 = rt ? t : r;
    if (before(a1, b0) || before(b1, a0)) return Meet::apart;
    if (same(a1, b0)) {
      at = a1;
      return Meet::touch;
    }
    if (same(b1, a0)) {
      at = a0;
      return Meet::touch;
    }
    return Meet::cross;
  }
  if (o1 != 0 && o2 != 0 && o3 != 0 && o4 != 0) return Meet::cross;  // proper
  // The lines meet in one point: the end point that lies on the other line.
  at = o1 == 0 ? r : (o2 == 0 ? t : (o3 == 0 ? p : q));
  return Meet::touch;
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

// Two rings (or one ring twice: then invalid) meet at `at`, a point of edge
// `edge` (from vertex edge to edge+1) of ring `ring`.
struct Touch {
  Point2 at;
  uint32_t ring, edge;
};

struct ValidityScratch {
  std::vector<Chain> chains;
  std::vector<uint32_t> order, active;
  std::vector<Touch> touches;
  std::vector<Point2> touch_points;  // sorted (before), distinct
};

// Where polygon_validity's caller asked for them (`culprits`), every
// problem of the first phase that finds one: the sweep then goes on past a
// problem instead of answering at once. blame() records one ring's share of
// a problem and says whether to answer invalid now (no caller asked).
// The answer is then the one the first problem gave (invalid, or unsure
// when an orientation was fragile by then), whatever the sweep met after it.
thread_local std::vector<Culprit>* blamed = nullptr;
thread_local bool fragile_at_first_blame = false;
bool blame(uint32_t ring, Point2 at, bool whole = false) {
  if (blamed) {
    if (blamed->empty()) fragile_at_first_blame = fragile;
    blamed->push_back({ring, at, whole});
  }
  return blamed == nullptr;
}
Point2 midpoint(const Point2& a, const Point2& b) {
  return {0.5 * (a.x + b.x), 0.5 * (a.y + b.y)};
}
// The answer at the end of a phase that went on past its problems.
Validity after_phase() {
  return blamed && !blamed->empty() ? Validity::invalid : Validity::valid;
}

// Checks the turn at every vertex of ring `ri` and appends the ring's
// monotone chains. A vertex where the ring goes straight on is fine; one
// where it turns back (a spike: its two edges overlap) is invalid.
Validity append_chains(const Ring& r, uint32_t ri, std::vector<Chain>& chains) {
  const uint32_t n = static_cast<uint32_t>(r.size());
  for (uint32_t i = 0; i < n; ++i) {
    const Point2 &a = r[i == 0 ? n - 1 : i - 1], &v = r[i], &b = r[i + 1 == n ? 0 : i + 1];
    const bool was_fragile = fragile, back = before(a, v) == before(b, v);
    const int o = orientation(a, v, b);
    if (o == 0 && back && blame(ri, v)) return Validity::invalid;
    // Going on past v (v between its neighbours along x, or y): the edges
    // meet only at v whether GEOS finds them collinear or not.
    if (!back) fragile = was_fragile;
  }
  // Chains: start at an edge whose direction class differs from the
  // previous edge's, so no chain wraps around the ring's start.
  auto dir = [&](uint32_t e) {
    const double dx = r[e + 1 == n ? 0 : e + 1].x - r[e].x;
    return dx > 0 ? 1 : (dx < 0 ? -1 : 0);
  };
  uint32_t start = 0;
  while (start < n && dir(start) != 0 && dir(start) == dir((start + n - 1) % n)) ++start;
  if (start == n) return Validity::unsure;  // x monotone around a closed ring: impossible
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
  return Validity::valid;
}

// The sweep in x over the chains of all rings: every pair of chains whose
// boxes meet has its edges tested pairwise; one work budget for all tests.
// Edges of different rings may touch (recorded in `touches`); any other
// meeting makes the polygon invalid.
class ChainSweep {
 public:
  ChainSweep(const std::vector<Ring>& rings, const std::vector<Chain>& chains,
             std::vector<Touch>& touches, size_t budget)
      : rings_(rings), chains_(chains), touches_(touches), budget_(budget) {}

  // valid: the edges meet only at shared vertices of neighbours and at
  // touches between rings (all in `touches`); invalid: two edges cross,
  // overlap, or a ring meets itself; unsure: the budget ran out. `order`
  // and `active` are scratch.
  Validity scan(std::vector<uint32_t>& order, std::vector<uint32_t>& active) {
    order.resize(chains_.size());
    std::iota(order.begin(), order.end(), 0u);
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
        if (budget_-- == 0) return Validity::unsure;
        const Validity v = chains_meet(a, b);
        if (v != Validity::valid) return v;
      }
      active.resize(w);
      active.push_back(ci);
    }
    return after_phase();
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

  // Tests every pair of edges of chains a and b whose boxes meet.
  Validity chains_meet(const Chain& a, const Chain& b) {
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
        if (budget_-- == 0) return Validity::unsure;
        if (a.ring == b.ring) {
          const uint32_t n = static_cast<uint32_t>(rings_[a.ring].size());
          // Neighbours share a vertex; the turn test covers them.
          if ((ia + 1) % n == ib || (ib + 1) % n == ia) continue;
        }
        Point2 at;
        const Meet m = meet(*p, *q, *r, *t, at);
        if (m == Meet::apart) continue;
        // A crossing, an overlap, or a ring meeting itself (GEOS: "Ring
        // Self-intersection"; inverted rings are not allowed).
        if (m == Meet::cross || a.ring == b.ring) {
          if (blame(a.ring, midpoint(*p, *q)) | blame(b.ring, midpoint(*r, *t)))
            return Validity::invalid;
          continue;
        }
        at = {at.x + 0.0, at.y + 0.0};  // -0 and 0 are one point
        touches_.push_back({at, a.ring, ia});
        touches_.push_back({at, b.ring, ib});
      }
    }
    return Validity::valid;
  }

  const std::vector<Ring>& rings_;
  const std::vector<Chain>& chains_;
  std::vector<Touch>& touches_;
  size_t budget_;
};

// ------------------------------------------------------ touch points --
//
// At a touch point the rings must not cross: GEOS's test at a node
// (PolygonNodeTopology::isCrossing): the two edges of one ring at the node
// split the directions around it in two; the other ring's two edges must
// lie on the same side. Angles are compared as GEOS does: by quadrant, then
// by exact orientation.

// The quadrant of p seen from o: 0 NE, 1 NW, 2 SW, 3 SE (an axis belongs
// to the quadrant it opens, counter-clockwise).
int quadrant(const Point2& o, const Point2& p) {
  if (p.x >= o.x) return p.y >= o.y ? 0 : 3;
  return p.y >= o.y ? 1 : 2;
}

// +1 when the direction o->p has the greater angle from +x (in [0, 2 pi)),
// -1 the smaller, 0 the same.
int compare_angle(const Point2& o, const Point2& p, const Point2& q) {
  const int qp = quadrant(o, p), qq = quadrant(o, q);
  if (qp != qq) return qp > qq ? 1 : -1;
  return orientation(o, q, p);
}

// +1 when the direction o->p lies strictly between lo and hi (by angle,
// lo < hi), -1 outside, 0 along one of them.
int between(const Point2& o, const Point2& p, const Point2& lo, const Point2& hi) {
  const int c0 = compare_angle(o, p, lo);
  if (c0 == 0) return 0;
  const int c1 = compare_angle(o, p, hi);
  if (c1 == 0) return 0;
  return c0 > 0 && c1 < 0 ? 1 : -1;
}

// The two edges of one ring at a touch point: towards a0 and a1.
struct Arms {
  uint32_t ring;
  Point2 a0, a1;
};

// The edges of ring `t.ring` at t.at: the neighbours of the vertex there,
// or the ends of the edge whose inside it is.
Arms arms_at(const std::vector<Ring>& rings, const Touch& t) {
  const Ring& r = rings[t.ring];
  const uint32_t n = static_cast<uint32_t>(r.size()), e = t.edge;
  const Point2 &p = r[e], &q = r[e + 1 == n ? 0 : e + 1];
  if (same(t.at, p)) return {t.ring, r[e == 0 ? n - 1 : e - 1], q};
  if (same(t.at, q)) return {t.ring, p, r[e + 2 >= n ? e + 2 - n : e + 2]};
  return {t.ring, p, q};
}

// valid: the rings do not cross at o; invalid: they do; unsure: two edges
// leave o in the same direction (an overlap the sweep reports first).
Validity crossing_at(const Point2& o, const Arms& a, const Arms& b) {
  const bool swap = compare_angle(o, a.a0, a.a1) > 0;
  const Point2 &lo = swap ? a.a1 : a.a0, &hi = swap ? a.a0 : a.a1;
  const int c0 = between(o, b.a0, lo, hi), c1 = between(o, b.a1, lo, hi);
  if (c0 == 0 || c1 == 0 || compare_angle(o, a.a0, a.a1) == 0) return Validity::unsure;
  return c0 == c1 ? Validity::valid : Validity::invalid;
}

// Checks the touch points: the rings through each must not cross there
// (pairwise), and the graph of rings and touch points must be a forest:
// two rings touching twice, or a chain of touching rings closing on itself,
// cut the interior in two (GEOS: "Interior is disconnected"). Fills
// `points` with the touch points (sorted, distinct).
Validity check_touches(const std::vector<Ring>& rings, std::vector<Touch>& touches,
                       std::vector<Point2>& points) {
  constexpr size_t kMaxRingsAtAPoint = 32;
  points.clear();
  if (touches.empty()) return Validity::valid;
  std::sort(touches.begin(), touches.end(), [](const Touch& a, const Touch& b) {
    if (!same(a.at, b.at)) return before(a.at, b.at);
    return a.ring < b.ring || (a.ring == b.ring && a.edge < b.edge);
  });
  UnionFind forest(rings.size() + touches.size());
  std::vector<Arms> arms;
  for (size_t i = 0; i < touches.size();) {
    const Point2 at = touches[i].at;
    const uint32_t node = static_cast<uint32_t>(rings.size() + points.size());
    points.push_back(at);
    arms.clear();
    for (; i < touches.size() && same(touches[i].at, at); ++i)
      if (arms.empty() || arms.back().ring != touches[i].ring) {
        if (arms.size() == kMaxRingsAtAPoint) return Validity::unsure;
        arms.push_back(arms_at(rings, touches[i]));
        if (!forest.unite(touches[i].ring, node)) {
          bool now = false;
          for (const Arms& a : arms) now = blame(a.ring, at);
          if (now) return Validity::invalid;
        }
      }
    for (size_t a = 0; a < arms.size(); ++a)
      for (size_t b = a + 1; b < arms.size(); ++b) {
        const Validity v = crossing_at(at, arms[a], arms[b]);
        if (v == Validity::invalid) {
          if (blame(arms[a].ring, at) | blame(arms[b].ring, at)) return v;
          continue;
        }
        if (v != Validity::valid) return v;
      }
  }
  return after_phase();
}

// ------------------------------------------------------ hole placement --
//
// The rings meet only at touch points where they do not cross, so each
// hole lies wholly inside or outside the shell (and any other hole), save
// those points: one vertex of the hole that is no touch point decides, and
// it lies on no other ring.

// For each hole (rings[1..]), a vertex that is no touch point; false when
// some hole has none (GEOS decides).
bool free_vertices(const std::vector<Ring>& rings, const std::vector<Point2>& touch_points,
                   std::vector<Point2>& out) {
  out.clear();
  for (size_t h = 1; h < rings.size(); ++h) {
    const auto free = std::find_if(rings[h].begin(), rings[h].end(), [&](const Point2& p) {
      return !std::binary_search(touch_points.begin(), touch_points.end(), p, before);
    });
    if (free == rings[h].end()) return false;
    out.push_back(*free);
  }
  return true;
}

// A few holes: each hole's free vertex against every ring.
Validity holes_placed_pairwise(const std::vector<Ring>& rings, const std::vector<Point2>& free) {
  for (size_t h = 1; h < rings.size(); ++h) {
    const Point2& p = free[h - 1];
    const Side s = side_of(p, rings[0]);
    if (s == Side::on) return Validity::unsure;
    if (s != Side::in && (blame(0, p) | blame(uint32_t(h), p))) return Validity::invalid;
    for (size_t o = 1; o < rings.size(); ++o) {
      if (o == h) continue;
      const Side t = side_of(p, rings[o]);
      if (t == Side::on) return Validity::unsure;
      if (t != Side::out && (blame(uint32_t(o), p) | blame(uint32_t(h), p)))
        return Validity::invalid;
    }
  }
  return after_phase();
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

// holes_placed for many holes. Each hole's free vertex against the shell:
// the crossing number over the shell edges of that vertex's row of a y
// grid (every edge the ray from the vertex can cross spans its y); against
// the other holes: only those whose boxes hold the vertex (a cell grid of
// the hole boxes), walked within `budget` edges in all.
Validity holes_placed_indexed(const std::vector<Ring>& rings, const std::vector<Point2>& free,
                              size_t budget) {
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
  if (!rows_index.build(edge_boxes, shell_box, 1, rows, 16 * n + 1024)) return Validity::unsure;
  std::vector<Box> hole_boxes(holes);
  for (size_t h = 0; h < holes; ++h) hole_boxes[h] = box_of(rings[h + 1]);
  BucketIndex cells;
  const uint32_t side = uint32_t(std::clamp(std::sqrt(double(holes)), 1.0, 1024.0));
  if (!cells.build(hole_boxes, shell_box, side, side, 16 * holes + 1024)) return Validity::unsure;
  for (size_t h = 0; h < holes; ++h) {
    const Point2& p = free[h];
    // Off the ring, so on or beyond the shell's box is outside.
    if (p.x <= shell_box.xmin || p.x >= shell_box.xmax || p.y <= shell_box.ymin ||
        p.y >= shell_box.ymax) {
      if (blame(0, p) | blame(uint32_t(h + 1), p)) return Validity::invalid;
      continue;
    }
    bool in = false;
    for (uint32_t e : rows_index.at(p.x, p.y))
      if (!cross_step(shell[e], shell[(e + 1) % n], p, in)) return Validity::unsure;
    if (!in) {  // outside the shell
      if (blame(0, p) | blame(uint32_t(h + 1), p)) return Validity::invalid;
      continue;
    }
    for (uint32_t o : cells.at(p.x, p.y)) {
      if (o == h) continue;
      const Box& b = hole_boxes[o];
      if (p.x < b.xmin || p.x > b.xmax || p.y < b.ymin || p.y > b.ymax) continue;
      const Ring& other = rings[o + 1];
      if (other.size() > budget) return Validity::unsure;
      budget -= other.size();
      const Side s = side_of(p, other);
      if (s == Side::on) return Validity::unsure;
      if (s != Side::out && (blame(o + 1, p) | blame(uint32_t(h + 1), p)))  // nested
        return Validity::invalid;
    }
  }
  return after_phase();
}

Validity holes_placed(const std::vector<Ring>& rings, const std::vector<Point2>& free,
                      size_t budget) {
  constexpr size_t kPairwiseHoles = 8;
  return rings.size() <= 1 + kPairwiseHoles ? holes_placed_pairwise(rings, free)
                                            : holes_placed_indexed(rings, free, budget);
}

// The rings with consecutive repeated points (and a last point repeating
// the first) removed, as GEOS reads them; null when there are none.
const std::vector<Ring>* without_repeats(const std::vector<Ring>& rings, std::vector<Ring>& copy) {
  auto repeats = [](const Ring& r) {
    for (size_t i = 0; i < r.size(); ++i)
      if (same(r[i], r[i + 1 == r.size() ? 0 : i + 1]) && r.size() > 1) return true;
    return false;
  };
  if (std::none_of(rings.begin(), rings.end(), repeats)) return nullptr;
  copy = rings;
  for (Ring& r : copy) {
    r.erase(std::unique(r.begin(), r.end(), same), r.end());
    while (r.size() > 1 && same(r.front(), r.back())) r.pop_back();
  }
  return &copy;
}

// polygon_validity without the check of fragile orientations.
Validity decide(const std::vector<Ring>& input) {
  if (input.empty()) return Validity::unsure;
  for (const Ring& r : input)
    for (const Point2& p : r)
      if (!std::isfinite(p.x) || !std::isfinite(p.y)) return Validity::invalid;
  std::vector<Ring> copy;
  const std::vector<Ring>* deduped = without_repeats(input, copy);
  const std::vector<Ring>& rings = deduped ? *deduped : input;
  thread_local ValidityScratch scratch;
  scratch.chains.clear();
  scratch.touches.clear();
  size_t total = 0;
  for (uint32_t ri = 0; ri < rings.size(); ++ri) {
    if (rings[ri].size() < 3) {  // GEOS: "Too few points"
      if (blame(ri, {}, /*whole=*/true)) return Validity::invalid;
      continue;
    }
    const Validity v = append_chains(rings[ri], ri, scratch.chains);
    if (v != Validity::valid) return v;
    total += rings[ri].size();
  }
  if (after_phase() == Validity::invalid) return Validity::invalid;
  ChainSweep sweep(rings, scratch.chains, scratch.touches, 32 * total + 4096);
  Validity v = sweep.scan(scratch.order, scratch.active);
  if (v != Validity::valid) return v;
  v = check_touches(rings, scratch.touches, scratch.touch_points);
  if (v != Validity::valid) return v;
  std::vector<Point2> free;
  if (!free_vertices(rings, scratch.touch_points, free)) return Validity::unsure;
  return holes_placed(rings, free, 32 * total + 4096);
}

}  // namespace

Validity polygon_validity(const std::vector<Ring>& rings, std::vector<Culprit>* culprits) {
  fragile = false;
  if (culprits) culprits->clear();
  blamed = culprits;
  Validity v = decide(rings);
  blamed = nullptr;
  if (culprits && !culprits->empty()) {
    if (fragile_at_first_blame) {
      culprits->clear();
      return Validity::unsure;
    }
    return Validity::invalid;
  }
  return fragile ? Validity::unsure : v;
}

bool certainly_valid(const std::vector<Ring>& rings) {
  return polygon_validity(rings) == Validity::valid;
}

}  // namespace prep::detail
