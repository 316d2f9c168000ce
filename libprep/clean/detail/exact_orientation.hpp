// The exact orientation predicate of clean's validity proof
// (detail/certainly_valid.hpp): CGAL's filtered exact predicate (Epick, as
// the model and render stages use it), in a file of its own so that CGAL
// and its -frounding-math stay out of the rest of the stage.
#pragma once

#include "prep/features.hpp"

namespace prep::detail {

// The exact sign of the orientation of (a, b, c) for finite coordinates:
// +1 left turn, -1 right turn, 0 collinear (exactly).
int exact_orientation(const Point2& a, const Point2& b, const Point2& c);

}  // namespace prep::detail
