// ogr_lines.hpp — the plain LineStrings of an OGR layer, for the tests and
// benchmarks that read real OSM roads (tests/model, bench/bench_terrain.cpp).
// Header-only and GDAL's: include it only where GDAL is linked.
#pragma once

#include <ogrsf_frmts.h>

namespace prep::test {

// Calls `fn(feature, line)` for every feature of `layer` (its attribute
// filter applied) whose geometry is a LineString; other geometries are
// passed over.
template <class Fn>
void for_each_line_string(OGRLayer& layer, Fn&& fn) {
  for (auto& f : layer) {
    const OGRGeometry* g = f->GetGeometryRef();
    if (!g || wkbFlatten(g->getGeometryType()) != wkbLineString) continue;
    fn(*f, *g->toLineString());
  }
}

}  // namespace prep::test
