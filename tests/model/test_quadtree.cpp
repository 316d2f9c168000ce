// Quad-tree correctness against GEOS: for random polygons
// with holes and nested islands, every leaf's covered area (type 2: its box;
// type 3: the even-odd region of its leaf polygon inside the box) equals the
// GEOS area of polygon ∩ leaf box to 1e-9 relative, and no type-1/2 leaf box
// intersects the ring.
#include <gtest/gtest.h>

#include <cmath>

#include "../evaluate/synthetic.hpp"
#include "decal/layout.hpp"
#include "prep/model.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace model_quadtree {

namespace {

using synth::G;

// The model's leaf loops as (first, count) ranges of (start, end) segments,
// decoded by the format library (decal/layout.hpp).
struct LeafSegments {
  std::vector<prep::uvec2> range, segments;
  const prep::DecalModel& m;
  explicit LeafSegments(const prep::DecalModel& model) : m(model) {
    decal::layout::decode_leaves(m.qt_leaf_loop_range, m.qt_leaf_loops, range, segments);
  }
};

// Even-odd of the leaf polygon at (x, y), written here independently of the
// evaluator (plain double crossing test; used at face interior points only).
bool leaf_parity(const LeafSegments& l, const prep::uvec2& range, double x, double y) {
  const prep::DecalModel& m = l.m;
  bool in = false;
  for (uint32_t s = range[0]; s < range[0] + range[1]; ++s) {
    const auto& a = m.qt_leaf_vertices[l.segments[s][0]];
    const auto& b = m.qt_leaf_vertices[l.segments[s][1]];
    const double ax = a[0], ay = a[1], bx = b[0], by = b[1];
    if ((ay > y) != (by > y)) {
      const double xi = ax + (y - ay) * (bx - ax) / (by - ay);
      if (xi > x) in = !in;
    }
  }
  return in;
}

// Area of the leaf polygon's even-odd region inside box b: node the leaf
// segments with the box outline (GEOS), polygonize, and keep odd faces.
double leaf_region_area(GEOSContextHandle_t h, const LeafSegments& l, const prep::uvec2& range,
                        const G& boxpoly) {
  const prep::DecalModel& m = l.m;
  std::vector<G> parts;
  for (uint32_t s = range[0]; s < range[0] + range[1]; ++s) {
    const auto& a = m.qt_leaf_vertices[l.segments[s][0]];
    const auto& b = m.qt_leaf_vertices[l.segments[s][1]];
    parts.push_back(
        synth::linestring(h, {{double(a[0]), double(a[1])}, {double(b[0]), double(b[1])}}));
  }
  G mls = synth::collection(h, GEOS_MULTILINESTRING, parts);
  G inside(h, GEOSIntersection_r(h, mls.g, boxpoly.g));
  G outline(h, GEOSBoundary_r(h, boxpoly.g));
  G noded(h, GEOSUnion_r(h, inside.g, outline.g));
  const GEOSGeometry* in[] = {noded.g};
  G faces(h, GEOSPolygonize_r(h, in, 1));
  double area = 0;
  for (int i = 0; i < GEOSGetNumGeometries_r(h, faces.g); ++i) {
    const GEOSGeometry* f = GEOSGetGeometryN_r(h, faces.g, i);
    G pt(h, GEOSPointOnSurface_r(h, f));
    double x, y, a;
    GEOSGeomGetX_r(h, pt.g, &x);
    GEOSGeomGetY_r(h, pt.g, &y);
    GEOSArea_r(h, f, &a);
    if (leaf_parity(l, range, x, y)) area += a;
  }
  return area;
}

prep::Ring quantised(const prep::Ring& r) {
  prep::Ring q;
  for (const auto& p : r) {
    prep::Point2 v{double(std::llround(p.x / decal::kQuantumMetres)),
                   double(std::llround(p.y / decal::kQuantumMetres))};
    if (q.empty() || q.back().x != v.x || q.back().y != v.y) q.push_back(v);
  }
  return q;
}

}  // namespace

