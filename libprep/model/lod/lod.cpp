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

}  // namespace
}  // namespace detail

LodSet build_lod(const std::vector<LodInputLine>& lines, const LodOptions& options) {
  using namespace detail;
  LodSet out;
  const auto nlines = static_cast<uint32_t>(lines.size());
  out.line_points.resize(nlines);
  out.line_range.resize(nlines);

  // Global point array; closed rings repeat their first point at the end.
  std::vector<ivec2> all;
  std::vector<std::vector<ivec2>> local(nlines);
  for (uint32_t li = 0; li < nlines; ++li) {
    const auto& in = lines[li];
    if (in.points.size() < 2 || (in.closed && in.points.size() < 3))
      fail<input_error>(
          kLodStage, "line " + std::to_string(in.line) + ": " + std::to_string(in.points.size()) +
                         " points are too few for a " + (in.closed ? "closed ring" : "line"));
    local[li] = in.points;
    if (in.closed) local[li].push_back(in.points.front());
    out.line_points[li] = {static_cast<uint32_t>(all.size()),
                           static_cast<uint32_t>(local[li].size())};
    all.insert(all.end(), local[li].begin(), local[li].end());
  }
  const auto npts = static_cast<uint32_t>(all.size());
  std::vector<uint32_t> point_line(npts);
  for (uint32_t li = 0; li < nlines; ++li)
    for (uint32_t k = 0; k < out.line_points[li][1]; ++k)
      point_line[out.line_points[li][0] + k] = li;

  // §3.1 BLG-trees, one per line, in parallel.
  std::vector<BlgTree> trees(nlines);
  tbb::parallel_for(uint32_t(0), nlines, [&](uint32_t li) { trees[li] = build_blg(local[li]); });

  // Per global point: own error e0, tree children, always-flag.
  std::vector<double> e0(npts, 0.0);
  std::vector<char> always(npts, 0);
  std::vector<std::vector<uint32_t>> deps(npts);  // dependency edges s -> j
  for (uint32_t li = 0; li < nlines; ++li) {
    const BlgTree& t = trees[li];
    const uint32_t base = out.line_points[li][0];
    const uint32_t n = out.line_points[li][1];
    always[base] = always[base + n - 1] = 1;  // line ends are always drawn
    // e0 top-down (parents are created before children, so a preorder walk).
    if (t.root == kNone) continue;
    std::vector<uint32_t> stack{t.root};
    while (!stack.empty()) {
      const uint32_t i = stack.back();
      stack.pop_back();
      double e = t.error[i];
      if (options.error_rule == LodErrorRule::dp_exact && t.parent[i] != kNone)
        e = std::min(e, e0[base + t.parent[i]]);
      e0[base + i] = e;
      for (uint32_t c : {t.child_l[i], t.child_r[i]})
        if (c != kNone) {
          deps[base + i].push_back(base + c);  // §3.3 saturation edge
          stack.push_back(c);
        }
    }
  }

  // §3.2 the attributed segment set (rules 1-3): per node its baseline
  // (generator = parent, splitter = node), plus the original segments.
  for (uint32_t li = 0; li < nlines; ++li) {
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
  out.stats.lines = nlines;
  out.stats.attributed_segments = out.segments.size();

  // §3.4 dependees: points (of any LOD line) inside the closed polygon of the
  // sub-line a node's baseline replaces. Excluding the node while such a
  // point is drawn could make the baseline cross a line the original does
  // not cross; the polygon (not only the triangle of §3.4) makes that a
  // guarantee: a segment crossing the baseline with both ends outside the
  // polygon also crosses the original sub-line.
  if (options.dependees && npts > 0) {
    PointGrid grid;
    grid.build(all);
    std::vector<std::vector<uint32_t>> found(npts);
    tbb::parallel_for(uint32_t(0), npts, [&](uint32_t s) {
      const uint32_t li = point_line[s];
      const uint32_t base = out.line_points[li][0];
      const uint32_t i = s - base;
      const BlgTree& t = trees[li];
      if (i >= t.span_l.size() || t.span_l[i] == kNone) return;
      const auto& pts = local[li];
      const uint32_t l = t.span_l[i], r = t.span_r[i];
      int64_t xmin = pts[l][0], xmax = xmin, ymin = pts[l][1], ymax = ymin;
      for (uint32_t k = l; k <= r; ++k) {
        xmin = std::min<int64_t>(xmin, pts[k][0]);
        xmax = std::max<int64_t>(xmax, pts[k][0]);
        ymin = std::min<int64_t>(ymin, pts[k][1]);
        ymax = std::max<int64_t>(ymax, pts[k][1]);
      }
      auto& mine = found[s];
      const SpanPolygon polygon(pts, l, r, ymin, ymax);
      for (int64_t gy = grid.cy(ymin); gy <= grid.cy(ymax); ++gy)
        for (int64_t gx = grid.cx(xmin); gx <= grid.cx(xmax); ++gx) {
          const auto c = static_cast<size_t>(gx + grid.nx * gy);
          for (uint32_t k = grid.start[c]; k < grid.start[c + 1]; ++k) {
            const uint32_t q = grid.items[k];
            if (point_line[q] == li && q >= base + l && q <= base + r) continue;
            const Vec qv{all[q][0], all[q][1]};
            if (qv.x < xmin || qv.x > xmax || qv.y < ymin || qv.y > ymax) continue;
            // A point on an end of the baseline is a joint with this line,
            // not something the baseline can cross.
            if ((qv.x == pts[l][0] && qv.y == pts[l][1]) ||
                (qv.x == pts[r][0] && qv.y == pts[r][1]))
              continue;
            if (polygon.inside_or_on(qv)) mine.push_back(q);
          }
        }
      std::sort(mine.begin(), mine.end());
    });
    for (uint32_t s = 0; s < npts; ++s) {
      out.stats.dependee_edges += found[s].size();
      deps[s].insert(deps[s].end(), found[s].begin(), found[s].end());
    }
  }

  // Condense cycles (§3.4, proxy points) and saturate e*, d* over the DAG.
  std::vector<uint32_t> adj_start(npts + 1, 0), adj;
  for (uint32_t s = 0; s < npts; ++s) adj_start[s + 1] = adj_start[s] + uint32_t(deps[s].size());
  adj.reserve(adj_start.back());
  for (const auto& d : deps) adj.insert(adj.end(), d.begin(), d.end());
  std::vector<uint32_t> comp;
  const uint32_t ncomp = strongly_connected(adj_start, adj, comp);

  std::vector<std::vector<uint32_t>> members(ncomp);
  for (uint32_t p = 0; p < npts; ++p) members[comp[p]].push_back(p);
  std::vector<ivec2> eval(ncomp);
  std::vector<float> estar(ncomp), dstar(ncomp);
  std::vector<char> comp_always(ncomp, 0);
  for (uint32_t c = 0; c < ncomp; ++c) {  // reverse topological: successors first
    const auto& m = members[c];
    double sx = 0, sy = 0, e = 0;
    bool alw = false;
    for (uint32_t p : m) {
      sx += all[p][0];
      sy += all[p][1];
      e = std::max(e, e0[p]);
      alw = alw || always[p];
    }
    eval[c] = {static_cast<int32_t>(std::llround(sx / double(m.size()))),
               static_cast<int32_t>(std::llround(sy / double(m.size())))};
    double d = 0;
    if (m.size() > 1) {
      ++out.stats.cycles;
      out.stats.points_in_cycles += m.size();
      for (uint32_t p : m)
        d = std::max(
            d,
            std::hypot(double(all[p][0] - eval[c][0]), double(all[p][1] - eval[c][1])) * kQ + 1e-3);
    }
    for (uint32_t p : m)
      for (uint32_t k = adj_start[p]; k < adj_start[p + 1]; ++k) {
        const uint32_t y = comp[adj[k]];
        if (y == c) continue;
        alw = alw || comp_always[y];
        e = std::max(e, double(estar[y]));
        const double dist =
            std::hypot(double(eval[c][0] - eval[y][0]), double(eval[c][1] - eval[y][1])) * kQ;
        d = std::max(d, dist + double(dstar[y]) + 1e-3);
      }
    comp_always[c] = alw;
    estar[c] = alw ? std::numeric_limits<float>::max() : round_up(e);
    dstar[c] = alw ? 0.0f : round_up(d);
  }

  out.points.resize(npts);
  for (uint32_t p = 0; p < npts; ++p) {
    const uint32_t c = comp[p];
    auto& lp = out.points[p];
    lp.x = all[p][0];
    lp.y = all[p][1];
    lp.eval_x = eval[c][0];
    lp.eval_y = eval[c][1];
    lp.e_star = estar[c];
    lp.d_star = dstar[c];
    lp.line = lines[point_line[p]].line;
    lp.flags = comp_always[c] ? decal::kLodPointAlways : 0u;
    if (comp_always[c]) ++out.stats.always_points;
  }
  return out;
}

}  // namespace prep
