// The adaptive decal grid (libprep/model/grid.cpp
// choose_grid): size-aware against the thesis 500x500 grid on the same data,
// coarse for sparse data, and stopped early by target_per_cell. Sizes are
// read from the built arrays, not from the estimate choose_grid makes.
#include <gtest/gtest.h>

#include <cstdio>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "../evaluate/synthetic.hpp"
#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "v12_cells.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace model_grid {

namespace {

template <class T>
uint64_t bytes_of(const std::vector<T>& v) {
  return uint64_t(v.size()) * sizeof(T);
}

// Every static blob of the model in the v1.2 layout the grid chooser's byte
// model counts (grid.cpp): the leaf polygons as one (start, end) segment per
// leaf vertex rather than the model's loops.
uint64_t static_bytes(const prep::DecalModel& m) {
  return bytes_of(m.line_vertices) + bytes_of(m.line_vertex_line) + bytes_of(m.line_props) +
         bytes_of(m.line_corners) + bytes_of(m.poly_props) + bytes_of(m.poly_root_node) +
         bytes_of(m.qt_node_box) + bytes_of(m.qt_node) + bytes_of(m.qt_leaf_loop_range) +
         2 * bytes_of(m.qt_leaf_vertices) + prep::test::v12_cell_bytes(m);
}

// A city-like scene: polygons (a third with a hole) and polylines, denser
// towards the centre, so that cells near it hold many primitives.
prep::SceneFeatures clustered_scene(int polygons, int lines) {
  auto vertices = [nv = std::uniform_int_distribution<int>(6, 30)](std::mt19937_64& rng) mutable {
    return nv(rng);
  };
  return synth::clustered_scene({.seed = 21,
                                 .polygons = polygons,
                                 .lines = lines,
                                 .sx = 800,
                                 .sy = 500,
                                 .shell_vertices = vertices,
                                 .hole_vertices = vertices,
                                 .walk_points = 12,
                                 .step = 20,
                                 .turn = 0.5,
                                 .corner = decal::CornerStyle::bevel,
                                 .width = 4,
                                 .length = [](int) { return 220.0; }});
}

// Mean of all query-cost counters over `n` covered points sampled uniformly
// over the grid (the same points for any grid over the same extent).
double mean_tests(const prep::DecalModel& m, const prep::Extent& e, int n) {
  const prep::StaticView v = prep::view_of(m);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> X(e.xmin, e.xmax), Y(e.ymin, e.ymax);
  double sum = 0;
  int covered = 0;
  for (int i = 0; i < 200 * n && covered < n; ++i) {
    prep::EvalCounters c;
    const prep::EvalSample s = prep::evaluate(v, X(rng), Y(rng), &c);
    if (!s.line_covered && !s.polygon_covered) continue;
    sum += double(c.bvh_nodes + c.qt_nodes + c.edge_tests + c.segment_tests);
    ++covered;
  }
  EXPECT_EQ(covered, n);
  return sum / covered;
}

prep::Extent extent_of(const prep::DecalModel& m) {
  const double q = decal::kQuantumMetres;
  return {m.grid.origin_x * q, m.grid.origin_y * q,
          (m.grid.origin_x + m.grid.cell_w * int64_t(m.grid.nx)) * q,
          (m.grid.origin_y + m.grid.cell_h * int64_t(m.grid.ny)) * q};
}

}  // namespace

TEST(DecalGrid, AdaptivePackageIsAtMost1Point2TimesTheThesisGridsAndQueriesCostLess) {
  for (const int lines : {1500, 0}) {
    SCOPED_TRACE(lines ? "polygons and lines" : "polygons only");
    const prep::SceneFeatures scene = clustered_scene(3000, lines);
    prep::ModelOptions adaptive, thesis;
    thesis.grid_nx = thesis.grid_ny = 500;
    const prep::DecalModel a = prep::build_model(scene, adaptive),
                           t = prep::build_model(scene, thesis);
    ASSERT_EQ(t.grid.nx, 500u);
    ASSERT_GT(a.grid.nx, 0u);
    const double ratio = double(static_bytes(a)) / double(static_bytes(t));
    // The size contract of docs/build.md and grid.cpp (kGridSizeBudget).
    EXPECT_LE(ratio, 1.2) << "adaptive grid " << a.grid.nx << "x" << a.grid.ny;
    std::printf("[%s] adaptive %ux%u: %.4f x the 500x500 package\n",
                lines ? "polygons and lines" : "polygons only", a.grid.nx, a.grid.ny, ratio);
    // Same points for both: sample over the larger of the two grid extents.
    const prep::Extent ea = extent_of(a), et = extent_of(t);
    const prep::Extent e{std::min(ea.xmin, et.xmin), std::min(ea.ymin, et.ymin),
                         std::max(ea.xmax, et.xmax), std::max(ea.ymax, et.ymax)};
    const double ta = mean_tests(a, e, 20000), tt = mean_tests(t, e, 20000);
    EXPECT_LT(ta, tt) << "adaptive " << a.grid.nx << "x" << a.grid.ny << " bytes ratio " << ratio;
  }
}

