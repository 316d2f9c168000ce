// bench_validity — the validity decision of clean
// (libprep/clean/detail/certainly_valid.hpp polygon_validity) against GEOS
// isValid on one generated polygon shaped like the large land parts whose
// validity dominated clean: a shell of `shell` vertices (a circle of radius
// 10 km at a UTM-sized offset) and `holes` small triangular holes inside
// it, one at every other shell vertex, each touching the shell at that
// vertex (valid under OGC: GEOS isValid agrees, checked here). GEOS places
// each hole by a point-in-ring walk over the whole shell (time holes x
// shell vertices); the decision is near-linear. Three variants: the touch
// vertex first in each hole (GEOS's hole point 0 lies on the shell, so it
// also walks the shell to find the segment there), the touch vertex second,
// and the holes moved off the shell (no touches: the older proof's case).
// Prints the times (best of `runs`) and their ratio; writes a CSV.
//
//   bench_validity [holes=10000] [shell=20000] [runs=3]
//                  [csv=bench/report/validity.csv (run from the repo root)]
#include <geos_c.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "detail/certainly_valid.hpp"

namespace {

using prep::Point2;
using prep::Ring;
using Rings = std::vector<Ring>;

// The shell and holes; `touch_first`: the touch vertex is each hole's
// first; `apart`: the holes moved inwards off the shell.
Rings make_polygon(int holes, int shell, bool touch_first, bool apart) {
  const double cx = 500000, cy = 4800000, r = 10000;
  Rings rings(1);
  for (int i = 0; i < shell; ++i) {
    const double a = 2 * M_PI * i / shell;
    rings[0].push_back({cx + r * std::cos(a), cy + r * std::sin(a)});
  }
  const double s = 2 * M_PI * r / shell;  // shell vertex spacing
  const int step = std::max(1, shell / holes);
  for (int h = 0; h < holes; ++h) {
    const Point2 v = rings[0][size_t(h * step) % size_t(shell)];
    const double a = 2 * M_PI * (h * step % shell) / shell;
    const double ux = -std::cos(a), uy = -std::sin(a), tx = -uy, ty = ux;  // inward, tangent
    const double d = 0.8 * s * step / 2, w = 0.3 * s * step / 2;
    Point2 apex = v;
    if (apart) apex = {v.x + 0.2 * d * ux, v.y + 0.2 * d * uy};
    const Point2 p{v.x + d * ux + w * tx, v.y + d * uy + w * ty};
    const Point2 q{v.x + d * ux - w * tx, v.y + d * uy - w * ty};
    rings.push_back(touch_first ? Ring{apex, p, q} : Ring{p, q, apex});
  }
  return rings;
}

GEOSGeometry* to_geos(GEOSContextHandle_t h, const Rings& rings) {
  std::vector<GEOSGeometry*> rs;
  for (const Ring& r : rings) {
    GEOSCoordSequence* cs = GEOSCoordSeq_create_r(h, unsigned(r.size() + 1), 2);
    for (size_t i = 0; i <= r.size(); ++i)
      GEOSCoordSeq_setXY_r(h, cs, unsigned(i), r[i % r.size()].x, r[i % r.size()].y);
    rs.push_back(GEOSGeom_createLinearRing_r(h, cs));
  }
  return GEOSGeom_createPolygon_r(h, rs[0], rs.data() + 1, unsigned(rs.size() - 1));
}

template <class F>
double best_of(int runs, F&& f) {
  double best = INFINITY;
  for (int k = 0; k < runs; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    best = std::min(best,
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

const char* name(prep::detail::Validity v) {
  return v == prep::detail::Validity::valid
             ? "valid"
             : (v == prep::detail::Validity::invalid ? "invalid" : "unsure");
}

}  // namespace

int main(int argc, char** argv) {
  const int holes = argc > 1 ? std::atoi(argv[1]) : 10000;
  const int shell = argc > 2 ? std::atoi(argv[2]) : 20000;
  const int runs = argc > 3 ? std::atoi(argv[3]) : 3;
  const std::string csv = argc > 4 ? argv[4] : "bench/report/validity.csv";
  if (holes < 1 || shell < 3 || runs < 1) {
    std::fprintf(stderr, "usage: bench_validity [holes] [shell] [runs] [csv]\n");
    return 2;
  }
  GEOSContextHandle_t h = GEOS_init_r();
  FILE* out = std::fopen(csv.c_str(), "w");
  if (!out) {
    std::fprintf(stderr, "bench_validity: cannot write %s\n", csv.c_str());
    return 1;
  }
  std::fprintf(out,
               "variant,shell_vertices,holes,geos_build_s,geos_isvalid_s,decision_s,"
               "isvalid_over_decision,decision,geos_valid\n");
  struct Variant {
    const char* name;
    const char* key;  // the CSV's variant column
    bool touch_first, apart;
  };
  int status = 0;
  for (const Variant& v : {Variant{"touching, touch vertex first", "touch_first", true, false},
                           Variant{"touching, touch vertex last", "touch_last", false, false},
                           Variant{"holes apart", "apart", false, true}}) {
    const Rings rings = make_polygon(holes, shell, v.touch_first, v.apart);
    GEOSGeometry* g = nullptr;
    const double build_s = best_of(1, [&] { g = to_geos(h, rings); });
    char geos_valid = 2;
    const double geos_s = best_of(runs, [&] { geos_valid = GEOSisValid_r(h, g); });
    prep::detail::Validity decision{};
    const double proof_s = best_of(runs, [&] { decision = prep::detail::polygon_validity(rings); });
    GEOSGeom_destroy_r(h, g);
    std::printf(
        "%s: %d shell vertices, %d holes: GEOS isValid %.4f s (%s; building the GEOS polygon "
        "%.4f s), decision %.4f s (%s): x%.0f\n",
        v.name, shell, holes, geos_s, geos_valid == 1 ? "valid" : "invalid", build_s, proof_s,
        name(decision), geos_s / proof_s);
    std::fprintf(out, "%s,%d,%d,%.6f,%.6f,%.6f,%.1f,%s,%d\n", v.key, shell, holes, build_s, geos_s,
                 proof_s, geos_s / proof_s, name(decision), geos_valid == 1);
    if (geos_valid != 1 || decision != prep::detail::Validity::valid) status = 1;
  }
  std::fclose(out);
  GEOS_finish_r(h);
  std::printf("wrote %s\n", csv.c_str());
  return status;
}
