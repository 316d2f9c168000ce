// A small DecalModel written by hand (no build stage needed): a square
// polygon with a square hole and a nested island, and a diagonal line, on a
// 2x2 grid over [0, 100] m². Tests compare renders with analytic coverage.
#pragma once

#include <algorithm>

#include "prep/model.hpp"

namespace render_test {

struct HandShapes {
  // Exterior [20, 80]², hole [40, 60]², island (separate exterior) [45, 55]².
  static bool in_polygon(double x, double y) {
    auto in = [&](double a, double b) { return x > a && x < b && y > a && y < b; };
    return (in(20, 80) && !in(40, 60)) || in(45, 55);
  }
  // Line (10, 10) -> (90, 90), half width 2, round.
  static bool in_line(double x, double y) {
    double t = std::clamp(((x - 10) * 80 + (y - 10) * 80) / (2 * 80.0 * 80.0), 0.0, 1.0);
    double px = 10 + 80 * t - x, py = 10 + 80 * t - y;
    return px * px + py * py <= 4.0;
  }
  // Line (10, 90) -> (90, 10), half width 3, round, drawn below the first.
  static bool in_line2(double x, double y) {
    double t = std::clamp(((x - 10) * 80 - (y - 90) * 80) / (2 * 80.0 * 80.0), 0.0, 1.0);
    double px = 10 + 80 * t - x, py = 90 - 80 * t - y;
    return px * px + py * py <= 9.0;
  }
  static constexpr uint32_t kLine2Rgba = 0x9000c0ffu;   // orange, alpha 0x90
  static constexpr uint32_t kPolyRgba = 0xff2020e0u;    // R=e0 G=20 B=20, opaque
  static constexpr uint32_t kIslandRgba = 0xff20e020u;  // green
  static constexpr uint32_t kLineRgba = 0x80e02020u;    // blue, alpha 0x80
};

prep::DecalModel hand_model();

}  // namespace render_test
