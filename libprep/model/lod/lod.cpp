// LOCALIS LOD segments (seed 001 §3.1-3.5). See lod/lod.hpp for the
// contract and decal/format.hpp for the stored visibility rule.
#include "lod/lod.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"

namespace prep {

namespace detail {
namespace {

__extension__ typedef __int128 int128;

constexpr uint32_t kNone = decal::kLodNone;
constexpr double kQ = decal::kQuantumMetres;

// Distance of p to the segment (a, b); to a when a == b (closed rings).
double distance_to_segment(double px, double py, double ax, double ay, double bx, double by) {
  const double vx = bx - ax, vy = by - ay;
  const double wx = px - ax, wy = py - ay;
  const double vv = vx * vx + vy * vy;
  double t = vv > 0 ? (wx * vx + wy * vy) / vv : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double dx = wx - t * vx, dy = wy - t * vy;
  return std::sqrt(dx * dx + dy * dy);
}

// The BLG-tree of one line (§3.1): one node per interior point.
struct BlgTree {
  std::vector<uint32_t> parent;            // local index, kNone for the root (and B, E)
  std::vector<uint32_t> span_l, span_r;    // the baseline the node splits
  std::vector<uint32_t> child_l, child_r;  // kNone when absent
  std::vector<double> error;               // DP distance to the baseline
  uint32_t root = kNone;
};

BlgTree build_blg(const std::vector<ivec2>& pts) {
  const auto n = static_cast<uint32_t>(pts.size());
  BlgTree t;
  t.parent.assign(n, kNone);
  t.span_l.assign(n, kNone);
  t.span_r.assign(n, kNone);
  t.child_l.assign(n, kNone);
  t.child_r.assign(n, kNone);
  t.error.assign(n, 0.0);
  struct Task {
    uint32_t l, r, parent;
    bool left;  // is the left child of parent
  };
  std::vector<Task> stack{{0, n - 1, kNone, false}};
  while (!stack.empty()) {
    const Task task = stack.back();
    stack.pop_back();
    if (task.r - task.l < 2) continue;
    const double ax = pts[task.l][0] * kQ, ay = pts[task.l][1] * kQ;
    const double bx = pts[task.r][0] * kQ, by = pts[task.r][1] * kQ;
    uint32_t best = task.l + 1;
    double best_d = -1;
    for (uint32_t i = task.l + 1; i < task.r; ++i) {
      const double d = distance_to_segment(pts[i][0] * kQ, pts[i][1] * kQ, ax, ay, bx, by);
      if (d > best_d) {  // first maximum wins ties
        best_d = d;
        best = i;
      }
    }
    t.error[best] = best_d;
    t.span_l[best] = task.l;
    t.span_r[best] = task.r;
    t.parent[best] = task.parent;
    if (task.parent == kNone) {
      t.root = best;
    } else if (task.left) {
      t.child_l[task.parent] = best;
    } else {
      t.child_r[task.parent] = best;
    }
    stack.push_back({best, task.r, best, false});
    stack.push_back({task.l, best, best, true});
  }
  return t;
}

struct Vec {
  int64_t x, y;
};

// Even-odd containment test against the closed polygon pts[l..r] (closing
// edge r -> l); points on the boundary count as inside. Exact integer
// arithmetic. Edges are bucketed by horizontal bands so a query only looks
// at the edges its +x ray (or the point itself) can meet.
class SpanPolygon {
 public:
  SpanPolygon(const std::vector<ivec2>& pts, uint32_t l, uint32_t r, int64_t ymin, int64_t ymax)
      : pts_(pts), l_(l), r_(r), ymin_(ymin) {
    const uint32_t edges = r - l + 1;
    bands_ = std::clamp<int64_t>(edges / 8, 1, 256);
    height_ = ymax - ymin + 1;
    start_.assign(static_cast<size_t>(bands_ + 1), 0);
    auto each_band = [&](uint32_t k, auto&& f) {
      const uint32_t k2 = k == r_ ? l_ : k + 1;
      const int64_t y0 = std::min<int64_t>(pts_[k][1], pts_[k2][1]);
      const int64_t y1 = std::max<int64_t>(pts_[k][1], pts_[k2][1]);
      for (int64_t b = band(y0); b <= band(y1); ++b) f(b);
    };
    for (uint32_t k = l; k <= r; ++k)
      each_band(k, [&](int64_t b) { ++start_[static_cast<size_t>(b) + 1]; });
    std::partial_sum(start_.begin(), start_.end(), start_.begin());
    edges_.resize(start_.back());
    std::vector<uint32_t> fill(start_.begin(), start_.end() - 1);
    for (uint32_t k = l; k <= r; ++k)
      each_band(k, [&](int64_t b) { edges_[fill[static_cast<size_t>(b)]++] = k; });
  }

