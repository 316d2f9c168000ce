// Terrain matching of dynamic lines: thesis §3.2.2 (Algorithm 3.1) and
// §4.2.2 (line subdivision with per-segment offsets from a prefix sum, then
// line sampling), plus the adaptive mode (--terrain-tolerance).
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_scan.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "prep/error.hpp"
#include "prep/stage_error.hpp"
#include "terrain/terrain.hpp"

namespace prep {

namespace {

constexpr double kQ = decal::kQuantumMetres;
// A quantised vertex moves by at most sqrt(2)/2 quanta, so a piece grows by
// at most sqrt(2) quanta: subdivide to lmax minus that (and a little).
constexpr double kLengthReserve = 1.5e-3;
// Adaptive mode holds this much of the tolerance back for the quantisation
// of positions and heights (0.7 mm x slope, 0.5 mm per height).
constexpr double kToleranceReserve = 5e-3;
constexpr double kMinAdaptivePiece = 0.01;  // metres

int32_t quantise(double v) {
  return static_cast<int32_t>(std::llround(v / kQ));
}

// Exclusive prefix sum with oneTBB (thesis §4.2.2 suggests a parallel
// prefix sum for the vertex offsets). out has counts.size() + 1 entries.
std::vector<uint64_t> exclusive_scan(const std::vector<uint64_t>& counts) {
  std::vector<uint64_t> out(counts.size() + 1, 0);
  tbb::parallel_scan(
      tbb::blocked_range<size_t>(0, counts.size()), uint64_t(0),
      [&](const tbb::blocked_range<size_t>& r, uint64_t sum, bool final_scan) {
        for (size_t i = r.begin(); i < r.end(); ++i) {
          if (final_scan) out[i] = sum;
          sum += counts[i];
        }
        return sum;
      },
      [](uint64_t a, uint64_t b) { return a + b; });
  out[counts.size()] = counts.empty() ? 0 : out[counts.size() - 1] + counts.back();
  return out;
}

// One input segment of one line.
struct Segment {
  uint32_t line;
  Point2 a, b;
  bool last_open;  // last segment of an open line: also emits its end vertex
};

struct Kept {
  double s;
  ivec2 q;
  int32_t z;
  Point2 pixel;
};

}  // namespace

double piece_deviation(const DemSampler& dem, std::span<const PixelPathPoint> path, double za,
                       double zb, double* arg) {
  double best = 0, best_s = 0;
  bool any = false;
  auto f_at = [&](double s, double px, double py) {
    return za + s * (zb - za) - dem.height(px, py);
  };
  auto consider = [&](double s, double f) {
    if (!any || std::abs(f) > best) {
      best = std::abs(f);
      best_s = s;
      any = true;
    }
  };
  std::vector<double> us;
  for (size_t k = 0; k + 1 < path.size(); ++k) {
    const PixelPathPoint& p = path[k];
    const PixelPathPoint& q = path[k + 1];
    us.assign({0.0, 1.0});
    // Cuts where the path crosses a line through cell centres (k + 0.5):
    // between cuts the bilinear surface restricted to the path is quadratic.
    auto cuts = [&](double a, double b) {
      const double d = b - a;
      if (d == 0) return;
      const double lo = std::min(a, b), hi = std::max(a, b);
      for (double c = std::ceil(lo - 0.5); c <= std::floor(hi - 0.5); c += 1) {
        const double u = (c + 0.5 - a) / d;
        if (u > 0 && u < 1) us.push_back(u);
      }
    };
    cuts(p.pixel.x, q.pixel.x);
    cuts(p.pixel.y, q.pixel.y);
    std::sort(us.begin(), us.end());
    auto at = [&](double u, double* s) {
      *s = p.s + u * (q.s - p.s);
      return f_at(*s, p.pixel.x + u * (q.pixel.x - p.pixel.x),
                  p.pixel.y + u * (q.pixel.y - p.pixel.y));
    };
    for (size_t i = 0; i + 1 < us.size(); ++i) {
      const double ua = us[i], ub = us[i + 1];
      if (ub <= ua) continue;
      double sa, sm, sb;
      const double fa = at(ua, &sa), fm = at(0.5 * (ua + ub), &sm), fb = at(ub, &sb);
      consider(sa, fa);
      consider(sb, fb);
      // f(t) = fa + B t + A t^2 through t = 0, 1/2, 1; its extremum, if inside.
      const double A = 2 * fa - 4 * fm + 2 * fb, B = -3 * fa + 4 * fm - fb;
      if (A != 0) {
        const double t = -B / (2 * A);
        if (t > 0 && t < 1) {
          double st;
          const double ft = at(ua + t * (ub - ua), &st);
          consider(st, ft);
        }
      }
    }
  }
  if (arg) *arg = best_s;
  return best;
}

namespace {

Point2 pos(const Segment& s, double t) {
  return {s.a.x + t * (s.b.x - s.a.x), s.a.y + t * (s.b.y - s.a.y)};
}

// The fixed subdivision of every segment of every line (Algorithm 3.1) and
// what the adaptive mode and the statistics read from it.
struct Subdivision {
  std::vector<Segment> segs;
  std::vector<uint32_t> line_first_seg;  // per line, plus one past the end
  std::vector<uint64_t> pieces, counts;  // per segment: pieces, vertices emitted
  std::vector<uint64_t> offset;          // exclusive scan of counts
  std::vector<ivec2> fq;                 // quantised fixed vertices
  std::vector<Point2> fpix;              // their DEM pixel positions (with a DEM)

