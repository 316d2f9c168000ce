// libprep/model/lines.cpp — static lines and outlines (thesis §3.6, §4.2.1
// "Line Segments"): quantised vertices, per-line properties, per-vertex
// corner data, and the widened shape of every segment for cell assignment.
//
// Corner data per vertex (decal::LineCorner), in metres, computed from the
// cleaned double-precision geometry (not the quantised one, so that stored
// corners sit within the representation error of the true ones):
//   bevel_in / bevel_out: half width times the unit normal of the incoming /
//     outgoing segment, on the OUTER side of the turn (decided by CGAL's exact
//     orientation predicate); the left normal where the turn is straight and
//     at line ends; null where the segment does not exist (open line ends).
//   miter (miter style only): vertex -> LEFT miter corner, length
//     hw / sin(theta/2); null at open line ends and where the interior angle
//     theta is below options.miter_limit_deg (round fallback, thesis §4.2.1).
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "detail.hpp"
#include "prep/error.hpp"
#include "prep/model.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace prep::detail {

namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;

struct V2 {
  double x, y;
};
inline V2 sub(V2 a, V2 b) {
  return {a.x - b.x, a.y - b.y};
}
inline V2 unit(V2 a) {
  double l = std::hypot(a.x, a.y);
  return {a.x / l, a.y / l};
}
inline V2 left(V2 u) {
  return {-u.y, u.x};
}

struct LineOut {
  bool kept = false;
  std::string reason;
  std::vector<QPoint> q;
  std::vector<decal::LineCorner> corners;
  decal::LineProps props{};
  double max_err = 0;
};

std::string where_of(const SceneFeatures& s, const SceneLine& l) {
  std::ostringstream m;
  m << "layer '" << (l.layer < s.layers.size() ? s.layers[l.layer].name : std::string("?"))
    << "' fid " << l.fid << " part " << l.part;
  return m.str();
}

LineOut convert_line(const SceneFeatures& scene, const SceneLine& line, const ModelOptions& opt,
                     decal::CornerStyle corner, decal::OutlineMode outline) {
  LineOut out;
  const WhereFn where = [&] { return where_of(scene, line); };
  if (!(line.width > 0) || !std::isfinite(line.width)) {
    out.reason = "line width is not a positive finite number";
    return out;
  }
  // Quantise; drop vertices that quantise onto their predecessor, keeping the
  // first original position of each run for the corner directions.
  std::vector<V2> orig;
  for (const Point2& p : line.points) {
    QPoint q = quantise(p, out.max_err, where);
    if (!out.q.empty() && out.q.back() == q) continue;
    out.q.push_back(q);
    orig.push_back({p.x, p.y});
  }
  bool closed = line.closed;
  if (closed && out.q.size() > 1 && out.q.back() == out.q.front()) {
    out.q.pop_back();
    orig.pop_back();
  }
  if (closed && out.q.size() < 3) closed = false;
  if (out.q.size() < 2) {
    out.reason = "fewer than 2 distinct vertices at 1 mm resolution";
    return out;
  }
  const size_t n = out.q.size();
  const double hw = line.width * 0.5 * (outline == decal::OutlineMode::normal ? 1.0 : 2.0);
  const double cos_limit = std::cos(opt.miter_limit_deg * M_PI / 180.0);
  out.corners.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const bool has_prev = closed || i > 0, has_next = closed || i + 1 < n;
    const V2 v = orig[i];
    const V2 p = has_prev ? orig[(i + n - 1) % n] : v;
    const V2 nx = has_next ? orig[(i + 1) % n] : v;
    V2 u_in{0, 0}, u_out{0, 0};
    if (has_prev) u_in = unit(sub(v, p));
    if (has_next) u_out = unit(sub(nx, v));
    double side = 1.0;  // +1: outer side is the left
    if (has_prev && has_next) {
      auto o = CGAL::orientation(Kernel::Point_2(p.x, p.y), Kernel::Point_2(v.x, v.y),
                                 Kernel::Point_2(nx.x, nx.y));
      if (o == CGAL::LEFT_TURN) side = -1.0;
    }
    decal::LineCorner& c = out.corners[i];
    if (has_prev) {
      V2 n_in = left(u_in);
      c.bevel_in[0] = float(side * hw * n_in.x);
      c.bevel_in[1] = float(side * hw * n_in.y);
    }
    if (has_next) {
      V2 n_out = left(u_out);
      c.bevel_out[0] = float(side * hw * n_out.x);
      c.bevel_out[1] = float(side * hw * n_out.y);
    }
    if (corner == decal::CornerStyle::miter && has_prev && has_next) {
      const double dot = u_in.x * u_out.x + u_in.y * u_out.y;  // = -cos(theta)
      if (-dot <= cos_limit) {                                 // theta >= limit: keep the miter
        V2 n_in = left(u_in), n_out = left(u_out);
        const double k = hw / (1.0 + dot);
        c.miter[0] = float((n_in.x + n_out.x) * k);
        c.miter[1] = float((n_in.y + n_out.y) * k);
      }
    }
  }
  const LayerSpec& layer = scene.layers[line.layer];
  decal::LineProps& pr = out.props;
  pr.half_width = float(hw);
  pr.rgba = resolve_color(layer.style.color, line.color_value);
  pr.style = uint32_t(corner) | (uint32_t(outline) << decal::kStyleOutlineShift) |
             (closed ? decal::kStyleClosedBit : 0u);
  pr.value = float(line.color_value);
  pr.layer = line.layer;
  pr.feature = stored_feature_id(line.fid);
  pr.clip_node = 0;  // set by build_model() for clipped outlines
  out.kept = true;
  return out;
}

