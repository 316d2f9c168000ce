// bench_simplify — the --resolution table: on the
// Monaco extract, for each resolution, the vertex counts before and after
// simplification, the largest Hausdorff deviation of a simplified part from
// its unsimplified self (GEOS, densified discrete Hausdorff), and how many
// outputs GEOS finds invalid (must be 0).
//
//   bench_simplify [monaco.osm.pbf (default: samples/monaco/, run from the repo root)]
//                  [densify_fraction=0.1]
#include <geos_c.h>

#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "prep/pipeline.hpp"

namespace {

prep::SceneFeatures build(const std::string& pbf, double resolution) {
  prep::BuildSpec s;
  s.layers = {{.name = "landuse",
               .source = pbf,
               .layer = "multipolygons",
               .where = "landuse IS NOT NULL OR leisure IS NOT NULL OR \"natural\" IS NOT NULL",
               .kind = prep::DecalKind::polygon},
              {.name = "buildings",
               .source = pbf,
               .layer = "multipolygons",
               .where = "building IS NOT NULL",
               .kind = prep::DecalKind::polygon},
              {.name = "highways",
               .source = pbf,
               .layer = "lines",
               .where = "highway IS NOT NULL",
               .kind = prep::DecalKind::line}};
  s.resolution = resolution;
  prep::BuildRequest req;
  req.dry_run = true;
  return prep::run_build(s, req).scene;
}

// `as_ring`: a LinearRing (for polygons); else a LineString, closed when
// `closed`. (GEOS 3.11's Hausdorff distance is wrong on bare LinearRings.)
GEOSGeometry* ring(GEOSContextHandle_t h, const prep::Ring& r, bool closed, bool as_ring = true) {
  const size_t n = r.size() + (closed ? 1 : 0);
  GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h, static_cast<unsigned>(n), 2);
  for (size_t i = 0; i < n; ++i)
    GEOSCoordSeq_setXY_r(h, cs, static_cast<unsigned>(i), r[i % r.size()].x, r[i % r.size()].y);
  return closed && as_ring ? GEOSGeom_createLinearRing_r(h, cs)
                           : GEOSGeom_createLineString_r(h, cs);
}

GEOSGeometry* polygon(GEOSContextHandle_t h, const prep::ScenePolygon& p) {
  std::vector<GEOSGeometry*> holes;
  for (const auto& r : p.holes) holes.push_back(ring(h, r, true));
  return GEOSGeom_createPolygon_r(h, ring(h, p.shell, true), holes.data(),
                                  static_cast<unsigned>(holes.size()));
}

GEOSGeometry* line(GEOSContextHandle_t h, const prep::SceneLine& l) {
  return ring(h, l.points, l.closed, false);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string pbf = argc > 1 ? argv[1] : std::string("samples/monaco/monaco.osm.pbf");
  const double densify = argc > 2 ? std::stod(argv[2]) : 0.1;
  GEOSContextHandle_t h = GEOS_init_r();
  const prep::SceneFeatures base = build(pbf, 0.0);
  std::printf("Monaco (%s): %zu polygons, %zu lines; Hausdorff densify fraction %.2f\n",
              pbf.c_str(), base.polygons.size(), base.lines.size(), densify);
  std::printf(
      "| resolution (m) | vertices in | vertices out | kept %% | max Hausdorff (m) | mean "
      "Hausdorff (m) | invalid outputs |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (double res : {0.0, 0.1, 0.5, 2.0}) {
    const prep::SceneFeatures s = res == 0.0 ? base : build(pbf, res);
    uint64_t vin = 0, vout = 0;
    for (const auto& c : s.manifest.layers) {
      vin += c.vertices_in;
      vout += c.vertices_out;
    }
    double worst = 0, sum = 0;
    size_t n = 0, invalid = 0;
    if (s.polygons.size() != base.polygons.size() || s.lines.size() != base.lines.size()) {
      std::fprintf(stderr, "part counts differ at %.1f m\n", res);
      return 1;
    }
    auto measure = [&](GEOSGeometry* a, GEOSGeometry* b) {
      if (GEOSisValid_r(h, b) != 1) ++invalid;
      double d = 0;
      GEOSHausdorffDistanceDensify_r(h, a, b, densify, &d);
      worst = std::max(worst, d);
      sum += d;
      ++n;
      GEOSGeom_destroy_r(h, a);
      GEOSGeom_destroy_r(h, b);
    };
    for (size_t i = 0; i < s.polygons.size(); ++i)
      measure(polygon(h, base.polygons[i]), polygon(h, s.polygons[i]));
    for (size_t i = 0; i < s.lines.size(); ++i)
      measure(line(h, base.lines[i]), line(h, s.lines[i]));
    std::printf("| %.1f | %llu | %llu | %.1f | %.4f | %.4f | %zu |\n", res, (unsigned long long)vin,
                (unsigned long long)vout, 100.0 * double(vout) / double(vin), worst,
                n ? sum / double(n) : 0.0, invalid);
  }
  GEOS_finish_r(h);
  return 0;
}
