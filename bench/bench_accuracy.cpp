// bench_accuracy — the accuracy axis of bench/run. Not a Google
// Benchmark: a helper that bench/run calls once per configuration, printing
// one JSON object per line on stdout.
//
//   bench_accuracy INPUT [--kind polygon|line|outline] [--width W] [--corner C]
//                  [--crs CRS] [--extent X0,Y0,X1,Y1 [--extent-crs C]] [--resolution R] [--samples
//                  N] [--seed S]
//                  [--band B] [--package P] [--raster TIF ...]
//                  [--export-oracle OUT.fgb] [--encoding] [--hausdorff]
//
// INPUT is a scene file (.toml) or a single GDAL source, as for
// `decalprep build`. The oracle is the cleaned geometry at resolution 0
// (GEOS, double precision): polygons as they are, static lines buffered by
// half their width with the layer's join style. Sample points are half
// uniform over the data bounding box, half near oracle boundaries (offset
// 2 mm .. B metres along the edge normal); a misclassified point closer than
// 2 mm to the boundary is excluded, as the format's quantum is 1 mm.
//
// --package: classify with prep::evaluate (polygon or line coverage),
//   report misclassified points, the largest distance of a misclassified
//   point from the oracle boundary (position error), and the query-cost
//   counters (mean, p99) over covered points.
// --raster: classify by the raster pixel value at each point (non-zero =
//   covered); the raster must be in scene coordinates (see --export-oracle).
// --export-oracle: write the oracle shapes (scene coordinates, metres
//   relative to the frame origin) to a vector file for gdal_rasterize.
// --encoding: quantise the oracle polygon coordinates as int32 1 mm fixed
//   point, float32 relative to the origin, float32 absolute (frame CRS), and
//   float32 absolute 900 km from the CRS origin; report each one's largest
//   vertex error and misclassified points against the exact polygons.
// --hausdorff: largest discrete Hausdorff distance between the parts at
//   --resolution and the same parts at resolution 0.
#include <gdal.h>
#include <geos_c.h>
#include <ogr_api.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "bench_scene.hpp"
#include "decal/reader.hpp"
#include "prep/evaluate.hpp"
#include "prep/pipeline.hpp"
#include "prep/read.hpp"

namespace {

void geos_msg(const char*, void*) {}

struct Args {
  std::string input, kind = "polygon", corner = "round", crs, extent, extent_crs, package,
                     export_oracle;
  std::vector<std::string> rasters;
  double width = 2.0, resolution = 0.0, band = 0.5;
  size_t samples = 20000;
  uint64_t seed = 7;
  bool encoding = false, hausdorff = false;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    std::string s = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::runtime_error("missing value after " + s);
      return argv[++i];
    };
    if (s == "--kind")
      a.kind = next();
    else if (s == "--width")
      a.width = std::stod(next());
    else if (s == "--corner")
      a.corner = next();
    else if (s == "--crs")
      a.crs = next();
    else if (s == "--extent")
      a.extent = next();
    else if (s == "--extent-crs")
      a.extent_crs = next();
    else if (s == "--resolution")
      a.resolution = std::stod(next());
    else if (s == "--samples")
      a.samples = std::stoul(next());
    else if (s == "--seed")
      a.seed = std::stoull(next());
    else if (s == "--band")
      a.band = std::stod(next());
    else if (s == "--package")
      a.package = next();
    else if (s == "--raster")
      a.rasters.push_back(next());
    else if (s == "--export-oracle")
      a.export_oracle = next();
    else if (s == "--encoding")
      a.encoding = true;
    else if (s == "--hausdorff")
      a.hausdorff = true;
    else if (!s.empty() && s[0] == '-')
      throw std::runtime_error("unknown option " + s);
    else
      a.input = s;
  }
  if (a.input.empty()) throw std::runtime_error("usage: bench_accuracy INPUT [options]");
  return a;
}