  // The node after the last fixed vertex of segment k (its b end).
  uint64_t next_node(size_t k) const {
    const Segment& s = segs[k];
    if (s.last_open) return offset[k] + pieces[k];
    if (k + 1 == line_first_seg[s.line + 1])
      return offset[line_first_seg[s.line]];  // closed: wraps
    return offset[k + 1];
  }
};

// Flattens the segments of all lines (closed lines include the closing one).
void flatten_segments(const std::vector<SceneLine>& lines, Subdivision& sub, MatchedLines& out) {
  sub.line_first_seg.assign(lines.size() + 1, 0);
  for (uint32_t li = 0; li < lines.size(); ++li) {
    const SceneLine& l = lines[li];
    const size_t n = l.points.size();
    if (n < 2 || (l.closed && n < 3))
      fail<input_error>(kTerrainStage, "dynamic line " + std::to_string(li) + " (fid " +
                                           std::to_string(l.fid) + "): " + std::to_string(n) +
                                           " points are too few");
    out.vertices_in += n;
    sub.line_first_seg[li] = static_cast<uint32_t>(sub.segs.size());
    const size_t nseg = l.closed ? n : n - 1;
    for (size_t k = 0; k < nseg; ++k)
      sub.segs.push_back({li, l.points[k], l.points[(k + 1) % n], !l.closed && k + 1 == nseg});
  }
  sub.line_first_seg[lines.size()] = static_cast<uint32_t>(sub.segs.size());
}

// Algorithm 3.1: n = floor(|s| / lmax) + 1 pieces when |s| > lmax; the
// quantised positions and their DEM pixel positions.
void subdivide_fixed(double l_eff, DemSampler* dem, Subdivision& sub) {
  const size_t nseg = sub.segs.size();
  sub.pieces.resize(nseg);
  sub.counts.resize(nseg);
  tbb::parallel_for(size_t(0), nseg, [&](size_t k) {
    const Segment& s = sub.segs[k];
    const double len = std::hypot(s.b.x - s.a.x, s.b.y - s.a.y);
    sub.pieces[k] = len > l_eff ? static_cast<uint64_t>(std::floor(len / l_eff)) + 1 : 1;
    sub.counts[k] = sub.pieces[k] + (s.last_open ? 1 : 0);
  });
  sub.offset = exclusive_scan(sub.counts);
  const uint64_t nfixed = sub.offset[nseg];
  sub.fq.resize(nfixed);
  sub.fpix.resize(dem ? nfixed : 0);
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, nseg, 256), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<Point2> scene;
        for (size_t k = r.begin(); k < r.end(); ++k) {
          const Segment& s = sub.segs[k];
          const uint64_t o = sub.offset[k];
          for (uint64_t i = 0; i < sub.counts[k]; ++i) {
            // The end vertex of an open line is the segment's b exactly.
            const Point2 p = i == sub.pieces[k] ? s.b : pos(s, double(i) / double(sub.pieces[k]));
            sub.fq[o + i] = {quantise(p.x), quantise(p.y)};
          }
          if (dem) {
            scene.resize(sub.counts[k]);
            for (uint64_t i = 0; i < sub.counts[k]; ++i)
              scene[i] = {sub.fq[o + i][0] * kQ, sub.fq[o + i][1] * kQ};
            dem->to_pixel(scene, std::span<Point2>(sub.fpix.data() + o, sub.counts[k]));
          }
        }
      });
}