// Per layer the corner style and the outline mode drawn, with the fallback
// of thesis §3.6 (inset and offset need the miter corner style: a layer
// with lines that asks for them otherwise is noted and drawn in normal
// mode).
void layer_line_styles(const SceneFeatures& scene, DecalModel& model,
                       std::vector<decal::CornerStyle>& corner,
                       std::vector<decal::OutlineMode>& outline) {
  corner.resize(scene.layers.size());
  outline.resize(scene.layers.size());
  for (size_t l = 0; l < scene.layers.size(); ++l) {
    const LayerStyle& st = scene.layers[l].style;
    corner[l] = st.corner;
    outline[l] = st.outline;
    if (st.outline != decal::OutlineMode::normal && st.corner != decal::CornerStyle::miter) {
      outline[l] = decal::OutlineMode::normal;
      bool used = std::any_of(scene.lines.begin(), scene.lines.end(),
                              [&](const SceneLine& x) { return x.layer == l; });
      if (used)
        model.manifest.notes.push_back(
            stage_message(kBuildStage, "layer '" + scene.layers[l].name +
                                           "': outline mode inset/offset needs corner style miter; "
                                           "drawn in normal mode"));
    }
  }
}

// Where the kept lines lie in the model's arrays: per kept line (and one
// past the last) its first vertex and first segment.
struct KeptLines {
  std::vector<uint32_t> first_vertex, seg_first;
  uint32_t segments = 0;
};

// The converted lines appended to the model in input order (deterministic):
// vertices, corners, properties, dash starts and a draw key per kept line;
// a dropped line goes to the manifest with its reason.
KeptLines append_lines(const SceneFeatures& scene, const std::vector<LineOut>& outs,
                       DecalModel& model, std::vector<DrawKey>& keys) {
  KeptLines kept;
  uint32_t nseg = 0;
  for (size_t i = 0; i < outs.size(); ++i) {
    const LineOut& o = outs[i];
    model.max_representation_error = std::max(model.max_representation_error, o.max_err);
    const SceneLine& l = scene.lines[i];
    if (!o.kept) {
      ManifestEntry e;
      e.layer = scene.layers[l.layer].name;
      e.fid = l.fid;
      e.part = l.part;
      e.action = ManifestAction::dropped;
      e.reason = stage_message(kBuildStage, o.reason);
      model.manifest.entries.push_back(e);
      continue;
    }
    const uint32_t line_index = uint32_t(model.line_props.size());
    kept.first_vertex.push_back(uint32_t(model.line_vertices.size()));
    kept.seg_first.push_back(nseg);
    for (const QPoint& q : o.q) {
      model.line_vertices.push_back({int32_t(q.x), int32_t(q.y)});
      model.line_vertex_line.push_back(line_index);
    }
    model.line_corners.insert(model.line_corners.end(), o.corners.begin(), o.corners.end());
    model.line_props.push_back(o.props);
    model.line_dash_start.push_back(l.dash_start);
    const bool closed = o.props.style & decal::kStyleClosedBit;
    nseg += uint32_t(closed ? o.q.size() : o.q.size() - 1);
    keys.push_back({std::isnan(l.order_value) ? l.length : l.order_value, l.layer, DrawKind::line,
                    l.fid, l.part, uint32_t(i)});
  }
  kept.first_vertex.push_back(uint32_t(model.line_vertices.size()));
  kept.seg_first.push_back(nseg);
  kept.segments = nseg;
  return kept;
}