prep::BuildSpec spec_of(const Args& a) {
  if (a.input.size() > 5 && a.input.substr(a.input.size() - 5) == ".toml") {
    prep::BuildSpec s = prep::load_scene_file(a.input);
    if (!a.crs.empty()) s.crs = a.crs;
    return s;
  }
  prep::BuildSpec s;
  prep::LayerSpec l;
  l.name = "input";
  l.source = a.input;
  l.kind = prep::parse_kind(a.kind);
  l.style.width = a.width;
  l.style.corner = prep::parse_corner(a.corner);
  s.layers.push_back(l);
  s.crs = a.crs;
  if (!a.extent.empty()) {
    prep::Extent e;
    if (std::sscanf(a.extent.c_str(), "%lf,%lf,%lf,%lf", &e.xmin, &e.ymin, &e.xmax, &e.ymax) != 4)
      throw std::runtime_error("--extent: expected xmin,ymin,xmax,ymax, got " + a.extent);
    s.extent = e;
    s.extent_crs = a.extent_crs;
  }
  return s;
}

// A set of covering shapes with an STRtree: the oracle, or a quantised copy.
struct Shapes {
  GEOSContextHandle_t h;
  std::vector<GEOSGeometry*> geoms;
  std::vector<const GEOSPreparedGeometry*> prepared;
  std::vector<GEOSGeometry*> boundaries;
  GEOSSTRtree* tree = nullptr;

  explicit Shapes(GEOSContextHandle_t ctx) : h(ctx) {}
  ~Shapes() {
    if (tree) GEOSSTRtree_destroy_r(h, tree);
    for (auto* p : prepared) GEOSPreparedGeom_destroy_r(h, p);
    for (auto* g : boundaries) GEOSGeom_destroy_r(h, g);
    for (auto* g : geoms) GEOSGeom_destroy_r(h, g);
  }
  void add(GEOSGeometry* g, const std::string& tag = "") {
    if (!g || GEOSisEmpty_r(h, g) == 1) {
      if (g) GEOSGeom_destroy_r(h, g);
      return;
    }
    geoms.push_back(g);
    tags.push_back(tag);
  }
  void index() {
    tree = GEOSSTRtree_create_r(h, 10);
    for (size_t i = 0; i < geoms.size(); ++i) {
      prepared.push_back(GEOSPrepare_r(h, geoms[i]));
      boundaries.push_back(GEOSBoundary_r(h, geoms[i]));
      GEOSSTRtree_insert_r(h, tree, geoms[i], reinterpret_cast<void*>(static_cast<intptr_t>(i)));
    }
  }
  std::vector<size_t> candidates(double x0, double y0, double x1, double y1) const {
    std::vector<size_t> out;
    GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h, 5, 2);
    const double xs[5] = {x0, x1, x1, x0, x0}, ys[5] = {y0, y0, y1, y1, y0};
    for (unsigned i = 0; i < 5; ++i) GEOSCoordSeq_setXY_r(h, cs, i, xs[i], ys[i]);
    GEOSGeometry* env = GEOSGeom_createPolygon_r(h, GEOSGeom_createLinearRing_r(h, cs), nullptr, 0);
    GEOSSTRtree_query_r(
        h, tree, env,
        [](void* item, void* ud) {
          static_cast<std::vector<size_t>*>(ud)->push_back(
              static_cast<size_t>(reinterpret_cast<intptr_t>(item)));
        },
        &out);
    GEOSGeom_destroy_r(h, env);
    return out;
  }
  bool covers(double x, double y) const {
    GEOSGeometry* p = GEOSGeom_createPointFromXY_r(h, x, y);
    bool in = false;
    for (size_t i : candidates(x, y, x, y))
      if (GEOSPreparedIntersects_r(h, prepared[i], p) == 1) {
        in = true;
        break;
      }
    GEOSGeom_destroy_r(h, p);
    return in;
  }
  // Distance from (x, y) to the nearest shape boundary (search grows until
  // a candidate answers; infinity when there is none).
  std::vector<std::string> tags;  // layer name per shape (for breakdowns)
  double boundary_distance(double x, double y, double span, size_t* nearest = nullptr) const {
    GEOSGeometry* p = GEOSGeom_createPointFromXY_r(h, x, y);
    double best = INFINITY;
    for (double r = 1.0; r < 4 * span + 4; r *= 4) {
      for (size_t i : candidates(x - r, y - r, x + r, y + r)) {
        double d = 0;
        if (GEOSDistance_r(h, boundaries[i], p, &d) == 1 && d < best) {
          best = d;
          if (nearest) *nearest = i;
        }
      }
      if (best <= r) break;
    }
    GEOSGeom_destroy_r(h, p);
    return best;
  }
};

