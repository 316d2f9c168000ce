// Polygon coverage of the CPU evaluator against GEOS:
// GEOSContains on the cleaned polygon with holes (nested islands are their
// own polygons), >= 10^6 samples, uniform and near edges, points within 2 mm
// of a boundary excluded, 0 misclassified.
#include <gtest/gtest.h>
#include <cstdlib>
#include <mutex>

#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "sampling.hpp"
#include "synthetic.hpp"
#include "test_support.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace evaluate_polygon_accuracy {

namespace {

// 10^6 samples for each dataset at the origin; the variants (900 km, mm
// scale, 500x500 grid) default to 2.5x10^5 to keep ctest short.
// DECALPREP_SAMPLES overrides both.
using prep::test::sample_count;
using prep::test::VariantSamples;

using synth::Outcome;

// Max distance between the cleaned input vertices and the stored quanta,
// computed here independently of the build.
double measured_representation_error(const prep::SceneFeatures& s) {
  double e = 0;
  for (const auto& p : s.polygons) {
    std::vector<const prep::Ring*> rings{&p.shell};
    for (const auto& h : p.holes) rings.push_back(&h);
    for (const auto* r : rings)
      for (const auto& v : *r)
        e = std::max(e, std::hypot(std::llround(v.x * 1000.0) / 1000.0 - v.x,
                                   std::llround(v.y * 1000.0) / 1000.0 - v.y));
  }
  return e;
}

Outcome check_polygons(const synth::PolygonSet& set, const prep::DecalModel& model, size_t n,
                       double near, double band) {
  const prep::StaticView view = prep::view_of(model);
  const auto& polys = set.scene.polygons;  // pairs: (shell with hole, island) per tile
  std::mutex log_mutex;
  int logged = 0;
  // One chunk: `count` samples on the chunk's own GEOS context `h`.
  auto sample = [&](GEOSContextHandle_t h, std::mt19937_64& rng, size_t count) {
    synth::PreparedRegions oracle(h);
    for (const auto& p : polys) oracle.add(synth::polygon(h, p.shell, p.holes));
    std::uniform_real_distribution<double> U(0, 1);
    const double span = set.tiles * set.tile;
    Outcome mine;
    for (size_t k = 0; k < count; ++k) {
      double x, y;
      if (k % 2 == 0) {  // uniform over the extent and a margin around it
        x = set.ox - 0.05 * span + 1.1 * span * U(rng);
        y = set.oy - 0.05 * span + 1.1 * span * U(rng);
      } else {  // near an edge of a random ring
        const auto& p = polys[size_t(U(rng) * polys.size()) % polys.size()];
        const prep::Ring& r = (p.holes.empty() || U(rng) < 0.5) ? p.shell : p.holes[0];
        const size_t i = size_t(U(rng) * r.size()) % r.size();
        const auto& a = r[i];
        const auto& b = r[(i + 1) % r.size()];
        const double t = U(rng);
        x = a.x + t * (b.x - a.x) + near * (2 * U(rng) - 1);
        y = a.y + t * (b.y - a.y) + near * (2 * U(rng) - 1);
      }
      const int ti = int(std::floor((x - set.ox) / set.tile)),
                tj = int(std::floor((y - set.oy) / set.tile));
      bool truth = false, skip = false;
      if (ti >= 0 && tj >= 0 && ti < set.tiles && tj < set.tiles) {
        const size_t base = 2 * size_t(ti + tj * set.tiles);
        synth::G pt = synth::point(h, x, y);
        for (size_t q = base; q < base + 2; ++q) {
          if (oracle.near_boundary(q, pt, band)) skip = true;
          truth = truth || oracle.contains(q, pt);
        }
      }
      if (skip) {
        ++mine.excluded;
        continue;
      }
      ++mine.tested;
      mine.inside += truth;
      const bool got = prep::evaluate(view, x, y).polygon_covered;
      if (got != truth) {
        ++mine.wrong;
        std::lock_guard<std::mutex> lock(log_mutex);
        if (logged++ < 10)
          ADD_FAILURE() << "misclassified (" << std::fixed << x << ", " << y << "): GEOS " << truth
                        << " evaluator " << got;
      }
    }
    return mine;
  };
  return synth::sample_in_chunks(n, 4, 1234, sample);
}

void run_case(const char* name, const synth::PolygonSet& set, double near, double min_tested = 0.5,
              uint32_t grid = 0) {
  prep::ModelOptions opt;
  opt.grid_nx = opt.grid_ny = grid;
  const prep::DecalModel model = prep::build_model(set.scene, opt);
  const Outcome o = check_polygons(set, model, sample_count(), near, 0.002);
  synth::print_outcome(name, "polygons", "inside", o, model);
  EXPECT_EQ(o.wrong, 0u);
  EXPECT_GT(double(o.tested), min_tested * double(sample_count()));
  EXPECT_LE(model.max_representation_error, 0.001);
  EXPECT_NEAR(model.max_representation_error, measured_representation_error(set.scene), 1e-9);
}

}  // namespace

TEST(PolygonAccuracy, EvaluatorAgreesWithGeosContainsOnPolygonsWithHolesAndIslands) {
  run_case("origin", synth::polygon_set(7, 20, 100.0, -1000.0, 500.0), 0.05);
}

TEST(PolygonAccuracy, CullingNodesAreRightOnTheThesis500x500Grid) {
  VariantSamples variant;
  run_case("500x500", synth::polygon_set(10, 20, 100.0, 0.0, 0.0), 0.05, 0.5, 500);
}

TEST(PolygonAccuracy, EvaluatorAgreesWithGeos900KmFromTheOrigin) {
  VariantSamples variant;
  run_case("900 km", synth::polygon_set(8, 20, 100.0, 900000.0, -3000.0), 0.05);
}

TEST(PolygonAccuracy, EvaluatorAgreesWithGeosOnMillimetreFeatures) {
  VariantSamples variant;
  // Tiles of 4 cm: islands 1-3 mm across, annuli a few mm wide, at 1 mm
  // quanta. Most samples fall in the 2 mm band, the rest must agree.
  run_case("mm", synth::polygon_set(9, 20, 0.04, 12.0, 34.0), 0.004, 0.2);
}

}  // namespace evaluate_polygon_accuracy