TEST(DecalGrid, OnePolygonGetsAFewCellsRatherThanTheThesisQuarterMillion) {
  std::mt19937_64 rng(4);
  prep::SceneFeatures s;
  s.layers.push_back(synth::layer("parcel", prep::DecalKind::polygon, 0xff0000ffu));
  prep::ScenePolygon p;
  p.shell = synth::star(rng, 0, 0, 60, 100, 200, false);
  p.area = 1;
  s.polygons.push_back(p);
  prep::ModelOptions adaptive, thesis;
  thesis.grid_nx = thesis.grid_ny = 500;
  const prep::DecalModel a = prep::build_model(s, adaptive), t = prep::build_model(s, thesis);
  EXPECT_LT(uint64_t(a.grid.nx) * a.grid.ny, 250000u / 16) << a.grid.nx << "x" << a.grid.ny;
  EXPECT_LT(static_bytes(a) * 4, static_bytes(t));
}

TEST(DecalGrid, TargetPerCellStopsTheRefinementAtACoarserGrid) {
  const prep::SceneFeatures scene = clustered_scene(1500, 0);
  prep::ModelOptions dflt, aimed;
  aimed.target_per_cell = 48;
  const prep::DecalModel d = prep::build_model(scene, dflt), a = prep::build_model(scene, aimed);
  EXPECT_LT(uint64_t(a.grid.nx) * a.grid.ny, uint64_t(d.grid.nx) * d.grid.ny);
  EXPECT_LT(static_bytes(a), static_bytes(d));
}

TEST(DecalGrid, MinCellKeepsEveryCellAtLeastThatWideAndTheModelSmaller) {
  const prep::SceneFeatures scene = clustered_scene(3000, 1500);
  prep::ModelOptions dflt, floored;
  const prep::DecalModel d = prep::build_model(scene, dflt);
  const double q = decal::kQuantumMetres;
  const double d_side = double(d.grid.cell_w) * q;
  // A floor well above the default grid's cells (which the dense centre drives fine).
  floored.min_cell_m = 4 * d_side;
  const prep::DecalModel f = prep::build_model(scene, floored);
  EXPECT_GE(double(f.grid.cell_w) * q, floored.min_cell_m);
  EXPECT_GE(double(f.grid.cell_h) * q, floored.min_cell_m);
  EXPECT_LT(static_bytes(f), static_bytes(d));
  // The same primitives are found: evaluate() at covered points agrees.
  const prep::StaticView vd = prep::view_of(d), vf = prep::view_of(f);
  const prep::Extent e = extent_of(d);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> X(e.xmin, e.xmax), Y(e.ymin, e.ymax);
  int covered = 0;
  for (int i = 0; i < 20000; ++i) {
    const double x = X(rng), y = Y(rng);
    const prep::EvalSample a = prep::evaluate(vd, x, y), b = prep::evaluate(vf, x, y);
    ASSERT_EQ(a.line_covered, b.line_covered) << x << "," << y;
    ASSERT_EQ(a.polygon_covered, b.polygon_covered) << x << "," << y;
    covered += a.line_covered || a.polygon_covered;
  }
  EXPECT_GT(covered, 1000);
  // One tiny polygon under a floor wider than the data: one cell, not a failure.
  prep::SceneFeatures one;
  one.layers = scene.layers;
  one.polygons.push_back(scene.polygons.front());
  prep::ModelOptions wide;
  wide.min_cell_m = 1e5;
  const prep::DecalModel o = prep::build_model(one, wide);
  EXPECT_EQ(uint64_t(o.grid.nx) * o.grid.ny, 1u);
}

