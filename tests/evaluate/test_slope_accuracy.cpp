// Slope widths in the CPU evaluator (step 6b of the query block in
// libprep/evaluate/evaluate.cpp; formats/SPEC.md "Slope widths") against
// GEOS buffers, corners and ends included. On the plane of gradient g the
// map L = I + (sqrt(1 + g.g) - 1) ĝ ĝ^T takes plan points to lengths on
// the ground (|L u| = |u|_G), so the band of a line measured on the ground
// is L^-1 of the plan band (the oracle of test_line_accuracy: round, bevel,
// miter buffers with round ends) of the line mapped by L. Round, miter and
// bevel zig-zags under a 60° and a 30° slope in two directions, half of
// DECALPREP_SAMPLES (default 10^6) points each; points within 2 mm of the
// oracle's boundary are left out. Lines whose miter
// corners would fall back to round on one side of the map and not on the
// other (the package decides by plan angles) are not drawn.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "sampling.hpp"
#include "synthetic.hpp"
#include "test_support.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace evaluate_slope_accuracy {

namespace {

using synth::G;

struct Map {
  double gx, gy, c;  // L = I + c ĝ ĝ^T
  Map(double gx_, double gy_) : gx(gx_), gy(gy_), c(std::sqrt(1 + gx_ * gx_ + gy_ * gy_) - 1) {}
  prep::Point2 apply(prep::Point2 p, double k) const {  // I + k ĝ ĝ^T
    const double g2 = gx * gx + gy * gy, s = k * (gx * p.x + gy * p.y) / g2;
    return {p.x + s * gx, p.y + s * gy};
  }
  prep::Point2 to_ground(prep::Point2 p) const { return apply(p, c); }
  prep::Point2 to_plan(prep::Point2 p) const { return apply(p, -c / (1 + c)); }
};

// The interior angles at the inner vertices, degrees.
std::vector<double> interior_angles(const prep::Ring& pts) {
  std::vector<double> out;
  for (size_t i = 1; i + 1 < pts.size(); ++i) {
    const double ax = pts[i].x - pts[i - 1].x, ay = pts[i].y - pts[i - 1].y;
    const double bx = pts[i + 1].x - pts[i].x, by = pts[i + 1].y - pts[i].y;
    const double turn = std::acos(
        std::clamp((ax * bx + ay * by) / (std::hypot(ax, ay) * std::hypot(bx, by)), -1.0, 1.0));
    out.push_back(180 - turn * 180 / M_PI);
  }
  return out;
}

// Every corner is a miter in plan and on the ground alike, or a round
// fallback in both (the package decides in plan, the oracle on the
// ground), at least 5° from the 40° limit.
bool same_corners(const prep::Ring& plan, const prep::Ring& ground) {
  const std::vector<double> a = interior_angles(plan), b = interior_angles(ground);
  for (size_t i = 0; i < a.size(); ++i) {
    const double lim = synth::kLimitDeg;
    if (std::abs(a[i] - lim) < 5 || std::abs(b[i] - lim) < 5 || (a[i] < lim) != (b[i] < lim))
      return false;
  }
  return true;
}

void run(const char* name, double slope_deg, double dir_deg, uint64_t seed) {
  const double s = std::tan(slope_deg * M_PI / 180);
  const Map L(s * std::cos(dir_deg * M_PI / 180), s * std::sin(dir_deg * M_PI / 180));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0, 1);
  prep::SceneFeatures scene;
  using decal::CornerStyle;
  scene.layers = {synth::layer("round", prep::DecalKind::line, 0xff0000ffu, CornerStyle::round,
                               decal::OutlineMode::normal, 3),
                  synth::layer("miter", prep::DecalKind::line, 0xff00ff00u, CornerStyle::miter,
                               decal::OutlineMode::normal, 3),
                  synth::layer("bevel", prep::DecalKind::line, 0xffff0000u, CornerStyle::bevel,
                               decal::OutlineMode::normal, 3)};
  const double tile = 120;
  const int cols = 12;
  std::vector<prep::SceneLine> ground;  // each line mapped by L
  for (uint32_t style = 0; style < 3; ++style)
    for (int k = 0; k < 36;) {
      const int t = int(scene.lines.size()), col = t % cols, row = t / cols;
      const prep::Point2 c{(col + 0.5) * tile, (row + 0.5) * tile};
      prep::SceneLine l;
      double a = 2 * M_PI * U(rng);
      prep::Point2 p = c;
      l.points.push_back(p);
      for (int v = 0; v < 4; ++v) {  // 4 segments of 8.5..9.5 m, turns 1..179°
        const double len = 8.5 + U(rng);
        p = {p.x + len * std::cos(a), p.y + len * std::sin(a)};
        l.points.push_back(p);
        a += (U(rng) < 0.5 ? -1 : 1) * (1 + 178 * U(rng)) * M_PI / 180.0;
      }
      prep::SceneLine m = l;
      for (prep::Point2& q : m.points) q = L.to_ground(q);
      if (!same_corners(l.points, m.points)) continue;
      l.layer = m.layer = style;
      l.width = m.width = 3;
      l.fid = m.fid = int64_t(scene.lines.size());
      l.length = 1000.0 - double(l.fid);
      scene.lines.push_back(l);
      ground.push_back(m);
      ++k;
    }
  const int rows = int((scene.lines.size() + cols - 1) / cols);
  scene.extent = {0, 0, cols * tile, rows * tile};
  const prep::DecalModel model = prep::build_model(scene, prep::ModelOptions{});
  const prep::StaticView view = prep::view_of(model);
  const std::vector<uint8_t> layers{1, 1, 1};
  const prep::SurfaceSlope slope{L.gx, L.gy, layers};
  const size_t n = prep::test::sample_count() / 2;
  size_t logged = 0, plan_wrong = 0;
  synth::Geos geos;
  synth::PreparedRegions regions(geos.h);
  std::vector<std::array<double, 4>> box;  // ground box of each line's band
  for (const prep::SceneLine& m : ground) {
    G o = synth::oracle(geos.h, m, scene.layers[m.layer]);
    double x0, y0, x1, y1;
    GEOSGeom_getXMin_r(geos.h, o.g, &x0);
    GEOSGeom_getYMin_r(geos.h, o.g, &y0);
    GEOSGeom_getXMax_r(geos.h, o.g, &x1);
    GEOSGeom_getYMax_r(geos.h, o.g, &y1);
    box.push_back({x0 - 2, y0 - 2, x1 + 2, y1 + 2});
    regions.add(std::move(o));
  }
  synth::Outcome o;
  for (size_t k = 0; k < n; ++k) {
    const size_t li = size_t(U(rng) * double(ground.size())) % ground.size();
    const auto& b = box[li];
    const prep::Point2 q{b[0] + U(rng) * (b[2] - b[0]), b[1] + U(rng) * (b[3] - b[1])};
    G pt = synth::point(geos.h, q.x, q.y);
    bool truth = false, near = false;
    for (size_t j = 0; j < ground.size(); ++j) {  // any line's band (boxes may overlap)
      const auto& c = box[j];
      if (!(q.x >= c[0] && q.x <= c[2] && q.y >= c[1] && q.y <= c[3])) continue;
      near = near || regions.near_boundary(j, pt, 0.002);
      truth = truth || regions.contains(j, pt);
    }
    if (near) {
      ++o.excluded;
      continue;
    }
    const prep::Point2 p = L.to_plan(q);
    const prep::EvalSample got = prep::evaluate(view, p.x, p.y, slope);
    ++o.tested;
    o.inside += truth;
    plan_wrong += prep::evaluate(view, p.x, p.y).line_covered != truth;
    if (got.line_covered != truth) {
      ++o.wrong;
      if (logged++ < 10)
        ADD_FAILURE() << name << ": (" << p.x << ", " << p.y << ") line " << li << " layer "
                      << scene.layers[ground[li].layer].name << ": GEOS " << truth << ", evaluator "
                      << got.line_covered;
    }
  }
  std::printf(
      "[%s] %llu tested (%llu covered, %llu within 2 mm left out): %llu misclassified; measured "
      "in plan, %llu\n",
      name, (unsigned long long)o.tested, (unsigned long long)o.inside,
      (unsigned long long)o.excluded, (unsigned long long)o.wrong, (unsigned long long)plan_wrong);
  EXPECT_EQ(o.wrong, 0u);
  EXPECT_GT(o.inside, o.tested / 10);
  EXPECT_GT(plan_wrong, o.tested / 100);  // the oracle sees the slope
}

TEST(SlopeAccuracy, CornersAndEndsOnASixtyDegreePlaneAgreeWithGeosBuffers) {
  run("60° towards 17°", 60, 17, 11);
}

TEST(SlopeAccuracy, CornersAndEndsOnAThirtyDegreePlaneAgreeWithGeosBuffers) {
  run("30° towards 250°", 30, 250, 12);
}

}  // namespace

}  // namespace evaluate_slope_accuracy