GEOSGeometry* ring_geom(GEOSContextHandle_t h, const prep::Ring& r, bool linear_ring, bool closed,
                        double (*q)(double, bool) = nullptr) {
  const size_t n = r.size() + (closed ? 1 : 0);
  GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h, static_cast<unsigned>(n), 2);
  for (size_t i = 0; i < n; ++i) {
    const auto& p = r[i % r.size()];
    GEOSCoordSeq_setXY_r(h, cs, static_cast<unsigned>(i), q ? q(p.x, true) : p.x,
                         q ? q(p.y, false) : p.y);
  }
  return linear_ring ? GEOSGeom_createLinearRing_r(h, cs) : GEOSGeom_createLineString_r(h, cs);
}

GEOSGeometry* polygon_geom(GEOSContextHandle_t h, const prep::ScenePolygon& p,
                           double (*q)(double, bool) = nullptr) {
  std::vector<GEOSGeometry*> holes;
  for (const auto& r : p.holes) holes.push_back(ring_geom(h, r, true, true, q));
  return GEOSGeom_createPolygon_r(h, ring_geom(h, p.shell, true, true, q), holes.data(),
                                  static_cast<unsigned>(holes.size()));
}

// Static line band, as the package draws it (§3.3.1): round / bevel joins
// with round caps; miter approximated by GEOS mitre joins with the build's
// 40° limit (our fallback below the limit is round, GEOS bevels: the
// difference lies at the sharpest corners only).
GEOSGeometry* line_band(GEOSContextHandle_t h, const prep::SceneLine& l,
                        const prep::LayerSpec& layer) {
  // Inset / offset outlines (§3.3.2) draw the full width on one side of the
  // ring: a band of half-width w clipped to inside / outside the ring.
  const bool sided = layer.style.outline != decal::OutlineMode::normal && l.closed;
  const double hw = l.width * (sided ? 1.0 : 0.5);
  GEOSGeometry* g = ring_geom(h, l.points, false, l.closed);
  GEOSGeometry* band = nullptr;
  switch (layer.style.corner) {
    case decal::CornerStyle::round:
      band = GEOSBufferWithStyle_r(h, g, hw, 32, GEOSBUF_CAP_ROUND, GEOSBUF_JOIN_ROUND, 5);
      break;
    case decal::CornerStyle::bevel:
      band = GEOSBufferWithStyle_r(h, g, hw, 32, GEOSBUF_CAP_ROUND, GEOSBUF_JOIN_BEVEL, 5);
      break;
    case decal::CornerStyle::miter:
      band = GEOSBufferWithStyle_r(h, g, hw, 32, GEOSBUF_CAP_ROUND, GEOSBUF_JOIN_MITRE,
                                   1.0 / std::sin(40.0 * M_PI / 360.0));
      break;
  }
  GEOSGeom_destroy_r(h, g);
  if (sided && band) {
    GEOSGeometry* area =
        GEOSGeom_createPolygon_r(h, ring_geom(h, l.points, true, true), nullptr, 0);
    GEOSGeometry* fixed = GEOSMakeValid_r(h, area);
    GEOSGeometry* out = layer.style.outline == decal::OutlineMode::inset
                            ? GEOSIntersection_r(h, band, fixed)
                            : GEOSDifference_r(h, band, fixed);
    GEOSGeom_destroy_r(h, area);
    GEOSGeom_destroy_r(h, fixed);
    GEOSGeom_destroy_r(h, band);
    band = out;
  }
  return band;
}

