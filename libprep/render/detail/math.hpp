// Small double-precision vector/matrix helpers for cameras (column-major,
// as GL expects). Internal to prep_render.
#pragma once

#include <array>
#include <cmath>

#include "prep/render.hpp"

namespace prep::render::detail {

using Mat4 = std::array<double, 16>;  // column-major: m[col * 4 + row]

// The direction towards the terrain's light (unnormalised; the terrain pass
// and the CPU image normalise it alike; web/src/render/index.js has it too).
inline constexpr Vec3 kLightTowards{-0.4, -0.5, 0.75};

// Ground metres of one pixel of an H-pixel-high view (thesis Eq. 4.1/4.2,
// static_common.glsl pixel_metres): an orthographic view's constant (0 in
// perspective), and a perspective view's per metre of distance to the eye,
// 2 tan(fov_y / 2) / H (0 orthographic).
inline double ortho_pixel_metres(const Camera& c, uint32_t H) {
  return c.projection == Projection::orthographic ? c.ortho_h / H : 0.0;
}
inline double pixel_metres_per_metre(const Camera& c, uint32_t H) {
  return c.projection == Projection::perspective
             ? 2.0 * std::tan(c.fov_y_deg * 3.14159265358979323846 / 360.0) / H
             : 0.0;
}

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

// The ray through a point of the image (normalised device x, y in [-1, 1],
// y up) of a W x H view: origin and (unnormalised) direction, in the
// camera's frame. Perspective rays start at the eye; orthographic ones on
// the far plane's counterpart, looking forward.
class PixelRays {
 public:
  PixelRays(const Camera& c, uint32_t width, uint32_t height)
      : cam_(c),
        inv_(mat_inverse(
            mat_mul(projection_matrix(c, double(width) / height), view_matrix(c, c.eye)))),
        forward_(camera_basis(c).forward) {}
  void ray(double nx, double ny, Vec3& origin, Vec3& direction) const {
    double v[4] = {nx, ny, 1.0, 1}, r[4] = {0, 0, 0, 0};
    for (int row = 0; row < 4; ++row)
      for (int k = 0; k < 4; ++k) r[row] += inv_[k * 4 + row] * v[k];
    const Vec3 p{r[0] / r[3], r[1] / r[3], r[2] / r[3]};
    if (cam_.projection == Projection::perspective) {
      origin = cam_.eye;
      direction = sub(p, cam_.eye);
    } else {
      origin = p;
      direction = forward_;
    }
  }

 private:
  const Camera& cam_;
  Mat4 inv_;
  Vec3 forward_;
};

}  // namespace prep::render::detail
