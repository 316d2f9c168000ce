// The clip of a valid hole-heavy polygon to the scene extent in clean
// (libprep/clean/clean.cpp), with the same area as GEOS Intersection of the
// whole polygon and the rectangle.
//
// GEOS Intersection (OverlayNG) of a polygon with tens of thousands of
// holes and a rectangle spends minutes assigning every hole to its result
// polygon, although most holes lie wholly outside the rectangle or wholly
// inside it. For a valid polygonal input, per polygon:
//  - a hole whose envelope misses the rectangle cannot change the result
//    inside it: it is left out;
//  - a hole whose envelope lies strictly inside the rectangle comes through
//    the intersection unchanged: it is set aside, and put back afterwards
//    into the result polygon that covers it (a valid input's hole lies in
//    its polygon's closure, so in exactly one result piece; the smallest
//    covering shell when an island piece lies in a hole);
//  - only the shell and the holes that cross the rectangle's boundary go to
//    GEOS Intersection, one input polygon at a time (the polygons of a
//    valid MultiPolygon have disjoint interiors, so their clips do too).
// The result is valid when the input is: its rings are the clipped rings
// and the original holes, in the places the whole intersection gives them.
// Tests: tests/clean/test_clip_many_holes.cpp (the result against GEOS
// Intersection of the whole).
#pragma once

#include <geos_c.h>

#include <cstddef>

namespace prep::detail {

// Below this many holes in all the whole intersection is cheap; those
// polygons keep GEOS Intersection's result (and its ring order) unchanged.
inline constexpr size_t kClipByHolesMinHoles = 64;

// The intersection of `valid` with the rectangle [x0, x1] x [y0, y1], as
// above. `valid` is a valid Polygon or MultiPolygon, or a GeometryCollection
// of such polygons and lower-dimensional pieces (as MakeValid returns; the
// pieces are clipped as they are). Null when the split does not apply
// (another geometry type, fewer than kClipByHolesMinHoles holes) or a step
// fails (a set-aside hole that no result piece covers): the caller then
// intersects the whole. The result is a Polygon, a MultiPolygon (empty when
// nothing is left), or a GeometryCollection of the area and the lower-
// dimensional pieces.
GEOSGeometry* clip_many_holes(GEOSContextHandle_t h, const GEOSGeometry* valid, double x0,
                              double y0, double x1, double y1);

}  // namespace prep::detail