// The miter quad of segment `sh` (a - ma, b - mb, b + mb, a + ma, in
// quanta; a bevel vector stands in at a null miter) as the four triangles
// of three of its corners, and `sh`'s box bounds (minx .. maxy) grown to
// hold them. Carathéodory: those triangles cover the quad's convex hull,
// hence the evaluator's two triangles whatever the quad's shape.
void miter_triangles(const decal::LineCorner& ca, const decal::LineCorner& cb, bool null_a,
                     bool null_b, double inv_q, SegmentShape& sh, double& minx, double& maxx,
                     double& miny, double& maxy) {
  // A null miter falls back to the bevel vector on that side.
  const float* ma = null_a ? ca.bevel_out : ca.miter;
  const float* mb = null_b ? cb.bevel_in : cb.miter;
  const double max_ = ma[0] * inv_q, may_ = ma[1] * inv_q;
  const double mbx = mb[0] * inv_q, mby = mb[1] * inv_q;
  const double A1x = sh.ax + max_, A1y = sh.ay + may_, A2x = sh.ax - max_, A2y = sh.ay - may_;
  const double B1x = sh.bx + mbx, B1y = sh.by + mby, B2x = sh.bx - mbx, B2y = sh.by - mby;
  const double xs[4] = {A1x, A2x, B1x, B2x}, ys[4] = {A1y, A2y, B1y, B2y};
  sh.ntri = 4;
  for (int k = 0; k < 4; ++k) {
    int t = 0;
    for (int j = 0; j < 4; ++j)
      if (j != k) {
        sh.tri[k][t++] = xs[j];
        sh.tri[k][t++] = ys[j];
      }
    minx = std::min(minx, xs[k]);
    maxx = std::max(maxx, xs[k]);
    miny = std::min(miny, ys[k]);
    maxy = std::max(maxy, ys[k]);
  }
}

// The widened shape (quanta) of the segment from vertex ia to vertex ib of
// kept line `li`: a capsule of the half width (a hair wider: float-stored
// vectors may be a hair longer) for round and bevel corners and at a null
// miter, the miter quad's triangles for miter corners, and the box of
// both, a quantum wider on each side.
//
// A line of a min_width_px layer whose widest drawn half width `reach`
// (quanta) passes its own is drawn scaled by up to K = reach / hw, corner
// vectors too: its shape is the capsule of K times the longest of hw and
// its corner vectors, which holds the scaled quad and triangles (convex).
void segment_shape(const DecalModel& model, uint32_t li, uint32_t ia, uint32_t ib, double inv_q,
                   double reach, SegmentShape& sh) {
  const decal::LineProps& pr = model.line_props[li];
  const auto style = decal::CornerStyle(pr.style & decal::kStyleCornerMask);
  const double hw = double(pr.half_width) * inv_q;
  sh.line = li;
  sh.start = ia;
  sh.end = ib;
  sh.ax = model.line_vertices[ia][0];
  sh.ay = model.line_vertices[ia][1];
  sh.bx = model.line_vertices[ib][0];
  sh.by = model.line_vertices[ib][1];
  sh.hw = hw * (1.0 + 1e-6);  // float-stored vectors may be a hair longer
  const decal::LineCorner& ca = model.line_corners[ia];
  const decal::LineCorner& cb = model.line_corners[ib];
  const bool null_a = ca.miter[0] == 0.f && ca.miter[1] == 0.f;
  const bool null_b = cb.miter[0] == 0.f && cb.miter[1] == 0.f;
  double minx = std::min(sh.ax, sh.bx), maxx = std::max(sh.ax, sh.bx);
  double miny = std::min(sh.ay, sh.by), maxy = std::max(sh.ay, sh.by);
  sh.capsule = style != decal::CornerStyle::miter || null_a || null_b;
  if (sh.capsule) {
    minx -= sh.hw;
    maxx += sh.hw;
    miny -= sh.hw;
    maxy += sh.hw;
  }
  const auto box_of = [](double x0, double y0, double x1, double y1) {
    return QBox{int64_t(std::floor(x0)) - 1, int64_t(std::floor(y0)) - 1,
                int64_t(std::ceil(x1)) + 1, int64_t(std::ceil(y1)) + 1};
  };
  if (style == decal::CornerStyle::miter)
    miter_triangles(ca, cb, null_a, null_b, inv_q, sh, minx, maxx, miny, maxy);
  sh.leaf_box = box_of(minx, miny, maxx, maxy);
  if (reach > hw) {
    double longest = hw;
    for (const decal::LineCorner* c : {&ca, &cb})
      for (const float* v : {c->miter, c->bevel_in, c->bevel_out})
        longest = std::max(longest, std::hypot(double(v[0]), double(v[1])) * inv_q);
    sh.capsule = true;
    sh.hw = reach / hw * longest * (1.0 + 1e-6);
    minx = std::min(sh.ax, sh.bx) - sh.hw;
    maxx = std::max(sh.ax, sh.bx) + sh.hw;
    miny = std::min(sh.ay, sh.by) - sh.hw;
    maxy = std::max(sh.ay, sh.by) + sh.hw;
    sh.ntri = 0;  // the capsule holds the miter quad
  }
  sh.box = box_of(minx, miny, maxx, maxy);
}

}  // namespace