TEST(QuadTree, LeafAreasEqualGeosAreaOfPolygonInLeafAndSolidLeavesMissTheRing) {
  const synth::PolygonSet set = synth::polygon_set(42, 5, 80.0, 100.0, -200.0, 4, 400);
  prep::ModelOptions opt;
  const prep::DecalModel m = prep::build_model(set.scene, opt);
  const LeafSegments leaves_of_m(m);
  synth::Geos geos;
  auto h = geos.h;
  std::vector<prep::Ring> rings;  // package polygon order: exterior, then its holes
  for (const auto& p : set.scene.polygons) {
    rings.push_back(quantised(p.shell));
    for (const auto& r : p.holes) rings.push_back(quantised(r));
  }
  ASSERT_EQ(rings.size(), m.poly_props.size());
  uint64_t leaves[4] = {0, 0, 0, 0};
  double worst_rel = 0;
  for (size_t r = 0; r < rings.size(); ++r) {
    G poly = synth::polygon(h, rings[r]);
    G line = synth::linestring(h, rings[r], true);
    double impl_total = 0, geos_total = 0, box_total = 0;
    std::vector<uint32_t> stack{m.poly_root_node[r]};
    while (!stack.empty()) {
      const uint32_t n = stack.back();
      stack.pop_back();
      const auto type = decal::QtNodeType(m.qt_node[n][0]);
      if (type == decal::QtNodeType::internal) {
        for (int c = 0; c < 4; ++c) stack.push_back(uint32_t(m.qt_node[n][1] + c));
        continue;
      }
      ++leaves[int(type)];
      const auto& b = m.qt_node_box[n];
      G boxpoly = synth::box(h, b[0], b[1], b[2], b[3]);
      G clip(h, GEOSIntersection_r(h, poly.g, boxpoly.g));
      const double truth = prep::test::area(clip), box_area = prep::test::area(boxpoly);
      double impl = 0;
      if (type == decal::QtNodeType::outside || type == decal::QtNodeType::inside) {
        EXPECT_FALSE(GEOSIntersects_r(h, boxpoly.g, line.g))
            << "ring " << r << " node " << n << " type " << int(type) << " touches the ring";
        impl = type == decal::QtNodeType::inside ? box_area : 0.0;
      } else {
        ASSERT_EQ(type, decal::QtNodeType::partial);
        impl = leaf_region_area(h, leaves_of_m, leaves_of_m.range[m.qt_node[n][1]], boxpoly);
      }
      EXPECT_NEAR(impl, truth, 1e-9 * box_area)
          << "ring " << r << " node " << n << " type " << int(type);
      worst_rel = std::max(worst_rel, std::fabs(impl - truth) / box_area);
      impl_total += impl;
      geos_total += truth;
      box_total += box_area;
    }
    EXPECT_NEAR(impl_total, geos_total, 1e-9 * geos_total) << "ring " << r;
  }
  std::printf(
      "quad-tree leaves: %llu outside, %llu inside, %llu partial; worst |area - GEOS| / leaf "
      "box area = %.3g\n",
      (unsigned long long)leaves[1], (unsigned long long)leaves[2], (unsigned long long)leaves[3],
      worst_rel);
  EXPECT_GT(leaves[1], 0u);
  EXPECT_GT(leaves[2], 0u);
  EXPECT_GT(leaves[3], 0u);
}

TEST(QuadTree, DepthCapAndLeafOverflowAreReportedInTheManifest) {
  synth::PolygonSet set = synth::polygon_set(3, 2, 50.0, 0.0, 0.0, 1);
  prep::ModelOptions opt;
  opt.qt_leaf_capacity = 2;
  opt.qt_max_depth = 2;
  const prep::DecalModel m = prep::build_model(set.scene, opt);
  bool found = false;
  for (const auto& n : m.manifest.notes)
    found = found || n.find("maximum depth 2") != std::string::npos;
  EXPECT_TRUE(found);
  EXPECT_GT(m.stats.qt_depth_capped, 0u);
  EXPECT_GT(m.stats.qt_max_leaf_segments, 2u);
}

}  // namespace model_quadtree