// Loads the DEM window that holds every fixed vertex.
void load_window(const std::vector<Point2>& fpix, DemSampler& dem) {
  if (fpix.empty()) return;
  double x0 = fpix[0].x, x1 = x0, y0 = fpix[0].y, y1 = y0;
  for (const auto& p : fpix) {
    x0 = std::min(x0, p.x);
    x1 = std::max(x1, p.x);
    y0 = std::min(y0, p.y);
    y1 = std::max(y1, p.y);
  }
  dem.load(x0, y0, x1, y1);
}

int32_t z_at(const DemSampler* dem, const Point2& pix) {
  return dem ? quantise(dem->height(pix.x, pix.y)) : 0;
}

// Adaptive mode: per segment, the vertices kept by recursive refinement
// (explicit stack, left to right): a piece is kept when its exact maximum
// deviation is within the bound. Records each segment's deviation and misses.
std::vector<Kept> refine_segment(const Subdivision& sub, size_t k, DemSampler& dem, double bound,
                                 double& dev_out, uint64_t& misses) {
  const Segment& s = sub.segs[k];
  const uint64_t n = sub.pieces[k];
  const uint64_t o = sub.offset[k];
  const double len = std::hypot(s.b.x - s.a.x, s.b.y - s.a.y);
  auto node_pixel = [&](uint64_t i) {
    return i == n ? sub.fpix[sub.next_node(k)] : sub.fpix[o + i];
  };
  auto make = [&](double t) {
    Kept v;
    v.s = t;
    const Point2 p = pos(s, t);
    v.q = {quantise(p.x), quantise(p.y)};
    v.pixel = dem.to_pixel(Point2{v.q[0] * kQ, v.q[1] * kQ});
    v.z = z_at(&dem, v.pixel);
    return v;
  };
  Kept first{0.0, sub.fq[o], z_at(&dem, sub.fpix[o]), sub.fpix[o]};
  const uint64_t e = sub.next_node(k);
  Kept last{1.0, sub.fq[e], z_at(&dem, sub.fpix[e]), sub.fpix[e]};
  std::vector<Kept> mine;
  std::vector<PixelPathPoint> path;
  std::vector<std::pair<Kept, Kept>> stack{{first, last}};
  while (!stack.empty()) {
    auto [a, b] = stack.back();
    stack.pop_back();
    path.clear();
    path.push_back({0.0, a.pixel});
    const double span = b.s - a.s;
    for (uint64_t i = static_cast<uint64_t>(std::floor(a.s * double(n))) + 1; i < n; ++i) {
      const double t = double(i) / double(n);
      if (t >= b.s) break;
      if (t > a.s) path.push_back({(t - a.s) / span, node_pixel(i)});
    }
    path.push_back({1.0, b.pixel});
    double arg = 0.5;
    const double dev = piece_deviation(dem, path, a.z * kQ, b.z * kQ, &arg);
    if (dev <= bound || span * len < kMinAdaptivePiece) {
      if (dev > bound) ++misses;
      dev_out = std::max(dev_out, dev);
      mine.push_back(a);
      continue;
    }
    // Split at the worst point, kept away from the ends.
    const double t = a.s + std::clamp(arg, 0.1, 0.9) * span;
    const Kept m = make(t);
    stack.push_back({m, b});
    stack.push_back({a, m});
  }
  if (s.last_open) mine.push_back(last);
  return mine;
}

