// Clean on real data (Monaco): every output valid, simplification within the
// resolution (Hausdorff distance against the unsimplified output, GEOS).
// The full 0/0.1/0.5/2 m table is bench/bench_simplify.
#include <gtest/gtest.h>

#include "../read/fixtures.hpp"
#include "../read/scene_fixtures.hpp"
#include "geos_oracle.hpp"
#include "prep/pipeline.hpp"

namespace {

prep::SceneFeatures monaco(double resolution) {
  prep::SceneSpec s;
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
