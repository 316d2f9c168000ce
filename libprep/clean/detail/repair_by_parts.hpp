// The repair of hole-heavy polygons in clean (libprep/clean/clean.cpp): GEOS
// MakeValid on the parts of a polygon that need it, with the same result as
// MakeValid of the whole polygon.
//
// GEOS 3.11's MakeValid spends time quadratic in the number of rings on a
// polygon with many holes (its area builder looks for each face's parent
// among all faces): 10^5 holes take minutes. Holes far from every other
// ring cannot change the repair away from themselves, so only the rings
// that interact are given to MakeValid:
//  - holes are grouped by contact (the transitive closure of "the rings
//    meet, or one lies inside the other", that is, the polygons of the
//    rings alone intersect), candidates from envelope contact through a GEOS
//    STRtree (a continent-sized hole's envelope holds thousands of islands
//    that touch nothing);
//  - "properly inside the shell" below means inside the shell's area (a
//    real coastline may cross itself somewhere) without meeting the shell
//    ring: the hole ring meets no shell segment and a vertex of it has odd
//    crossing parity against the shell ring (GEOS prepared ContainsProperly
//    of the polygon of the shell alone, valid or not: its point-in-area
//    test counts crossings). The hole then lies in one face of the shell's
//    noded linework, of odd parity, which both methods keep (linework: the
//    faces of odd parity; structure: every face the ring winds around). So
//    the shell's own repair is not needed before the split;
//  - a group with a hole that is not properly inside the shell (it touches,
//    crosses or lies outside it) is repaired together with the shell: the
//    "base" repair R0 = MakeValid(shell + those holes) (with no such group,
//    MakeValid(shell alone), or the shell itself when it is valid);
//  - a group properly inside the shell is repaired on its own, inside a
//    rectangle clear of it: MakeValid(box + the group's holes) is the box
//    with the group's regions cut out (and any islands inside them). The
//    box's holes become holes of the R0 polygon that contains them and the
//    islands become polygons; a single hole that is a valid ring on its own
//    is kept as it is, without MakeValid.
// Why this is exact: a group properly inside the shell touches no other
// ring and neither holds nor lies inside another group, so in the noded
// linework of the whole polygon its (connected) edges lie in one face of
// the rest and bound faces that hold nothing of the rest. MakeValid (both methods) then
// treats it like an enclosed component of that face: with the "linework"
// method the faces get their parity from the rings around them (the shell
// only, here), with "structure" the shell minus the union of the holes.
// Either way the result near the group is that face minus the group's
// regions, which is what the box repair gives. The pieces only come
// together, no overlay, and the result is checked piece by piece instead
// of by GEOS isValid of the whole (whose hole-in-shell test costs holes x
// shell vertices: seconds here): every MakeValid result is valid (GEOS
// isValid), every cut-out ring lies properly inside the base polygon it is
// put in (prepared GEOS ContainsProperly) and rings of different groups do
// not meet (GEOS Intersects on envelope candidates). Then the assembly is
// a valid polygon: rings inside their shell that touch nothing outside
// their own valid group, islands inside the rings they came with.
// The base repair and the groups' repairs are independent: they run in
// parallel, largest first, and are put together in group order. A hole
// wrongly taken for clear of the shell could not pass unnoticed: its cut
// rings must lie properly inside a polygon of R0 (the check above).
// Tests: tests/clean/test_repair_by_parts.cpp (the result against GEOS
// MakeValid of the whole polygon).
#pragma once

#include <geos_c.h>

#include <functional>
#include <vector>

#include "geos_handle.hpp"
#include "prep/features.hpp"

namespace prep::detail {

// Below this many holes MakeValid of the whole polygon is cheap; those
// polygons keep their whole repair (and its vertex order) unchanged.
inline constexpr size_t kRepairByPartsMinHoles = 64;

// MakeValid with the scene's method, on one GEOS polygon, with the given
// GEOS context (null: GEOS failed). Called from several threads at once,
// each with a context of its own.
using MakeValidFn = std::function<GEOSGeometry*(GEOSContextHandle_t, const GEOSGeometry*)>;

// What a repair with a window left out (below): the clear groups that
// needed a repair of their own, and the lone valid holes with the sum of
// their GEOS areas (the area the whole repair would have less by them).
struct LeftOut {
  size_t groups = 0;
  size_t lone_holes = 0;
  double lone_hole_area = 0;
};

// The repair of `polygon` (a GEOS polygon built from `rings`: [0] shell,
// then holes, in the same order) by parts, as above. With a `window` (clean
// clips the repair to the scene extent next), a clear group whose envelope
// misses the window is left out, unrepaired: everything its repair would
// cut out of the base or add lies in that envelope, so the result inside
// the window is the same (groups not clear of the shell are always
// repaired, with it); `left_out` (when given) says what was left out. Null when the split
// does not apply (fewer than kRepairByPartsMinHoles holes, a shell whose
// own repair has no area, no hole group clear of the shell, too many
// envelope contacts to enumerate) or any step fails: the caller then repairs the
// whole polygon. The result is a Polygon, a MultiPolygon, or a
// GeometryCollection of polygons and the collapsed (non-areal) pieces that
// MakeValid returned; valid (checked as above).
GEOSGeometry* make_valid_by_parts(GEOSContextHandle_t h, const GEOSGeometry* polygon,
                                  const std::vector<Ring>& rings, const MakeValidFn& make_valid,
                                  const Envelope* window = nullptr, LeftOut* left_out = nullptr);

}  // namespace prep::detail