// A strip 3,800 km long and 340 km high near the top of the int32 quantum
// range (an overview tile of 4,000 km with only its top edge covered): the
// square cells its width asks for would end past 2^31 quanta, which the
// shaders and the evaluator refuse. The grid stays inside the range, and
// every point of the strip (the analytic rectangle is the oracle) and none
// outside it is covered.
TEST(DecalGrid, AStripAtTheEdgeOfTheQuantumRangeGetsAGridInsideIt) {
  prep::SceneFeatures s;
  s.layers.push_back(synth::layer("strip", prep::DecalKind::polygon, 0xff0000ffu));
  prep::ScenePolygon p;
  const double x0 = -1.9e6, x1 = 1.9e6, y0 = 1.65e6, y1 = 1.99e6;
  p.shell = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  p.area = (x1 - x0) * (y1 - y0);
  s.polygons.push_back(p);
  prep::ModelOptions coarse;
  coarse.min_cell_m = 8000;  // a level-3 tile's cells at 500 km tiles
  const prep::DecalModel m = prep::build_model(s, coarse);
  const int64_t end = int64_t(1) << 31;
  EXPECT_LT(m.grid.origin_x + m.grid.cell_w * int64_t(m.grid.nx), end);
  EXPECT_LT(m.grid.origin_y + m.grid.cell_h * int64_t(m.grid.ny), end);
  EXPECT_GT(m.grid.origin_x, -end);
  EXPECT_GT(m.grid.origin_y, -end);
  const prep::StaticView v = prep::view_of(m);  // would throw on a grid past the range
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> X(x0 - 1e4, x1 + 1e4),
      Y(y0 - 1e4, std::min(y1 + 1e4, 2.1e6));
  for (int i = 0; i < 20000; ++i) {
    const double x = X(rng), y = Y(rng);
    const bool inside = x > x0 + 1 && x < x1 - 1 && y > y0 + 1 && y < y1 - 1;
    const bool outside = x < x0 - 1 || x > x1 + 1 || y < y0 - 1 || y > y1 + 1;
    if (!inside && !outside) continue;
    ASSERT_EQ(prep::evaluate(v, x, y).polygon_covered, inside) << x << "," << y;
  }
}