// The stored vertices (x, y, z, line) and, with a DEM, which touched filled
// no-data cells or lie outside the raster.
void emit_vertices(const Subdivision& sub, const std::vector<std::vector<Kept>>* kept,
                   const std::vector<uint64_t>& out_offset, DemSampler* dem, MatchedLines& out,
                   std::vector<uint8_t>& touched, std::vector<uint8_t>& outside) {
  tbb::parallel_for(size_t(0), sub.segs.size(), [&](size_t k) {
    const int32_t line = static_cast<int32_t>(sub.segs[k].line);
    if (kept) {
      for (size_t i = 0; i < (*kept)[k].size(); ++i) {
        const Kept& v = (*kept)[k][i];
        const uint64_t o = out_offset[k] + i;
        out.vertices[o] = {v.q[0], v.q[1], v.z, line};
        bool t = false;
        dem->height(v.pixel.x, v.pixel.y, &t);
        touched[o] = t;
        outside[o] = dem->outside(v.pixel.x, v.pixel.y);
      }
      return;
    }
    for (uint64_t i = 0; i < sub.counts[k]; ++i) {
      const uint64_t o = sub.offset[k] + i;
      int32_t z = 0;
      if (dem) {
        bool t = false;
        z = quantise(dem->height(sub.fpix[o].x, sub.fpix[o].y, &t));
        touched[o] = t;
        outside[o] = dem->outside(sub.fpix[o].x, sub.fpix[o].y);
      }
      out.vertices[o] = {sub.fq[o][0], sub.fq[o][1], z, line};
    }
  });
}

// Outline start per line, previous/next with closed outlines wrapping.
void link_lines(const std::vector<SceneLine>& lines, const Subdivision& sub,
                const std::vector<uint64_t>& out_offset, MatchedLines& out) {
  out.line_start.resize(lines.size());
  out.prev_next.resize(out.vertices.size());
  for (uint32_t li = 0; li < lines.size(); ++li) {
    const uint64_t first = out_offset[sub.line_first_seg[li]];
    const uint64_t end = out_offset[sub.line_first_seg[li + 1]];
    out.line_start[li] = static_cast<uint32_t>(first);
    const bool closed = lines[li].closed;
    for (uint64_t v = first; v < end; ++v) {
      const int32_t prev = v > first ? int32_t(v - 1) : (closed ? int32_t(end - 1) : -1);
      const int32_t next = v + 1 < end ? int32_t(v + 1) : (closed ? int32_t(first) : -1);
      out.prev_next[v] = {prev, next};
    }
  }
}

// Longest stored piece, metres.
double longest_piece(const MatchedLines& out) {
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, out.vertices.size()), 0.0,
      [&](const tbb::blocked_range<size_t>& r, double m) {
        for (size_t v = r.begin(); v < r.end(); ++v) {
          const int32_t nx = out.prev_next[v][1];
          if (nx < 0) continue;
          const auto& a = out.vertices[v];
          const auto& b = out.vertices[static_cast<size_t>(nx)];
          m = std::max(m, std::hypot(double(b[0] - a[0]), double(b[1] - a[1])) * kQ);
        }
        return m;
      },
      [](double a, double b) { return std::max(a, b); });
}