  bool inside_or_on(Vec q) const {
    if (q.y < ymin_ || q.y >= ymin_ + height_) return false;
    const int64_t b = band(q.y);
    bool inside = false;
    for (uint32_t e = start_[static_cast<size_t>(b)]; e < start_[static_cast<size_t>(b) + 1]; ++e) {
      const uint32_t k = edges_[e];
      const uint32_t k2 = k == r_ ? l_ : k + 1;
      const Vec a{pts_[k][0], pts_[k][1]}, c{pts_[k2][0], pts_[k2][1]};
      const int128 cross = int128(c.x - a.x) * (q.y - a.y) - int128(q.x - a.x) * (c.y - a.y);
      if (cross == 0 && q.x >= std::min(a.x, c.x) && q.x <= std::max(a.x, c.x) &&
          q.y >= std::min(a.y, c.y) && q.y <= std::max(a.y, c.y))
        return true;
      if ((a.y > q.y) != (c.y > q.y)) {
        if (c.y > a.y ? cross > 0 : cross < 0) inside = !inside;
      }
    }
    return inside;
  }

 private:
  int64_t band(int64_t y) const {
    return std::clamp<int64_t>(static_cast<int64_t>((int128(y - ymin_) * bands_) / height_), 0,
                               bands_ - 1);
  }
  const std::vector<ivec2>& pts_;
  uint32_t l_, r_;
  int64_t ymin_, height_ = 1, bands_ = 1;
  std::vector<uint32_t> start_, edges_;
};

// Uniform grid over all points, for the dependee search.
struct PointGrid {
  int64_t x0 = 0, y0 = 0, cell = 1;
  int64_t nx = 1, ny = 1;
  std::vector<uint32_t> start;  // CSR, nx*ny + 1
  std::vector<uint32_t> items;

