// The CPU counterpart of the GL dynamic-line pass (detail/dynamic_cpu.hpp).
#include "detail/dynamic_cpu.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "decal/format.hpp"
#include "decal/lod.hpp"

namespace prep::render {

LodView lod_view(const Camera& cam, uint32_t H, double zmin, double zmax, double tolerance_px) {
  LodView v;
  if (cam.projection == Projection::orthographic) {
    v.base = tolerance_px * detail::ortho_pixel_metres(cam, H);
    return v;
  }
  v.cx = cam.eye[0];
  v.cy = cam.eye[1];
  v.cz = cam.eye[2] > zmax ? cam.eye[2] - zmax : (cam.eye[2] < zmin ? zmin - cam.eye[2] : 0.0);
  v.slope = tolerance_px * detail::pixel_metres_per_metre(cam, H);
  return v;
}

}  // namespace prep::render

namespace prep::render::detail {

namespace {

template <class T>
std::vector<T> blob(const DecalSource& s, decal::BlobId id) {
  for (const DecalSource::Blob& b : s.blobs)
    if (b.id == id) {
      std::vector<T> v(b.bytes / sizeof(T));
      std::memcpy(v.data(), b.data, v.size() * sizeof(T));
      return v;
    }
  return {};
}

using P2 = std::array<double, 2>;

double cross2(const P2& a, const P2& b) {
  return a[0] * b[1] - a[1] * b[0];
}
P2 minus(const P2& a, const P2& b) {
  return {a[0] - b[0], a[1] - b[1]};
}
P2 plus(const P2& a, const P2& b) {
  return {a[0] + b[0], a[1] + b[1]};
}
P2 scaled(const P2& a, double s) {
  return {a[0] * s, a[1] * s};
}
double dot2(const P2& a, const P2& b) {
  return a[0] * b[0] + a[1] * b[1];
}
bool in_triangle(const P2& p, const P2& a, const P2& b, const P2& c) {
  const double d1 = cross2(minus(b, a), minus(p, a)), d2 = cross2(minus(c, b), minus(p, b)),
               d3 = cross2(minus(a, c), minus(p, c));
  return !((d1 < 0 || d2 < 0 || d3 < 0) && (d1 > 0 || d2 > 0 || d3 > 0));
}
P2 left_normal(const P2& from, const P2& to) {
  const P2 d = minus(to, from);
  const double l = std::sqrt(dot2(d, d));
  return l > 0 ? P2{-d[1] / l, d[0] / l} : P2{0, 0};
}
P2 unit(const P2& a) {
  const double l = std::sqrt(dot2(a, a));
  return l > 0 ? scaled(a, 1 / l) : a;
}

// Frustum outcode of clip coordinates (dyn_cull.comp.glsl).
uint32_t outcode(const std::array<double, 4>& c) {
  uint32_t o = 0;
  if (c[0] < -c[3]) o |= 1u;
  if (c[0] > c[3]) o |= 2u;
  if (c[1] < -c[3]) o |= 4u;
  if (c[1] > c[3]) o |= 8u;
  if (c[3] <= 0) o |= 16u;
  return o;
}

}  // namespace

// The lod_*.comp.glsl passes in double precision: the LOD lines' vertices
// leave the vertex chains (lod_mask), the visible segments
// (decal::visible_segments, lod_select) link their neighbours, and each one
// not outside a frustum plane becomes a segment between its points'
// dynamic vertices (lod_segments).
void DynamicLinesCpu::add_lod_segments(const DecalSource& source, const DynamicLod& lod,
                                       const Camera& cam, uint32_t H,
                                       const std::vector<std::array<int32_t, 4>>& verts,
                                       const std::vector<uint32_t>& codes,
                                       std::vector<char>& keep) {
  const auto points = blob<decal::LodPoint>(source, decal::BlobId::lod_points);
  const auto segs = blob<decal::LodSegment>(source, decal::BlobId::lod_segments);
  if (!lod.on || points.empty() || segs.empty()) return;
  const decal::LodDrawMap map =
      decal::lod_draw_map(points, segs, blob<uvec2>(source, decal::BlobId::lod_line_range), verts,
                          blob<uint32_t>(source, decal::BlobId::dyn_line_start),
                          blob<std::array<int32_t, 2>>(source, decal::BlobId::dyn_prev_next));
  for (size_t v = 0; v < verts.size(); ++v) {
    const auto line = size_t(verts[v][3]);
    if (line < map.line_drawn.size() && map.line_drawn[line]) keep[v] = 0;
  }
  const LodView lv = lod_view(cam, H, lod.zmin, lod.zmax, lod.tolerance_px);
  const std::vector<uint32_t> visible =
      decal::visible_segments(points, segs, decal::LodCamera{lv.cx, lv.cy, lv.cz},
                              decal::LinearThreshold{lv.base, lv.slope});
  constexpr uint32_t kNone = decal::kLodNone;
  std::vector<uint32_t> prev_of(points.size(), kNone), next_of(points.size(), kNone);
  for (uint32_t s : visible) {
    next_of[segs[s].a] = segs[s].b;
    prev_of[segs[s].b] = segs[s].a;
  }
  auto plan = [&](uint32_t v) {
    return P2{verts[v][0] * decal::kQuantumMetres, verts[v][1] * decal::kQuantumMetres};
  };
  uint64_t drawn = 0;
  for (uint32_t s : visible) {
    const uint32_t a = segs[s].a, b = segs[s].b;
    const uint32_t va = map.vertex[a], vb = map.vertex[b];
    if (va == kNone || vb == kNone) continue;
    if ((codes[va] & codes[vb] & 31u) != 0) continue;  // both outside one plane
    const uint32_t ea = map.end[a], eb = map.end[b];
    const uint32_t pa = ea == kNone ? prev_of[a] : (ea == a ? kNone : prev_of[ea]);
    const uint32_t nb = eb == kNone ? next_of[b] : (eb == b ? kNone : next_of[eb]);
    Segment seg;
    seg.a = plan(va);
    seg.b = plan(vb);
    seg.has_prev = va != vb && pa != kNone && map.vertex[pa] != kNone;
    seg.has_next = va != vb && nb != kNone && map.vertex[nb] != kNone;
    seg.prev = seg.has_prev ? plan(map.vertex[pa]) : seg.a;
    seg.next = seg.has_next ? plan(map.vertex[nb]) : seg.b;
    seg.line = uint32_t(verts[va][3]);
    segments_.push_back(seg);
    ++drawn;
  }
  lod_counts_ = {map.lines, visible.size(), drawn, map.original_segments};
}

DynamicLinesCpu::DynamicLinesCpu(const DecalSource& source, const Camera& cam, uint32_t W,
                                 uint32_t H, const DynamicLod& lod) {
  const auto verts = blob<std::array<int32_t, 4>>(source, decal::BlobId::dyn_vertices);
  const auto pn = blob<std::array<int32_t, 2>>(source, decal::BlobId::dyn_prev_next);
  const auto starts = blob<uint32_t>(source, decal::BlobId::dyn_line_start);
  props_ = blob<decal::LineProps>(source, decal::BlobId::dyn_line_props);
  if (verts.empty() || starts.empty() || pn.size() != verts.size()) return;
  eye_ = cam.eye;
  mpp_ortho_ = detail::ortho_pixel_metres(cam, H);
  mpp_per_metre_ = detail::pixel_metres_per_metre(cam, H);
  const double limit = source.miter_limit_deg * 3.14159265358979323846 / 180.0;
  cos_limit_ = std::cos(limit);
  // The farthest a corner reaches from its vertex in half widths: a miter
  // tip (1 / sin(theta / 2) at the limit), a bevel corner, a round cap.
  reach_ = std::max(1.0 / std::sin(limit / 2), std::sqrt(2.0)) * 1.01;
  for (const decal::LineProps& p : props_) max_hw_px_ = std::max<double>(max_hw_px_, p.half_width);
  for (float m : source.min_width_m) min_hw_m_.push_back(0.5 * double(m));
  for (double m : min_hw_m_) max_min_hw_m_ = std::max(max_min_hw_m_, m);

  const Mat4 vp = mat_mul(projection_matrix(cam, double(W) / H), view_matrix(cam, cam.eye));
  vp_ = vp;
  near_w_ = cam.projection == Projection::perspective ? cam.near : 0.0;
  width_ = W;
  height_ = H;
  if (source.view.dashes && source.view.dashes->table.any()) dashes_ = source.view.dashes;
  auto clip = [&](size_t v) {
    const double x = verts[v][0] * decal::kQuantumMetres, y = verts[v][1] * decal::kQuantumMetres,
                 z = verts[v][2] * decal::kQuantumMetres;
    std::array<double, 4> c{};
    for (int r = 0; r < 4; ++r) c[r] = vp[r] * x + vp[4 + r] * y + vp[8 + r] * z + vp[12 + r];
    return c;
  };
  auto pixel_of = [&](const std::array<double, 4>& c) {
    return std::array<int64_t, 2>{int64_t(std::floor((c[0] / c[3] * 0.5 + 0.5) * W)),
                                  int64_t(std::floor((c[1] / c[3] * 0.5 + 0.5) * H))};
  };
  auto plan = [&](size_t v) {
    return P2{verts[v][0] * decal::kQuantumMetres, verts[v][1] * decal::kQuantumMetres};
  };
  // dyn_cull: the vertices kept, with their outcodes.
  std::vector<uint32_t> codes(verts.size());
  std::vector<char> keep(verts.size());
  for (size_t v = 0; v < verts.size(); ++v) {
    const auto c = clip(v);
    codes[v] = outcode(c);
    const uint32_t line = uint32_t(verts[v][3]);
    bool k =
        (line < starts.size() && v == starts[line]) || pn[v][0] < 0 || pn[v][1] < 0 || c[3] <= 0;
    if (!k) {
      const auto cp = clip(size_t(pn[v][0]));
      k = cp[3] <= 0 || pixel_of(cp) != pixel_of(c);
    }
    keep[v] = k;
  }
  add_lod_segments(source, lod, cam, H, verts, codes, keep);
  // dyn_segments: per line, consecutive kept vertices (closed lines wrap).
  for (size_t line = 0; line < starts.size() && line < props_.size(); ++line) {
    const size_t first = starts[line],
                 end = line + 1 < starts.size() ? starts[line + 1] : verts.size();
    std::vector<size_t> kept;
    for (size_t v = first; v < end; ++v)
      if (keep[v]) kept.push_back(v);
    const bool closed = pn[first][0] >= 0;
    const size_t n = kept.size();
    // Dashes: the prefix sum of the kept segments' screen lengths.
    auto at3 = [&](size_t v) {
      return std::array<double, 3>{verts[v][0] * decal::kQuantumMetres,
                                   verts[v][1] * decal::kQuantumMetres,
                                   verts[v][2] * decal::kQuantumMetres};
    };
    std::vector<double> cum(n, 0.0);
    if (dashes_)
      for (size_t k = 0; k + 1 < n; ++k)
        cum[k + 1] = cum[k] + screen_length(clip(kept[k]), clip(kept[k + 1]));
    for (size_t k = 0; k < n; ++k) {
      const size_t next = k + 1 < n ? k + 1 : (closed ? 0 : n);
      if (next == n || next == k) continue;
      const size_t prev = k > 0 ? k - 1 : (closed ? n - 1 : n);
      const size_t next2 = next + 1 < n ? next + 1 : (closed ? 0 : n);
      const size_t va = kept[k], vb = kept[next];
      if ((codes[va] & codes[vb] & 31u) != 0) continue;  // both outside one plane
      Segment s;
      s.a = plan(va);
      s.b = plan(vb);
      s.has_prev = prev != n;
      s.has_next = next2 != n;
      s.prev = s.has_prev ? plan(kept[prev]) : s.a;
      s.next = s.has_next ? plan(kept[next2]) : s.b;
      s.line = uint32_t(line);
      s.a3 = at3(va);
      s.b3 = at3(vb);
      s.s0 = cum[k];
      segments_.push_back(s);
    }
  }
  if (segments_.empty()) return;
  // The grid: about one segment per cell.
  double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
  for (const Segment& s : segments_) {
    x0 = std::min({x0, s.a[0], s.b[0]});
    y0 = std::min({y0, s.a[1], s.b[1]});
    x1 = std::max({x1, s.a[0], s.b[0]});
    y1 = std::max({y1, s.a[1], s.b[1]});
  }
  cell_ = std::max(std::sqrt(std::max((x1 - x0) * (y1 - y0), 1.0) / double(segments_.size())), 1.0);
  gx0_ = x0;
  gy0_ = y0;
  gnx_ = int64_t((x1 - x0) / cell_) + 1;
  gny_ = int64_t((y1 - y0) / cell_) + 1;
  std::vector<std::vector<uint32_t>> cells(size_t(gnx_ * gny_));
  for (uint32_t k = 0; k < segments_.size(); ++k) {
    const Segment& s = segments_[k];
    const int64_t i0 = int64_t((std::min(s.a[0], s.b[0]) - gx0_) / cell_),
                  i1 = int64_t((std::max(s.a[0], s.b[0]) - gx0_) / cell_),
                  j0 = int64_t((std::min(s.a[1], s.b[1]) - gy0_) / cell_),
                  j1 = int64_t((std::max(s.a[1], s.b[1]) - gy0_) / cell_);
    for (int64_t j = j0; j <= j1; ++j)
      for (int64_t i = i0; i <= i1; ++i) cells[size_t(j * gnx_ + i)].push_back(k);
  }
  cell_start_.assign(cells.size() + 1, 0);
  for (size_t c = 0; c < cells.size(); ++c) {
    cell_start_[c + 1] = cell_start_[c] + uint32_t(cells[c].size());
    cell_items_.insert(cell_items_.end(), cells[c].begin(), cells[c].end());
  }
}

std::array<double, 4> DynamicLinesCpu::clip_of(const std::array<double, 3>& x) const {
  std::array<double, 4> c{};
  for (int r = 0; r < 4; ++r)
    c[r] = vp_[r] * x[0] + vp_[4 + r] * x[1] + vp_[8 + r] * x[2] + vp_[12 + r];
  return c;
}

// dyn_common.glsl screen_length: the part in front of the near plane.
double DynamicLinesCpu::screen_length(std::array<double, 4> ca, std::array<double, 4> cb) const {
  if (ca[3] < near_w_ && cb[3] < near_w_) return 0.0;
  auto mix = [](const std::array<double, 4>& x, const std::array<double, 4>& y, double t) {
    std::array<double, 4> m{};
    for (int r = 0; r < 4; ++r) m[r] = x[r] + (y[r] - x[r]) * t;
    return m;
  };
  if (ca[3] < near_w_)
    ca = mix(ca, cb, (near_w_ - ca[3]) / (cb[3] - ca[3]));
  else if (cb[3] < near_w_)
    cb = mix(cb, ca, (near_w_ - cb[3]) / (ca[3] - cb[3]));
  const double dx = (cb[0] / cb[3] - ca[0] / ca[3]) * 0.5 * width_,
               dy = (cb[1] / cb[3] - ca[1] / ca[3]) * 0.5 * height_;
  return std::sqrt(dx * dx + dy * dy);
}

// dyn_lists.frag.glsl dash_own_side: p lies on the segment's side of the
// bisector at each corner it has.
bool DynamicLinesCpu::dash_own_side(const Segment& s, const P2& p) const {
  P2 d = minus(s.b, s.a);
  d = dot2(d, d) > 0 ? unit(d) : P2{1, 0};
  auto side = [&](const P2& dother) {
    P2 t = dot2(dother, dother) > 0 ? plus(unit(dother), d) : d;
    if (dot2(t, t) < 1e-12) t = d;
    return t;
  };
  if (s.has_prev && dot2(minus(p, s.a), side(minus(s.a, s.prev))) < 0) return false;
  if (s.has_next && dot2(minus(p, s.b), side(minus(s.next, s.b))) > 0) return false;
  return true;
}

double DynamicLinesCpu::dash_s(const Segment& s, const P2& p) const {
  const P2 ab = minus(s.b, s.a);
  const double len2 = dot2(ab, ab);
  const double t = len2 > 0 ? std::clamp(dot2(minus(p, s.a), ab) / len2, 0.0, 1.0) : 0.0;
  const std::array<double, 3> q{s.a3[0] + t * (s.b3[0] - s.a3[0]),
                                s.a3[1] + t * (s.b3[1] - s.a3[1]),
                                s.a3[2] + t * (s.b3[2] - s.a3[2])};
  return s.s0 + screen_length(clip_of(s.a3), clip_of(q));
}

double DynamicLinesCpu::metres_per_pixel(const Vec3& p) const {
  return mpp_ortho_ > 0 ? mpp_ortho_ : std::sqrt(dot(sub(p, eye_), sub(p, eye_))) * mpp_per_metre_;
}

// dyn_lists.frag.glsl `covers`, in double precision.
bool DynamicLinesCpu::covers(const Segment& s, const P2& p, double hw, uint32_t corner) const {
  const P2 a = s.a, b = s.b, d = minus(b, a);
  const double len2 = dot2(d, d);
  if (corner == 0 || len2 == 0) {
    const double t = len2 > 0 ? std::clamp(dot2(minus(p, a), d) / len2, 0.0, 1.0) : 0.0;
    const P2 q = minus(plus(a, scaled(d, t)), p);
    return dot2(q, q) <= hw * hw;
  }
  const P2 n = scaled(P2{-d[1], d[0]}, hw / std::sqrt(len2));
  const P2 pp = s.prev, nn = s.next;
  auto miter_at = [&](const P2& u, const P2& v, const P2& w) -> P2 {
    const P2 e1 = unit(minus(u, v)), e2 = unit(minus(w, v));
    if (dot2(e1, e2) > cos_limit_) return {0, 0};
    const P2 n1 = left_normal(u, v), n2 = left_normal(v, w);
    P2 m = plus(n1, n2);
    if (dot2(m, m) < 1e-12) return scaled(n2, hw);
    m = unit(m);
    return scaled(m, hw / dot2(m, n2));
  };
  if (corner == 1) {
    const P2 ma = s.has_prev ? miter_at(pp, a, b) : P2{0, 0};
    const P2 mb = s.has_next ? miter_at(a, b, nn) : P2{0, 0};
    const bool ra = ma == P2{0, 0}, rb = mb == P2{0, 0};
    const P2 qa = ra ? n : ma, qb = rb ? n : mb;
    if (in_triangle(p, plus(a, qa), minus(a, qa), minus(b, qb)) ||
        in_triangle(p, plus(a, qa), minus(b, qb), plus(b, qb)))
      return true;
    if (ra && dot2(minus(p, a), minus(p, a)) <= hw * hw) return true;
    if (rb && dot2(minus(p, b), minus(p, b)) <= hw * hw) return true;
    return false;
  }
  // bevel
  const double t = dot2(minus(p, a), d) / len2;
  const double side = cross2(d, minus(p, a));
  if (t >= 0 && t <= 1 && side * side <= hw * hw * len2) return true;
  if (s.has_prev) {
    const P2 n1 = scaled(left_normal(pp, a), hw), n2 = n;
    const double turn = cross2(minus(a, pp), d);
    const double sg = turn > 0 ? -1.0 : 1.0;
    if (in_triangle(p, a, plus(a, scaled(n1, sg)), plus(a, scaled(n2, sg)))) return true;
  } else if (dot2(minus(p, a), minus(p, a)) <= hw * hw) {
    return true;
  }
  if (s.has_next) {
    const P2 n1 = n, n2 = scaled(left_normal(b, nn), hw);
    const double turn = cross2(d, minus(nn, b));
    const double sg = turn > 0 ? -1.0 : 1.0;
    if (in_triangle(p, b, plus(b, scaled(n1, sg)), plus(b, scaled(n2, sg)))) return true;
  } else if (dot2(minus(p, b), minus(p, b)) <= hw * hw) {
    return true;
  }
  return false;
}

std::array<float, 4> DynamicLinesCpu::at(const Vec3& p3) const {
  if (segments_.empty()) return {0, 0, 0, 0};
  const double wpix = metres_per_pixel(p3);
  const P2 p{p3[0], p3[1]};
  const double r = std::max(max_hw_px_ * wpix, max_min_hw_m_) * reach_;
  const int64_t i0 = std::max<int64_t>(0, int64_t(std::floor((p[0] - r - gx0_) / cell_))),
                i1 = std::min<int64_t>(gnx_ - 1, int64_t(std::floor((p[0] + r - gx0_) / cell_))),
                j0 = std::max<int64_t>(0, int64_t(std::floor((p[1] - r - gy0_) / cell_))),
                j1 = std::min<int64_t>(gny_ - 1, int64_t(std::floor((p[1] + r - gy0_) / cell_)));
  // (order, line) of the lines covering p; per thread, reused across pixels.
  thread_local std::vector<std::pair<uint32_t, uint32_t>> hits;
  hits.clear();
  auto hit = [&](uint32_t order) {
    for (const auto& h : hits)
      if (h.first == order) return true;
    return false;
  };
  for (int64_t j = j0; j <= j1; ++j)
    for (int64_t i = i0; i <= i1; ++i) {
      const size_t c = size_t(j * gnx_ + i);
      for (uint32_t k = cell_start_[c]; k < cell_start_[c + 1]; ++k) {
        const Segment& s = segments_[cell_items_[k]];
        const decal::LineProps& lp = props_[s.line];
        if (hit(lp.order)) continue;
        // A min_width_m layer: at least that many metres (dyn_lists.frag.glsl).
        const double min_hw =
            min_hw_m_.empty() ? 0.0 : min_hw_m_[std::min<size_t>(lp.layer, min_hw_m_.size() - 1)];
        if (!covers(s, p, std::max(double(lp.half_width) * wpix, min_hw), lp.style & 3u)) continue;
        if (dashes_) {
          const std::span<const double> pattern = dashes_->table.of(lp.layer);
          if (!pattern.empty() && !(dash_own_side(s, p) && dash_on(pattern, dash_s(s, p))))
            continue;
        }
        hits.emplace_back(lp.order, s.line);
      }
    }
  // Front to back in drawing order (order 0 on top), straight alpha.
  double acc[4] = {0, 0, 0, 0};
  std::sort(hits.begin(), hits.end());
  for (const auto& [order, line] : hits) {
    const uint32_t rgba = props_[line].rgba;
    const double a = double(rgba >> 24) / 255.0, w = (1 - acc[3]) * a;
    for (int ch = 0; ch < 3; ++ch) acc[ch] += w * double((rgba >> (8 * ch)) & 0xffu) / 255.0;
    acc[3] += w;
    if (acc[3] >= 1.0) break;
  }
  if (acc[3] <= 0) return {0, 0, 0, 0};
  return {float(acc[0] / acc[3]), float(acc[1] / acc[3]), float(acc[2] / acc[3]), float(acc[3])};
}

}  // namespace prep::render::detail