// A thin square frame (1.5 m wide, 1 km across, one ring with a slit) on
// the thesis grid: its cells fill a small share of the cell rectangle they
// span, so build_model merges its parts per cell by a sort
// (ring_cell_entries in libprep/model/build_model.cpp), while the star inside
// it takes the dense array. Every point clear of the outlines agrees with an
// even-odd crossing test on the input rings (the oracle), so every cell the
// polygons reach lists them, each with a culling node that holds its part.
TEST(DecalGrid, ThinFrameIsFoundInEveryCellItCrosses) {
  std::mt19937_64 rng(5);
  prep::SceneFeatures s;
  s.layers.push_back(synth::layer("parcels", prep::DecalKind::polygon, 0xc0406080u));
  // Corners of the frame; its sides split into 1 m edges, so that its
  // quad-tree leaves are small (the thesis leaf holds 8 edges).
  const std::vector<prep::Point2> corners = {{0, 0},       {1000, 0},  {1000, 1000}, {0, 1000},
                                             {0, 501},     {1.5, 501}, {1.5, 998.5}, {998.5, 998.5},
                                             {998.5, 1.5}, {1.5, 1.5}, {1.5, 499},   {0, 499}};
  prep::ScenePolygon frame;
  for (size_t i = 0; i < corners.size(); ++i) {
    const prep::Point2 a = corners[i], b = corners[(i + 1) % corners.size()];
    const int n = std::max(1, int(std::ceil(std::hypot(b.x - a.x, b.y - a.y))));
    for (int k = 0; k < n; ++k)
      frame.shell.push_back({a.x + (b.x - a.x) * k / n, a.y + (b.y - a.y) * k / n});
  }
  frame.area = 1;
  prep::ScenePolygon blob;
  blob.shell = synth::star(rng, 500, 500, 60, 150, 40, false);
  blob.area = 2;
  blob.fid = 1;
  s.polygons = {frame, blob};
  prep::ModelOptions thesis;
  thesis.grid_nx = thesis.grid_ny = 500;
  const prep::DecalModel m = prep::build_model(s, thesis);
  // The frame's entries: a sixth of the grid at most (its rectangle is all of it).
  uint64_t frame_cells = 0;
  for (const auto& e : m.cell_poly_entries) frame_cells += e[0] == 0;
  EXPECT_LT(frame_cells * 6, uint64_t(m.grid.nx) * m.grid.ny);
  const prep::StaticView v = prep::view_of(m);
  auto inside = [](const prep::Ring& r, double x, double y, double& clearance) {
    bool in = false;
    clearance = std::numeric_limits<double>::infinity();
    for (size_t i = 0, j = r.size() - 1; i < r.size(); j = i++) {
      const prep::Point2 a = r[j], b = r[i];
      if ((a.y > y) != (b.y > y) && x < a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y)) in = !in;
      const double dx = b.x - a.x, dy = b.y - a.y;
      const double t =
          std::clamp(((x - a.x) * dx + (y - a.y) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
      clearance = std::min(clearance, std::hypot(x - a.x - t * dx, y - a.y - t * dy));
    }
    return in;
  };
  std::uniform_real_distribution<double> U(0, 1000), D(-2, 4), B(-200, 200);
  int in_frame = 0, in_blob = 0, checked = 0;
  for (int i = 0; i < 40000; ++i) {
    double x = 500 + B(rng), y = 500 + B(rng);
    if (i % 2 == 0) {  // near a side of the frame
      const double t = U(rng), d = D(rng);
      const int side = (i / 2) % 4;
      x = side == 0 ? t : side == 1 ? 1000 - d : side == 2 ? t : d;
      y = side == 0 ? d : side == 1 ? t : side == 2 ? 1000 - d : t;
    }
    double c0, c1;
    const bool a = inside(frame.shell, x, y, c0), b = inside(blob.shell, x, y, c1);
    if (std::min(c0, c1) < 0.01) continue;  // within quantisation reach of an outline
    ++checked;
    in_frame += a;
    in_blob += b;
    ASSERT_EQ(prep::evaluate(v, x, y).polygon_covered, a || b) << x << "," << y;
  }
  EXPECT_GT(checked, 35000);
  EXPECT_GT(in_frame, 3000);
  EXPECT_GT(in_blob, 2000);
}

// What the build reports once the grid is chosen (ModelOptions::on_grid,
// where --max-memory checks it) is what it then makes: the cell count, and
// the bytes the cell lists and BVHs take in the v1.2 count, read here from
// the built arrays (prep::test::v12_cell_bytes). The chooser counts every
// (cell, hole) pair a hole's leaves make, the build keeps those whose
// exterior is in the cell too: equal without holes, at most a little over
// with them. Adaptive (exact counts) and fixed grids alike.
TEST(DecalGrid, TheFootprintReportedAtTheGridChoiceIsWhatTheBuildMakes) {
  for (const bool holes : {false, true})
    for (const uint32_t fixed : {0u, 300u}) {
      SCOPED_TRACE(std::string(holes ? "with" : "without") + " holes, grid " +
                   (fixed ? std::to_string(fixed) : std::string("adaptive")));
      prep::SceneFeatures s = clustered_scene(400, 200);
      if (!holes)
        for (prep::ScenePolygon& p : s.polygons) p.holes.clear();
      prep::ModelOptions o;
      o.grid_nx = o.grid_ny = fixed;
      int calls = 0;
      prep::GridFootprint f;
      o.on_grid = [&](const prep::GridFootprint& g) {
        ++calls;
        f = g;
      };
      const prep::DecalModel m = prep::build_model(s, o);
      ASSERT_EQ(calls, 1);
      EXPECT_EQ(f.cells, uint64_t(m.grid.nx) * m.grid.ny);
      const double built = double(prep::test::v12_cell_bytes(m));
      if (holes) {
        EXPECT_GE(f.cell_bytes, built);
        EXPECT_LE(f.cell_bytes, 1.02 * built);
      } else {
        EXPECT_EQ(f.cell_bytes, built);
      }
      EXPECT_EQ(
          f.geometry_bytes,
          double(bytes_of(m.line_vertices) + bytes_of(m.line_vertex_line) + bytes_of(m.line_props) +
                 bytes_of(m.line_corners) + bytes_of(m.poly_props) + bytes_of(m.poly_root_node) +
                 bytes_of(m.qt_node_box) + bytes_of(m.qt_node) + bytes_of(m.qt_leaf_loop_range) +
                 bytes_of(m.qt_leaf_loops) + bytes_of(m.qt_leaf_vertices)));
    }
}

}  // namespace model_grid
