// detail/exact_orientation.hpp: CGAL's exact orientation of three points.
#include "detail/exact_orientation.hpp"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>

namespace prep::detail {

int exact_orientation(const Point2& a, const Point2& b, const Point2& c) {
  using P = CGAL::Exact_predicates_inexact_constructions_kernel::Point_2;
  return static_cast<int>(CGAL::orientation(P(a.x, a.y), P(b.x, b.y), P(c.x, c.y)));
}

}  // namespace prep::detail
