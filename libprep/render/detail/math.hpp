// Small double-precision vector/matrix helpers for cameras (column-major,
// as GL expects). Internal to prep_render.
#pragma once

#include <array>
#include <cmath>

#include "prep/render.hpp"

namespace prep::render::detail {

using Mat4 = std::array<double, 16>;  // column-major: m[col * 4 + row]

inline Vec3 sub(const Vec3& a, const Vec3& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
inline Vec3 add(const Vec3& a, const Vec3& b) {
  return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}
inline Vec3 mul(const Vec3& a, double s) {
  return {a[0] * s, a[1] * s, a[2] * s};
}
inline double dot(const Vec3& a, const Vec3& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline Vec3 normalize(const Vec3& a) {
  double l = std::sqrt(dot(a, a));
  return l > 0 ? mul(a, 1.0 / l) : a;
}

inline Mat4 mat_mul(const Mat4& a, const Mat4& b) {
  Mat4 r{};
  for (int c = 0; c < 4; ++c)
    for (int rr = 0; rr < 4; ++rr) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += a[k * 4 + rr] * b[c * 4 + k];
      r[c * 4 + rr] = s;
    }
  return r;
}

// General 4x4 inverse (cofactors); the matrices here are well conditioned.
Mat4 mat_inverse(const Mat4& m);

// Camera basis: right, true up, forward (unit vectors).
struct Basis {
  Vec3 right, up, forward;
};
Basis camera_basis(const Camera& c);

// View matrix with the eye at `eye_rel` (anchor-relative).
Mat4 view_matrix(const Camera& c, const Vec3& eye_rel);
// Reversed-Z projection (GL_ZERO_TO_ONE clip control, depth 1 at the near
// plane, 0 at infinity / the far end of the orthographic range).
Mat4 projection_matrix(const Camera& c, double aspect);

}  // namespace prep::render::detail