// Fixed mode: the deviation of every stored piece from the DEM surface.
void fixed_deviation(const Subdivision& sub, const DemSampler& dem, const MatchedLines& out,
                     std::vector<double>& seg_dev) {
  tbb::parallel_for(size_t(0), sub.segs.size(), [&](size_t k) {
    for (uint64_t i = 0; i < sub.pieces[k]; ++i) {
      const uint64_t a = sub.offset[k] + i;
      const uint64_t b = i + 1 == sub.pieces[k] ? sub.next_node(k) : a + 1;
      const PixelPathPoint path[2] = {{0.0, sub.fpix[a]}, {1.0, sub.fpix[b]}};
      seg_dev[k] = std::max(
          seg_dev[k], piece_deviation(dem, path, out.vertices[a][2] * kQ, out.vertices[b][2] * kQ));
    }
  });
}

}  // namespace

MatchedLines match_terrain(const std::vector<SceneLine>& lines, DemSampler* dem,
                           const MatchOptions& options) {
  MatchedLines out;
  if (!(options.lmax >= 0.01))
    fail<usage_error>(kTerrainStage, "lmax " + std::to_string(options.lmax) + " m is below 0.01 m");
  const bool adaptive = options.tolerance > 0 && dem != nullptr;
  const double l_eff = std::isinf(options.lmax) ? options.lmax : options.lmax - kLengthReserve;

  Subdivision sub;
  flatten_segments(lines, sub, out);
  const size_t nseg = sub.segs.size();
  subdivide_fixed(l_eff, dem, sub);
  out.vertices_fixed = sub.offset[nseg];
  if (dem) load_window(sub.fpix, *dem);

  std::vector<std::vector<Kept>> kept;  // adaptive: per segment, kept vertices
  std::vector<double> seg_dev(nseg, 0.0);
  std::vector<uint64_t> seg_miss(nseg, 0);
  std::vector<uint64_t> out_offset = sub.offset;
  if (adaptive) {
    kept.resize(nseg);
    const double bound = std::max(options.tolerance - kToleranceReserve, options.tolerance * 0.5);
    tbb::parallel_for(size_t(0), nseg, [&](size_t k) {
      kept[k] = refine_segment(sub, k, *dem, bound, seg_dev[k], seg_miss[k]);
    });
    std::vector<uint64_t> kc(nseg);
    for (size_t k = 0; k < nseg; ++k) kc[k] = kept[k].size();
    out_offset = exclusive_scan(kc);
  }
  const uint64_t nout = out_offset[nseg];
  if (nout > uint64_t(std::numeric_limits<int32_t>::max()))
    fail<resource_error>(kTerrainStage,
                         std::to_string(nout) + " dynamic-line vertices exceed int32 indices");
  out.vertices_out = nout;
  out.vertices.resize(nout);
  std::vector<uint8_t> touched(nout, 0), outside(nout, 0);
  emit_vertices(sub, adaptive ? &kept : nullptr, out_offset, dem, out, touched, outside);
  link_lines(lines, sub, out_offset, out);

  // Statistics: longest stored piece, deviation of the stored pieces.
  out.max_piece_length = longest_piece(out);
  if (dem && !adaptive) fixed_deviation(sub, *dem, out, seg_dev);
  for (size_t k = 0; k < nseg; ++k) {
    out.max_deviation = std::max(out.max_deviation, seg_dev[k]);
    out.tolerance_misses += seg_miss[k];
  }
  if (dem) {
    out.terrain = dem->stats();
    out.terrain.samples = nout;
    out.terrain.samples_touching_fill =
        static_cast<uint64_t>(std::count(touched.begin(), touched.end(), 1));
    out.terrain.samples_outside =
        static_cast<uint64_t>(std::count(outside.begin(), outside.end(), 1));
    // Line li holds the vertices from line_start[li] to the next line's start.
    for (size_t li = 0; li < out.line_start.size(); ++li) {
      const size_t end = li + 1 < out.line_start.size() ? out.line_start[li + 1] : size_t(nout);
      out.lines_outside +=
          std::any_of(outside.begin() + out.line_start[li], outside.begin() + std::ptrdiff_t(end),
                      [](uint8_t o) { return o != 0; });
    }
  }
  return out;
}

}  // namespace prep