void build_lines(const SceneFeatures& scene, const ModelOptions& options, DecalModel& model,
                 std::vector<SegmentShape>& shapes, std::vector<DrawKey>& keys) {
  const size_t nl = scene.lines.size();
  std::vector<decal::CornerStyle> corner;
  std::vector<decal::OutlineMode> outline;
  layer_line_styles(scene, model, corner, outline);
  for (const SceneLine& l : scene.lines)
    if (l.layer >= scene.layers.size())
      fail<input_error>(kBuildStage, "line fid " + std::to_string(l.fid) +
                                         " refers to layer index " + std::to_string(l.layer) +
                                         ", but the scene has " +
                                         std::to_string(scene.layers.size()) + " layers");

  // Counted once per line converted, and again per kept line's shapes.
  ProgressStage stage(options.progress, "build.lines", 2 * nl, "lines");
  std::vector<LineOut> outs(nl);
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, nl, 64), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const SceneLine& l = scene.lines[i];
          outs[i] = convert_line(scene, l, options, corner[l.layer], outline[l.layer]);
        }
        stage.add(r.size());
      });
  const KeptLines kept = append_lines(scene, outs, model, keys);

  // Widened segment shapes (quanta), parallel per line. A min_width_px
  // layer's lines reach their drawn half width at the package's pixel
  // limit: N/2 pixels (the stored half width of an inset or offset line is
  // its whole visible width: N pixels).
  shapes.resize(kept.segments);
  stage.set_total(nl + model.line_props.size());
  const double inv_q = 1.0 / decal::kQuantumMetres;
  std::vector<double> reach(scene.layers.size(), 0.0);
  if (std::any_of(scene.layers.begin(), scene.layers.end(),
                  [](const LayerSpec& l) { return l.min_width_px > 0 && !l.dynamic; })) {
    const Extent& e = scene.extent;
    const double longer = std::max({e.xmax - e.xmin, e.ymax - e.ymin, 0.0});
    model.min_width_pixel_m = min_width_pixel_limit(
        options.min_width_resolution, options.min_width_side > 0 ? options.min_width_side : longer,
        options.min_width_whole < 0 ? longer : options.min_width_whole);
    for (size_t k = 0; k < scene.layers.size(); ++k)
      reach[k] = scene.layers[k].min_width_px * model.min_width_pixel_m *
                 (outline[k] == decal::OutlineMode::normal ? 0.5 : 1.0) * inv_q;
  }
  tbb::parallel_for(tbb::blocked_range<size_t>(0, model.line_props.size(), 64),
                    [&](const tbb::blocked_range<size_t>& r) {
                      for (size_t li = r.begin(); li != r.end(); ++li) {
                        const uint32_t v0 = kept.first_vertex[li],
                                       nv = kept.first_vertex[li + 1] - v0;
                        const uint32_t s0 = kept.seg_first[li], ns = kept.seg_first[li + 1] - s0;
                        for (uint32_t s = 0; s < ns; ++s)
                          segment_shape(model, uint32_t(li), v0 + s, v0 + (s + 1) % nv, inv_q,
                                        reach[model.line_props[li].layer], shapes[s0 + s]);
                      }
                      stage.add(r.size());
                    });
  stage.finish();
}

}  // namespace prep::detail