struct Sample {
  double x, y;
  bool truth;
};

// Edges of every oracle boundary, for near-edge sampling.
struct Edge {
  double x0, y0, x1, y1;
};

void collect_edges(GEOSContextHandle_t h, const GEOSGeometry* g, std::vector<Edge>& out) {
  const int n = GEOSGetNumGeometries_r(h, g);
  for (int i = 0; i < n; ++i) {
    const GEOSGeometry* part = GEOSGetGeometryN_r(h, g, i);
    const GEOSCoordSequence* cs = GEOSGeom_getCoordSeq_r(h, part);
    if (!cs) continue;
    unsigned m = 0;
    GEOSCoordSeq_getSize_r(h, cs, &m);
    double px = 0, py = 0;
    for (unsigned k = 0; k < m; ++k) {
      double x, y;
      GEOSCoordSeq_getXY_r(h, cs, k, &x, &y);
      if (k > 0 && (x != px || y != py)) out.push_back({px, py, x, y});
      px = x;
      py = y;
    }
  }
}

void emit(const char* fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  std::vprintf(fmt, ap);
  va_end(ap);
  std::printf("\n");
  std::fflush(stdout);
}

double percentile(std::vector<uint64_t> v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  size_t k = static_cast<size_t>(std::ceil(p * static_cast<double>(v.size())));
  return static_cast<double>(v[std::min(v.size() - 1, k == 0 ? 0 : k - 1)]);
}
double mean(const std::vector<uint64_t>& v) {
  double s = 0;
  for (auto x : v) s += static_cast<double>(x);
  return v.empty() ? 0 : s / static_cast<double>(v.size());
}

// Quantisers for --encoding (coordinates relative to the frame origin in,
// the value they decode to out).
double g_origin_x = 0, g_origin_y = 0;
double q_fixed(double v, bool) {
  return std::round(v / decal::kQuantumMetres) * decal::kQuantumMetres;
}
double q_f32_rel(double v, bool) {
  return static_cast<double>(static_cast<float>(v));
}
double q_f32_abs(double v, bool is_x) {
  const double o = is_x ? g_origin_x : g_origin_y;
  return static_cast<double>(static_cast<float>(v + o)) - o;
}
double q_f32_900(double v, bool) {
  return static_cast<double>(static_cast<float>(v + 900000.0)) - 900000.0;
}

// Classification error of `classify` against the oracle truth.
template <class F>
void score(const char* what, const char* name, const std::vector<Sample>& samples,
           const Shapes& oracle, double span, F classify, const char* extra_fmt = "",
           double e1 = 0) {
  size_t wrong = 0, excluded = 0, fp = 0, fn = 0;
  double max_err = 0;
  std::map<std::string, std::pair<size_t, double>>
      by_layer;  // nearest boundary's layer: count, max error
  for (const auto& s : samples) {
    if (classify(s) == s.truth) continue;
    size_t near = SIZE_MAX;
    const double d = oracle.boundary_distance(s.x, s.y, span, &near);
    if (d >= 0.002 && near < oracle.tags.size()) {
      auto& e = by_layer[oracle.tags[near]];
      e.first += 1;
      e.second = std::max(e.second, d);
    }
    if (d < 0.002) {
      ++excluded;
      continue;
    }
    ++wrong;
    (s.truth ? fn : fp) += 1;
    max_err = std::max(max_err, d);
  }
  char extra[256] = "";
  if (*extra_fmt) std::snprintf(extra, sizeof extra, extra_fmt, e1);
  std::string layers = "{";
  for (const auto& [k, v] : by_layer) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "%s\"%s\":[%zu,%.6g]", layers.size() > 1 ? "," : "", k.c_str(),
                  v.first, v.second);
    layers += buf;
  }
  layers += "}";
  emit(
      "{\"what\":\"%s\",\"name\":\"%s\",\"samples\":%zu,\"misclassified\":%zu,\"false_pos\":%zu,"
      "\"false_neg\":%zu,\"excluded_2mm\":%zu,\"max_position_error_m\":%.6g,\"by_layer\":%s%s}",
      what, name, samples.size(), wrong, fp, fn, excluded, max_err, layers.c_str(), extra);
}

}  // namespace