  void build(const std::vector<ivec2>& pts) {
    if (pts.empty()) return;
    int64_t xmin = pts[0][0], xmax = xmin, ymin = pts[0][1], ymax = ymin;
    for (const auto& p : pts) {
      xmin = std::min<int64_t>(xmin, p[0]);
      xmax = std::max<int64_t>(xmax, p[0]);
      ymin = std::min<int64_t>(ymin, p[1]);
      ymax = std::max<int64_t>(ymax, p[1]);
    }
    const double area = double(xmax - xmin + 1) * double(ymax - ymin + 1);
    cell = std::max<int64_t>(1, static_cast<int64_t>(std::sqrt(area / double(pts.size()) * 2.0)));
    x0 = xmin;
    y0 = ymin;
    nx = (xmax - xmin) / cell + 1;
    ny = (ymax - ymin) / cell + 1;
    start.assign(static_cast<size_t>(nx * ny + 1), 0);
    for (const auto& p : pts) ++start[static_cast<size_t>(cell_of(p[0], p[1])) + 1];
    std::partial_sum(start.begin(), start.end(), start.begin());
    items.resize(pts.size());
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (uint32_t i = 0; i < pts.size(); ++i)
      items[fill[static_cast<size_t>(cell_of(pts[i][0], pts[i][1]))]++] = i;
  }
  int64_t cx(int64_t x) const { return std::clamp<int64_t>((x - x0) / cell, 0, nx - 1); }
  int64_t cy(int64_t y) const { return std::clamp<int64_t>((y - y0) / cell, 0, ny - 1); }
  int64_t cell_of(int64_t x, int64_t y) const { return cx(x) + nx * cy(y); }
};

float round_up(double v) {
  if (v >= double(std::numeric_limits<float>::max())) return std::numeric_limits<float>::max();
  float f = static_cast<float>(v);
  if (double(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

// Iterative Tarjan: component id per node; components are numbered in
// reverse topological order (a component gets its id after every
// component it reaches).
uint32_t strongly_connected(const std::vector<uint32_t>& adj_start,
                            const std::vector<uint32_t>& adj, std::vector<uint32_t>& comp) {
  const auto n = static_cast<uint32_t>(adj_start.size() - 1);
  std::vector<uint32_t> index(n, kNone), low(n, 0), stack;
  std::vector<char> on_stack(n, 0);
  comp.assign(n, kNone);
  uint32_t next_index = 0, next_comp = 0;
  struct Frame {
    uint32_t v, edge;
  };
  std::vector<Frame> call;
  for (uint32_t s = 0; s < n; ++s) {
    if (index[s] != kNone) continue;
    call.push_back({s, adj_start[s]});
    index[s] = low[s] = next_index++;
    stack.push_back(s);
    on_stack[s] = 1;
    while (!call.empty()) {
      Frame& f = call.back();
      if (f.edge < adj_start[f.v + 1]) {
        const uint32_t w = adj[f.edge++];
        if (index[w] == kNone) {
          index[w] = low[w] = next_index++;
          stack.push_back(w);
          on_stack[w] = 1;
          call.push_back({w, adj_start[w]});
        } else if (on_stack[w]) {
          low[f.v] = std::min(low[f.v], index[w]);
        }
        continue;
      }
      const uint32_t v = f.v;
      call.pop_back();
      if (!call.empty()) low[call.back().v] = std::min(low[call.back().v], low[v]);
      if (low[v] == index[v]) {
        uint32_t w;
        do {
          w = stack.back();
          stack.pop_back();
          on_stack[w] = 0;
          comp[w] = next_comp;
        } while (w != v);
        ++next_comp;
      }
    }
  }
  return next_comp;
}

// What build_lod's steps hand on: the points of every line, per line and
// concatenated, and per point its own error, always-flag and dependency
// edges.
struct LodWork {
  std::vector<ivec2> all;                   // every line's points; closed rings repeat the first
  std::vector<std::vector<ivec2>> local;    // per line, as in `all`
  std::vector<uint32_t> point_line;         // per point of `all`: its line
  std::vector<BlgTree> trees;               // per line (§3.1)
  std::vector<double> e0;                   // per point: its own error
  std::vector<char> always;                 // per point: a line end, always drawn
  std::vector<std::vector<uint32_t>> deps;  // per point s: dependency edges s -> j
};

// The global point array (closed rings repeat their first point at the
// end) and out.line_points; throws input_error for a line with too few
// points.
void gather_lod_points(const std::vector<LodInputLine>& lines, LodSet& out, LodWork& w) {
  const auto nlines = static_cast<uint32_t>(lines.size());
  w.local.resize(nlines);
  for (uint32_t li = 0; li < nlines; ++li) {
    const auto& in = lines[li];
    if (in.points.size() < 2 || (in.closed && in.points.size() < 3))
      fail<input_error>(
          kLodStage, "line " + std::to_string(in.line) + ": " + std::to_string(in.points.size()) +
                         " points are too few for a " + (in.closed ? "closed ring" : "line"));
    w.local[li] = in.points;
    if (in.closed) w.local[li].push_back(in.points.front());
    out.line_points[li] = {static_cast<uint32_t>(w.all.size()),
                           static_cast<uint32_t>(w.local[li].size())};
    w.all.insert(w.all.end(), w.local[li].begin(), w.local[li].end());
  }
  w.point_line.resize(w.all.size());
  for (uint32_t li = 0; li < nlines; ++li)
    for (uint32_t k = 0; k < out.line_points[li][1]; ++k)
      w.point_line[out.line_points[li][0] + k] = li;
}

// Per point: its own error e0 (top-down over each tree, parents before
// children; under dp_exact no more than its parent's), the tree edges
// (§3.3 saturation edges) and the always-flag of the line ends.
void own_errors(const std::vector<uvec2>& line_points, const LodOptions& options, LodWork& w) {
  const size_t npts = w.all.size();
  w.e0.assign(npts, 0.0);
  w.always.assign(npts, 0);
  w.deps.resize(npts);
  for (uint32_t li = 0; li < line_points.size(); ++li) {
    const BlgTree& t = w.trees[li];
    const uint32_t base = line_points[li][0];
    const uint32_t n = line_points[li][1];
    w.always[base] = w.always[base + n - 1] = 1;  // line ends are always drawn
    // e0 top-down (parents are created before children, so a preorder walk).
    if (t.root == kNone) continue;
    std::vector<uint32_t> stack{t.root};
    while (!stack.empty()) {
      const uint32_t i = stack.back();
      stack.pop_back();
      double e = t.error[i];
      if (options.error_rule == LodErrorRule::dp_exact && t.parent[i] != kNone)
        e = std::min(e, w.e0[base + t.parent[i]]);
      w.e0[base + i] = e;
      for (uint32_t c : {t.child_l[i], t.child_r[i]})
        if (c != kNone) {
          w.deps[base + i].push_back(base + c);  // §3.3 saturation edge
          stack.push_back(c);
        }
    }
  }
}

// §3.2 the attributed segment set (rules 1-3): per node its baseline
// (generator = parent, splitter = node), plus the original segments; per
// line sorted by (a, b), into out.segments, out.line_range and the stats.
void attributed_segments(const std::vector<BlgTree>& trees, LodSet& out) {
  for (uint32_t li = 0; li < trees.size(); ++li) {
    const BlgTree& t = trees[li];
    const uint32_t base = out.line_points[li][0];
    const uint32_t n = out.line_points[li][1];
    std::vector<decal::LodSegment> segs;
    segs.reserve(2 * n);
    if (n == 2) segs.push_back({base, base + 1, kNone, kNone});
    for (uint32_t i = 1; i + 1 < n; ++i) {
      const uint32_t gen = t.parent[i] == kNone ? kNone : base + t.parent[i];
      segs.push_back({base + t.span_l[i], base + t.span_r[i], gen, base + i});
      if (i - t.span_l[i] == 1) segs.push_back({base + t.span_l[i], base + i, base + i, kNone});
      if (t.span_r[i] - i == 1) segs.push_back({base + i, base + t.span_r[i], base + i, kNone});
    }
    std::sort(segs.begin(), segs.end(),
              [](const auto& a, const auto& b) { return a.a != b.a ? a.a < b.a : a.b < b.b; });
    out.line_range[li] = {static_cast<uint32_t>(out.segments.size()),
                          static_cast<uint32_t>(segs.size())};
    out.segments.insert(out.segments.end(), segs.begin(), segs.end());
    out.stats.original_segments += n - 1;
  }
  out.stats.lines = static_cast<uint32_t>(trees.size());
  out.stats.attributed_segments = out.segments.size();
}

// The dependees of point s (a node of its line's tree; none for a line
// end), sorted: the points of other lines, or of its own line outside the
// sub-line, inside or on the closed polygon of the sub-line s's baseline
// replaces, but for points on the baseline's ends.
std::vector<uint32_t> dependees_of(uint32_t s, const LodWork& w, const PointGrid& grid,
                                   const std::vector<uvec2>& line_points) {
  std::vector<uint32_t> mine;
  const uint32_t li = w.point_line[s];
  const uint32_t base = line_points[li][0];
  const uint32_t i = s - base;
  const BlgTree& t = w.trees[li];
  if (i >= t.span_l.size() || t.span_l[i] == kNone) return mine;
  const auto& pts = w.local[li];
  const uint32_t l = t.span_l[i], r = t.span_r[i];
  int64_t xmin = pts[l][0], xmax = xmin, ymin = pts[l][1], ymax = ymin;
  for (uint32_t k = l; k <= r; ++k) {
    xmin = std::min<int64_t>(xmin, pts[k][0]);
    xmax = std::max<int64_t>(xmax, pts[k][0]);
    ymin = std::min<int64_t>(ymin, pts[k][1]);
    ymax = std::max<int64_t>(ymax, pts[k][1]);
  }
  const SpanPolygon polygon(pts, l, r, ymin, ymax);
  for (int64_t gy = grid.cy(ymin); gy <= grid.cy(ymax); ++gy)
    for (int64_t gx = grid.cx(xmin); gx <= grid.cx(xmax); ++gx) {
      const auto c = static_cast<size_t>(gx + grid.nx * gy);
      for (uint32_t k = grid.start[c]; k < grid.start[c + 1]; ++k) {
        const uint32_t q = grid.items[k];
        if (w.point_line[q] == li && q >= base + l && q <= base + r) continue;
        const Vec qv{w.all[q][0], w.all[q][1]};
        if (qv.x < xmin || qv.x > xmax || qv.y < ymin || qv.y > ymax) continue;
        // A point on an end of the baseline is a joint with this line,
        // not something the baseline can cross.
        if ((qv.x == pts[l][0] && qv.y == pts[l][1]) || (qv.x == pts[r][0] && qv.y == pts[r][1]))
          continue;
        if (polygon.inside_or_on(qv)) mine.push_back(q);
      }
    }
  std::sort(mine.begin(), mine.end());
  return mine;
}

// §3.4 dependees: points (of any LOD line) inside the closed polygon of the
// sub-line a node's baseline replaces. Excluding the node while such a
// point is drawn could make the baseline cross a line the original does
// not cross; the polygon (not only the triangle of §3.4) makes that a
// guarantee: a segment crossing the baseline with both ends outside the
// polygon also crosses the original sub-line. Found in parallel, added to
// each point's edges in point order.
void add_dependees(const std::vector<uvec2>& line_points, LodWork& w, LodStats& stats) {
  const auto npts = static_cast<uint32_t>(w.all.size());
  PointGrid grid;
  grid.build(w.all);
  std::vector<std::vector<uint32_t>> found(npts);
  tbb::parallel_for(uint32_t(0), npts,
                    [&](uint32_t s) { found[s] = dependees_of(s, w, grid, line_points); });
  for (uint32_t s = 0; s < npts; ++s) {
    stats.dependee_edges += found[s].size();
    w.deps[s].insert(w.deps[s].end(), found[s].begin(), found[s].end());
  }
}

// Per component of the dependency graph (cycles condensed into proxy
// points, §3.4): its evaluation point and the saturated e*, d* and
// always-flag.
struct Saturated {
  std::vector<uint32_t> comp;  // per point
  std::vector<ivec2> eval;
  std::vector<float> estar, dstar;
  std::vector<char> always;
};

// Condenses cycles (§3.4, proxy points: the rounded mean of the members)
// and saturates e*, d* over the DAG, successors first.
Saturated saturate(const LodWork& w, LodStats& stats) {
  const auto npts = static_cast<uint32_t>(w.all.size());
  std::vector<uint32_t> adj_start(npts + 1, 0), adj;
  for (uint32_t s = 0; s < npts; ++s) adj_start[s + 1] = adj_start[s] + uint32_t(w.deps[s].size());
  adj.reserve(adj_start.back());
  for (const auto& d : w.deps) adj.insert(adj.end(), d.begin(), d.end());
  Saturated z;
  const uint32_t ncomp = strongly_connected(adj_start, adj, z.comp);

  std::vector<std::vector<uint32_t>> members(ncomp);
  for (uint32_t p = 0; p < npts; ++p) members[z.comp[p]].push_back(p);
  z.eval.resize(ncomp);
  z.estar.resize(ncomp);
  z.dstar.resize(ncomp);
  z.always.assign(ncomp, 0);
  const auto& all = w.all;
  for (uint32_t c = 0; c < ncomp; ++c) {  // reverse topological: successors first
    const auto& m = members[c];
    double sx = 0, sy = 0, e = 0;
    bool alw = false;
    for (uint32_t p : m) {
      sx += all[p][0];
      sy += all[p][1];
      e = std::max(e, w.e0[p]);
      alw = alw || w.always[p];
    }
    z.eval[c] = {static_cast<int32_t>(std::llround(sx / double(m.size()))),
                 static_cast<int32_t>(std::llround(sy / double(m.size())))};
    double d = 0;
    if (m.size() > 1) {
      ++stats.cycles;
      stats.points_in_cycles += m.size();
      for (uint32_t p : m)
        d = std::max(
            d, std::hypot(double(all[p][0] - z.eval[c][0]), double(all[p][1] - z.eval[c][1])) * kQ +
                   1e-3);
    }
    for (uint32_t p : m)
      for (uint32_t k = adj_start[p]; k < adj_start[p + 1]; ++k) {
        const uint32_t y = z.comp[adj[k]];
        if (y == c) continue;
        alw = alw || z.always[y];
        e = std::max(e, double(z.estar[y]));
        const double dist =
            std::hypot(double(z.eval[c][0] - z.eval[y][0]), double(z.eval[c][1] - z.eval[y][1])) *
            kQ;
        d = std::max(d, dist + double(z.dstar[y]) + 1e-3);
      }
    z.always[c] = alw;
    z.estar[c] = alw ? std::numeric_limits<float>::max() : round_up(e);
    z.dstar[c] = alw ? 0.0f : round_up(d);
  }
  return z;
}

}  // namespace
}  // namespace detail

LodSet build_lod(const std::vector<LodInputLine>& lines, const LodOptions& options) {
  using namespace detail;
  LodSet out;
  const auto nlines = static_cast<uint32_t>(lines.size());
  out.line_points.resize(nlines);
  out.line_range.resize(nlines);
  LodWork w;
  gather_lod_points(lines, out, w);
  const auto npts = static_cast<uint32_t>(w.all.size());

  // §3.1 BLG-trees, one per line, in parallel.
  w.trees.resize(nlines);
  tbb::parallel_for(uint32_t(0), nlines,
                    [&](uint32_t li) { w.trees[li] = build_blg(w.local[li]); });
  own_errors(out.line_points, options, w);
  attributed_segments(w.trees, out);
  if (options.dependees && npts > 0) add_dependees(out.line_points, w, out.stats);
  const Saturated z = saturate(w, out.stats);

  out.points.resize(npts);
  for (uint32_t p = 0; p < npts; ++p) {
    const uint32_t c = z.comp[p];
    auto& lp = out.points[p];
    lp.x = w.all[p][0];
    lp.y = w.all[p][1];
    lp.eval_x = z.eval[c][0];
    lp.eval_y = z.eval[c][1];
    lp.e_star = z.estar[c];
    lp.d_star = z.dstar[c];
    lp.line = lines[w.point_line[p]].line;
    lp.flags = z.always[c] ? decal::kLodPointAlways : 0u;
    if (z.always[c]) ++out.stats.always_points;
  }
  return out;
}

}  // namespace prep
