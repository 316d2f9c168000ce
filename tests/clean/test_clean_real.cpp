// Clean on real data. Monaco: every output valid, simplification within the
// resolution (Hausdorff distance against the unsimplified output, GEOS;
// the full 0/0.1/0.5/2 m table is bench/bench_simplify). The Aegean
// islands of the optional earth-seas set: the repair of a hole-heavy
// polygon against GEOS MakeValid of the whole.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <cmath>
#include <cstdio>
#include <functional>

#include "../read/fixtures.hpp"
#include "../read/scene_fixtures.hpp"
#include "geos_oracle.hpp"
#include "prep/clean.hpp"
#include "prep/pipeline.hpp"

namespace {

prep::SceneFeatures monaco(double resolution) {
  prep::BuildSpec s;
  for (auto [name, layer, where, kind] :
       {std::tuple{"buildings", "multipolygons", "building IS NOT NULL", prep::DecalKind::polygon},
        std::tuple{"roads", "lines", "highway IS NOT NULL", prep::DecalKind::line}}) {
    prep::LayerSpec& l = s.layers.emplace_back(
        prep::test::layer_of(name, prep::test::monaco_sample("monaco.osm.pbf"), kind));
    l.layer = layer;
    l.where = where;
  }
  s.resolution = resolution;
  return prep::test::dry_run(s);
}

TEST(CleanMonaco, SimplifiedOutputIsValidAndWithinHalfAMetre) {
  if (!prep::test::exists(prep::test::monaco_sample("monaco.osm.pbf")))
    GTEST_SKIP() << "missing " << prep::test::monaco_sample("monaco.osm.pbf");
  prep::SceneFeatures full = monaco(0.0), simple = monaco(0.5);
  ASSERT_EQ(full.polygons.size(), simple.polygons.size());
  ASSERT_EQ(full.lines.size(), simple.lines.size());
  prep::test::Geos geos;
  double worst = 0;
  for (size_t i = 0; i < simple.polygons.size(); ++i) {
    ASSERT_EQ(full.polygons[i].fid, simple.polygons[i].fid);
    ASSERT_TRUE(prep::test::is_valid(geos.h, simple.polygons[i]))
        << "fid " << simple.polygons[i].fid;
    if (i % 10 != 0) continue;  // Hausdorff on a sample keeps the test fast
    const prep::test::G a = prep::test::polygon(geos.h, full.polygons[i]);
    const prep::test::G b = prep::test::polygon(geos.h, simple.polygons[i]);
    double d = 0;
    GEOSHausdorffDistanceDensify_r(geos.h, a.g, b.g, 0.25, &d);
    worst = std::max(worst, d);
  }
  // Densified discrete Hausdorff approximates the true distance from below
  // within the densification step; Douglas-Peucker bounds it by the tolerance.
  EXPECT_LE(worst, 0.5 + 1e-6);
  EXPECT_GT(worst, 0.0);
  EXPECT_LT(simple.manifest.layers[0].vertices_out, full.manifest.layers[0].vertices_out);
}

}  // namespace

// ------------------------------------------- hole-heavy real polygon --
//
// The islands of the Aegean (every hole of the earth-seas world ocean whose
// envelope lies in 22-29E, 35-41N: real rings, many of them close to each
// other) as the holes of one rectangular shell, plus one bow-tie hole so
// that the polygon is invalid: clean() repairs it by parts
// (libprep/clean/detail/repair_by_parts.hpp), and the result must be GEOS
// MakeValid of the whole polygon. Needs the optional earth-seas set
// (scripts/fetch-data earth-seas); skips, naming the path, without it.
namespace {

std::vector<prep::Ring> aegean_islands(const std::string& path) {
  GDALAllRegister();
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (!ds) return {};
  // Degrees to metres near 38N (an affine map: the oracle sees the same rings).
  const double kx = 111320.0 * std::cos(38.0 * M_PI / 180.0), ky = 110540.0;
  const double x0 = 22, x1 = 29, y0 = 35, y1 = 41;
  std::vector<prep::Ring> rings{
      {{0, 0}, {(x1 - x0) * kx, 0}, {(x1 - x0) * kx, (y1 - y0) * ky}, {0, (y1 - y0) * ky}}};
  OGRLayer* layer = ds->GetLayer(0);
  for (auto& feature : *layer) {
    std::vector<const OGRPolygon*> polys;
    std::function<void(const OGRGeometry*)> walk = [&](const OGRGeometry* g) {
      if (const auto* p = dynamic_cast<const OGRPolygon*>(g)) return polys.push_back(p);
      if (const auto* c = dynamic_cast<const OGRGeometryCollection*>(g))
        for (const OGRGeometry* part : c) walk(part);
    };
    walk(feature->GetGeometryRef());
    for (const OGRPolygon* p : polys)
      for (const OGRLinearRing* r : *p) {
        if (r == p->getExteriorRing()) continue;
        OGREnvelope e;
        r->getEnvelope(&e);
        if (e.MinX <= x0 || e.MaxX >= x1 || e.MinY <= y0 || e.MaxY >= y1) continue;
        prep::Ring ring;
        for (int i = 0; i + 1 < r->getNumPoints(); ++i)
          ring.push_back({(r->getX(i) - x0) * kx, (r->getY(i) - y0) * ky});
        rings.push_back(std::move(ring));
      }
  }
  // A bow-tie hole in open sea south of Crete's meridian band (35.1N 22.1E).
  const double cx = 0.1 * kx, cy = 0.1 * ky, r = 500;
  rings.push_back({{cx - r, cy - r}, {cx + r, cy + r}, {cx + r, cy - r}, {cx - r, cy + r}});
  return rings;
}

}  // namespace

TEST(CleanRealHoles, AegeanIslandsRepairedAsGeosMakeValidOfTheWhole) {
  const std::string seas = DECALPREP_EARTH_SEAS;
  if (!prep::test::exists(seas))
    GTEST_SKIP() << "missing " << seas << ": run scripts/fetch-data earth-seas";
  const std::vector<prep::Ring> rings = aegean_islands(seas);
  ASSERT_GT(rings.size(), 300u);  // 357 islands
  const prep::SceneFeatures out =
      prep::clean(prep::test::one_polygon_input("aegean", rings), prep::BuildSpec{});
  ASSERT_EQ(out.manifest.entries.size(), 1u);
  EXPECT_EQ(out.manifest.entries[0].action, prep::ManifestAction::repaired);

  prep::test::Geos geos;
  std::vector<prep::test::G> polys;
  for (const prep::ScenePolygon& p : out.polygons) polys.push_back(prep::test::polygon(geos.h, p));
  const prep::test::G got = prep::test::collection(geos.h, GEOS_MULTIPOLYGON, polys);
  EXPECT_EQ(GEOSisValid_r(geos.h, got.g), 1);
  const prep::test::G whole = prep::test::polygon(
      geos.h, rings[0], std::vector<prep::Ring>(rings.begin() + 1, rings.end()));
  const prep::test::G want(geos.h, GEOSMakeValid_r(geos.h, whole.g));
  const double a_want = prep::test::area(want);
  EXPECT_NEAR(prep::test::area(got), a_want, 1e-9 * a_want);
  const prep::test::G diff(geos.h, GEOSSymDifference_r(geos.h, got.g, want.g));
  EXPECT_LE(prep::test::area(diff), 1e-9 * a_want);
  std::printf("%zu holes: %zu polygons, area %.17g vs %.17g, symmetric difference %.3g m2\n",
              rings.size() - 1, out.polygons.size(), prep::test::area(got), a_want,
              prep::test::area(diff));
}