int main(int argc, char** argv) try {
  Args a = parse(argc, argv);
  GDALAllRegister();
  GEOSContextHandle_t h = GEOS_init_r();
  GEOSContext_setErrorMessageHandler_r(h, geos_msg, nullptr);

  prep::BuildSpec spec = spec_of(a);
  const double package_resolution = a.resolution >= 0 && a.input.find(".toml") == std::string::npos
                                        ? a.resolution
                                        : spec.resolution;
  spec.resolution = 0.0;  // the oracle: original geometry, cleaned
  prep::BuildRequest req;
  req.dry_run = true;
  const prep::SceneFeatures scene = prep::run_build(spec, req).scene;
  g_origin_x = scene.frame.origin_x;
  g_origin_y = scene.frame.origin_y;

  Shapes oracle(h);
  for (const auto& p : scene.polygons) oracle.add(polygon_geom(h, p), scene.layers[p.layer].name);
  for (const auto& l : scene.lines)
    oracle.add(line_band(h, l, scene.layers[l.layer]), scene.layers[l.layer].name);
  oracle.index();
  if (oracle.geoms.empty()) throw std::runtime_error("no static polygons or lines in " + a.input);

  double bx0 = INFINITY, by0 = INFINITY, bx1 = -INFINITY, by1 = -INFINITY;
  std::vector<Edge> edges;
  for (size_t i = 0; i < oracle.geoms.size(); ++i) {
    double x0, y0, x1, y1;
    GEOSGeom_getXMin_r(h, oracle.geoms[i], &x0);
    GEOSGeom_getYMin_r(h, oracle.geoms[i], &y0);
    GEOSGeom_getXMax_r(h, oracle.geoms[i], &x1);
    GEOSGeom_getYMax_r(h, oracle.geoms[i], &y1);
    bx0 = std::min(bx0, x0), by0 = std::min(by0, y0), bx1 = std::max(bx1, x1),
    by1 = std::max(by1, y1);
    collect_edges(h, oracle.boundaries[i], edges);
  }
  const double span = std::max(bx1 - bx0, by1 - by0);
  const uint64_t vertices = bench::scene_vertices(scene);
  emit(
      "{\"what\":\"oracle\",\"polygons\":%zu,\"lines\":%zu,\"vertices\":%llu,\"xmin\":%.3f,"
      "\"ymin\":%.3f,"
      "\"xmax\":%.3f,\"ymax\":%.3f,\"origin_x\":%.3f,\"origin_y\":%.3f}",
      scene.polygons.size(), scene.lines.size(), static_cast<unsigned long long>(vertices), bx0,
      by0, bx1, by1, g_origin_x, g_origin_y);

  // Samples: half uniform, half near a boundary edge picked by length.
  std::mt19937_64 rng(a.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<double> cum;
  double total = 0;
  for (const auto& e : edges) cum.push_back(total += std::hypot(e.x1 - e.x0, e.y1 - e.y0));
  std::vector<Sample> samples;
  samples.reserve(a.samples);
  for (size_t i = 0; i < a.samples; ++i) {
    double x, y;
    if (i % 2 == 0 || edges.empty()) {
      x = bx0 + u(rng) * (bx1 - bx0);
      y = by0 + u(rng) * (by1 - by0);
    } else {
      const size_t k = static_cast<size_t>(
          std::lower_bound(cum.begin(), cum.end(), u(rng) * total) - cum.begin());
      const Edge& e = edges[std::min(k, edges.size() - 1)];
      const double t = u(rng), len = std::hypot(e.x1 - e.x0, e.y1 - e.y0);
      const double off = (0.002 + u(rng) * (a.band - 0.002)) * (u(rng) < 0.5 ? -1 : 1);
      x = e.x0 + t * (e.x1 - e.x0) - off * (e.y1 - e.y0) / len;
      y = e.y0 + t * (e.y1 - e.y0) + off * (e.x1 - e.x0) / len;
    }
    samples.push_back({x, y, oracle.covers(x, y)});
  }

  if (!a.package.empty()) {
    decal::Package pkg;
    if (auto st = decal::Package::open(a.package, pkg); !st) throw std::runtime_error(st.message);
    const prep::StaticView view = prep::view_of(pkg);
    std::vector<uint64_t> bvh, qt, edge, seg, sum;
    std::vector<char> cls(samples.size());
    for (size_t i = 0; i < samples.size(); ++i) {
      prep::EvalCounters c;
      const prep::EvalSample r = prep::evaluate(view, samples[i].x, samples[i].y, &c);
      cls[i] = r.polygon_covered || r.line_covered;
      if (cls[i]) {
        bvh.push_back(c.bvh_nodes), qt.push_back(c.qt_nodes), edge.push_back(c.edge_tests);
        seg.push_back(c.segment_tests);
        sum.push_back(c.bvh_nodes + c.qt_nodes + c.edge_tests + c.segment_tests);
      }
    }
    score("package", a.package.c_str(), samples, oracle, span,
          [&](const Sample& s) { return cls[static_cast<size_t>(&s - samples.data())] != 0; });
    emit(
        "{\"what\":\"cost\",\"covered\":%zu,\"bvh_mean\":%.3f,\"bvh_p99\":%.0f,\"qt_mean\":%.3f,"
        "\"qt_p99\":%.0f,"
        "\"edge_mean\":%.3f,\"edge_p99\":%.0f,\"seg_mean\":%.3f,\"seg_p99\":%.0f,\"total_mean\":%."
        "3f,"
        "\"total_p99\":%.0f}",
        sum.size(), mean(bvh), percentile(bvh, 0.99), mean(qt), percentile(qt, 0.99), mean(edge),
        percentile(edge, 0.99), mean(seg), percentile(seg, 0.99), mean(sum), percentile(sum, 0.99));
  }

  for (const auto& path : a.rasters) {
    GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
    if (!ds) throw std::runtime_error("cannot open raster " + path);
    double gt[6];
    GDALGetGeoTransform(ds, gt);
    GDALRasterBandH band = GDALGetRasterBand(ds, 1);
    const int w = GDALGetRasterXSize(ds), hgt = GDALGetRasterYSize(ds);
    score("raster", path.c_str(), samples, oracle, span, [&](const Sample& s) {
      const double px = std::floor((s.x - gt[0]) / gt[1]), py = std::floor((s.y - gt[3]) / gt[5]);
      if (px < 0 || py < 0 || px >= w || py >= hgt) return false;
      uint8_t v = 0;
      if (GDALRasterIO(band, GF_Read, static_cast<int>(px), static_cast<int>(py), 1, 1, &v, 1, 1,
                       GDT_Byte, 0, 0) != CE_None)
        throw std::runtime_error("raster read failed: " + path);
      return v != 0;
    });
    GDALClose(ds);
  }

  if (a.encoding) {
    struct Q {
      const char* name;
      double (*q)(double, bool);
    };
    // Polygons only on both sides: the exact polygons are the truth here
    // (line bands are not quantised by this experiment).
    Shapes exact(h);
    for (const auto& p : scene.polygons) exact.add(polygon_geom(h, p));
    exact.index();
    std::vector<Sample> psamples = samples;
    for (auto& s : psamples) s.truth = exact.covers(s.x, s.y);
    for (const Q& q :
         {Q{"int32_1mm_fixed", q_fixed}, Q{"float32_origin_relative", q_f32_rel},
          Q{"float32_absolute_frame", q_f32_abs}, Q{"float32_absolute_900km", q_f32_900}}) {
      Shapes qs(h);
      double max_vertex = 0;
      for (const auto& p : scene.polygons) {
        qs.add(polygon_geom(h, p, q.q));
        auto upd = [&](const prep::Ring& r) {
          for (const auto& v : r)
            max_vertex =
                std::max(max_vertex, std::hypot(q.q(v.x, true) - v.x, q.q(v.y, false) - v.y));
        };
        upd(p.shell);
        for (const auto& r : p.holes) upd(r);
      }
      qs.index();
      score(
          "encoding", q.name, psamples, exact, span,
          [&](const Sample& s) { return qs.covers(s.x, s.y); }, ",\"max_vertex_error_m\":%.6g",
          max_vertex);
    }
  }

  if (a.hausdorff) {
    prep::BuildSpec simp = spec;
    simp.resolution = package_resolution;
    const prep::SceneFeatures s2 = prep::run_build(simp, req).scene;
    std::map<std::tuple<uint32_t, int64_t, int>, const prep::ScenePolygon*> orig;
    for (const auto& p : scene.polygons) orig[{p.layer, p.fid, p.part}] = &p;
    std::map<std::tuple<uint32_t, int64_t, int>, const prep::SceneLine*> orig_l;
    for (const auto& l : scene.lines) orig_l[{l.layer, l.fid, l.part}] = &l;
    double worst = 0;
    size_t matched = 0;
    auto haus = [&](const prep::Ring& x, bool cx, const prep::Ring& y, bool cy) {
      GEOSGeometry* gx = ring_geom(h, x, false, cx);
      GEOSGeometry* gy = ring_geom(h, y, false, cy);
      double d = 0;
      if (GEOSHausdorffDistanceDensify_r(h, gx, gy, 0.25, &d) == 1) worst = std::max(worst, d);
      GEOSGeom_destroy_r(h, gx);
      GEOSGeom_destroy_r(h, gy);
    };
    for (const auto& p : s2.polygons) {
      auto it = orig.find({p.layer, p.fid, p.part});
      if (it == orig.end()) continue;
      ++matched;
      haus(p.shell, true, it->second->shell, true);
    }
    for (const auto& l : s2.lines) {
      auto it = orig_l.find({l.layer, l.fid, l.part});
      if (it == orig_l.end()) continue;
      ++matched;
      haus(l.points, l.closed, it->second->points, it->second->closed);
    }
    const uint64_t v2 = bench::scene_vertices(s2);
    emit(
        "{\"what\":\"hausdorff\",\"resolution\":%.6g,\"matched_parts\":%zu,\"vertices_before\":%"
        "llu,"
        "\"vertices_after\":%llu,\"max_hausdorff_m\":%.6g}",
        package_resolution, matched, static_cast<unsigned long long>(vertices),
        static_cast<unsigned long long>(v2), worst);
  }

  if (!a.export_oracle.empty()) {
    GDALDriverH drv = GDALGetDriverByName("FlatGeobuf");
    GDALDatasetH ds = GDALCreate(drv, a.export_oracle.c_str(), 0, 0, 0, GDT_Unknown, nullptr);
    if (!ds) throw std::runtime_error("cannot create " + a.export_oracle);
    OGRLayerH lyr = GDALDatasetCreateLayer(ds, "oracle", nullptr, wkbMultiPolygon, nullptr);
    GEOSWKBWriter* wr = GEOSWKBWriter_create_r(h);
    for (auto* g : oracle.geoms) {
      size_t n = 0;
      unsigned char* wkb = GEOSWKBWriter_write_r(h, wr, g, &n);
      OGRGeometryH og = nullptr;
      OGR_G_CreateFromWkb(wkb, nullptr, &og, static_cast<int>(n));
      GEOSFree_r(h, wkb);
      OGRFeatureH f = OGR_F_Create(OGR_L_GetLayerDefn(lyr));
      OGR_F_SetGeometryDirectly(f, OGR_G_ForceToMultiPolygon(og));
      if (OGR_L_CreateFeature(lyr, f) != OGRERR_NONE)
        throw std::runtime_error("write failed: " + a.export_oracle);
      OGR_F_Destroy(f);
    }
    GEOSWKBWriter_destroy_r(h, wr);
    GDALClose(ds);
  }
  GEOS_finish_r(h);
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "bench_accuracy: %s\n", e.what());
  return 1;
}
