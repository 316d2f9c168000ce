// The planar geometry of the two older methods `decalprep render --method`
// compares with the decal method (thesis §5.2.2): the volume method
// (Schneider & Klein §3, stencil shadow volumes) and the texture method
// (Taibo et al. §3, lines tessellated and rasterised into textures). Both
// start from the same triangles, rebuilt from a package's static blobs:
// - a polygon with its holes: the ring edges of its quad-trees (the leaf
//   segments with both ends in the root box; closing segments always end on
//   the frame one quantum outside it, libprep/model/quadtree.cpp), triangulated
//   with CGAL's constrained Delaunay triangulation, faces of odd nesting
//   depth kept (method_geometry.cpp is the one file that includes CGAL);
// - a static line: per segment the convex pieces of the evaluator's segment
//   test (libprep/evaluate/evaluate.cpp step 6): the body (rectangle, miter
//   quadrilateral or bevel parallelogram) and its corners (discs for round
//   ends and the 40° round fallback of a null miter, thesis §3.6; bevel
//   triangles), widths in ground metres (LineProps::half_width); open
//   inset/offset lines cut by the evaluator's half-planes, clipped outlines
//   intersected with the triangles on their side of their own ring, dashed
//   lines cut per segment to their "on" parts (step 6b).
// Dynamic lines (pixel widths) are not here: the decal method's dynamic pass
// draws them for every method.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "prep/evaluate.hpp"

namespace prep::render::detail {

using P2d = std::array<double, 2>;

// One region: counter-clockwise triangles plus its boundary edges (a, b),
// interior on the left; a prism over it is closed (caps over the triangles,
// walls over the edges). Metres relative to the package origin.
struct MethodFeature {
  uint32_t rank = 0;  // merged drawing order (formats/SPEC.md "Drawing order"), 0 = top
  uint32_t rgba = 0;  // straight alpha, R in the low byte
  bool line = false;
  uint32_t layer = 0;                          // layer-table index (props.layer)
  uint32_t first_triangle = 0, triangles = 0;  // into MethodGeometry::triangles (3 points each)
  uint32_t first_edge = 0, edges = 0;          // into MethodGeometry::edges
  Extent box{};                                // of the triangles
};

struct MethodGeometry {
  std::vector<MethodFeature> features;  // top first
  std::vector<P2d> triangles;           // 3 per triangle, counter-clockwise
  std::vector<std::array<P2d, 2>> edges;
};

// The static polygons and lines of `view` as above, in drawing order, each
// cut to `clip` when given (a tile's square; every triangle then bounds a
// region of its own). `polygons` / `lines` pick the kinds.
MethodGeometry method_geometry(const StaticView& view, bool polygons, bool lines,
                               const std::optional<Extent>& clip);

}  // namespace prep::render::detail
