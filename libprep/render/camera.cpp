// Cameras and their matrices (prep/render.hpp).
#include <algorithm>
#include <cmath>
#include <numbers>

#include "detail/math.hpp"

namespace prep::render {

namespace detail {

Mat4 mat_inverse(const Mat4& m) {
  Mat4 inv{};
  inv[0] = m[5] * m[10] * m[15] - m[5] * m[11] * m[14] - m[9] * m[6] * m[15] + m[9] * m[7] * m[14] +
           m[13] * m[6] * m[11] - m[13] * m[7] * m[10];
  inv[4] = -m[4] * m[10] * m[15] + m[4] * m[11] * m[14] + m[8] * m[6] * m[15] -
           m[8] * m[7] * m[14] - m[12] * m[6] * m[11] + m[12] * m[7] * m[10];
  inv[8] = m[4] * m[9] * m[15] - m[4] * m[11] * m[13] - m[8] * m[5] * m[15] + m[8] * m[7] * m[13] +
           m[12] * m[5] * m[11] - m[12] * m[7] * m[9];
  inv[12] = -m[4] * m[9] * m[14] + m[4] * m[10] * m[13] + m[8] * m[5] * m[14] -
            m[8] * m[6] * m[13] - m[12] * m[5] * m[10] + m[12] * m[6] * m[9];
  inv[1] = -m[1] * m[10] * m[15] + m[1] * m[11] * m[14] + m[9] * m[2] * m[15] -
           m[9] * m[3] * m[14] - m[13] * m[2] * m[11] + m[13] * m[3] * m[10];
  inv[5] = m[0] * m[10] * m[15] - m[0] * m[11] * m[14] - m[8] * m[2] * m[15] + m[8] * m[3] * m[14] +
           m[12] * m[2] * m[11] - m[12] * m[3] * m[10];
  inv[9] = -m[0] * m[9] * m[15] + m[0] * m[11] * m[13] + m[8] * m[1] * m[15] - m[8] * m[3] * m[13] -
           m[12] * m[1] * m[11] + m[12] * m[3] * m[9];
  inv[13] = m[0] * m[9] * m[14] - m[0] * m[10] * m[13] - m[8] * m[1] * m[14] + m[8] * m[2] * m[13] +
            m[12] * m[1] * m[10] - m[12] * m[2] * m[9];
  inv[2] = m[1] * m[6] * m[15] - m[1] * m[7] * m[14] - m[5] * m[2] * m[15] + m[5] * m[3] * m[14] +
           m[13] * m[2] * m[7] - m[13] * m[3] * m[6];
  inv[6] = -m[0] * m[6] * m[15] + m[0] * m[7] * m[14] + m[4] * m[2] * m[15] - m[4] * m[3] * m[14] -
           m[12] * m[2] * m[7] + m[12] * m[3] * m[6];
  inv[10] = m[0] * m[5] * m[15] - m[0] * m[7] * m[13] - m[4] * m[1] * m[15] + m[4] * m[3] * m[13] +
            m[12] * m[1] * m[7] - m[12] * m[3] * m[5];
  inv[14] = -m[0] * m[5] * m[14] + m[0] * m[6] * m[13] + m[4] * m[1] * m[14] - m[4] * m[2] * m[13] -
            m[12] * m[1] * m[6] + m[12] * m[2] * m[5];
  inv[3] = -m[1] * m[6] * m[11] + m[1] * m[7] * m[10] + m[5] * m[2] * m[11] - m[5] * m[3] * m[10] -
           m[9] * m[2] * m[7] + m[9] * m[3] * m[6];
  inv[7] = m[0] * m[6] * m[11] - m[0] * m[7] * m[10] - m[4] * m[2] * m[11] + m[4] * m[3] * m[10] +
           m[8] * m[2] * m[7] - m[8] * m[3] * m[6];
  inv[11] = -m[0] * m[5] * m[11] + m[0] * m[7] * m[9] + m[4] * m[1] * m[11] - m[4] * m[3] * m[9] -
            m[8] * m[1] * m[7] + m[8] * m[3] * m[5];
  inv[15] = m[0] * m[5] * m[10] - m[0] * m[6] * m[9] - m[4] * m[1] * m[10] + m[4] * m[2] * m[9] +
            m[8] * m[1] * m[6] - m[8] * m[2] * m[5];
  double det = m[0] * inv[0] + m[1] * inv[4] + m[2] * inv[8] + m[3] * inv[12];
  for (double& v : inv) v /= det;
  return inv;
}

Basis camera_basis(const Camera& c) {
  Vec3 f = normalize(sub(c.target, c.eye));
  Vec3 r = normalize(cross(f, c.up));
  Vec3 u = cross(r, f);
  return {r, u, f};
}

Mat4 view_matrix(const Camera& c, const Vec3& eye_rel) {
  Basis b = camera_basis(c);
  Mat4 m{};
  for (int k = 0; k < 3; ++k) {
    m[k * 4 + 0] = b.right[k];
    m[k * 4 + 1] = b.up[k];
    m[k * 4 + 2] = -b.forward[k];
  }
  m[12] = -dot(b.right, eye_rel);
  m[13] = -dot(b.up, eye_rel);
  m[14] = dot(b.forward, eye_rel);
  m[15] = 1;
  return m;
}

Mat4 projection_matrix(const Camera& c, double aspect) {
  Mat4 p{};
  if (c.projection == Projection::perspective) {
    // Infinite reversed Z: depth = near / -z_view.
    double f = 1.0 / std::tan(c.fov_y_deg * std::numbers::pi / 360.0);
    p[0] = f / aspect;
    p[5] = f;
    p[14] = c.near;  // z' = near
    p[11] = -1;      // w' = -z
  } else {
    p[0] = 2.0 / c.ortho_w;
    p[5] = 2.0 / c.ortho_h;
    // depth 1 at the eye plane, 0 at depth_range in front of it
    p[10] = 1.0 / c.depth_range;
    p[14] = 1.0;
    p[15] = 1;
  }
  return p;
}

}  // namespace detail

Camera topdown_camera(const Extent& e, double zmin, double zmax) {
  Camera c;
  c.projection = Projection::orthographic;
  double cx = 0.5 * (e.xmin + e.xmax), cy = 0.5 * (e.ymin + e.ymax);
  double top = zmax + std::max(100.0, 0.1 * (zmax - zmin));
  c.eye = {cx, cy, top};
  c.target = {cx, cy, zmin - 1};
  c.up = {0, 1, 0};
  c.ortho_w = e.xmax - e.xmin;
  c.ortho_h = e.ymax - e.ymin;
  c.depth_range = (top - zmin) + 1000.0;
  c.topdown_extent = e;
  return c;
}

Camera fit_camera(const Extent& e, double zmin, double zmax, uint32_t width, uint32_t height,
                  Projection projection, double pitch_deg) {
  Camera c;
  c.projection = projection;
  double cx = 0.5 * (e.xmin + e.xmax), cy = 0.5 * (e.ymin + e.ymax), cz = 0.5 * (zmin + zmax);
  double w = e.xmax - e.xmin, h = e.ymax - e.ymin;
  double radius = 0.5 * std::sqrt(w * w + h * h + (zmax - zmin) * (zmax - zmin));
  double aspect = double(width) / double(height);
  double pitch = pitch_deg * std::numbers::pi / 180.0;
  double half_fov = c.fov_y_deg * std::numbers::pi / 360.0;
  // Distance at which a sphere around the extent fits the narrower angle.
  double half = std::min(half_fov, std::atan(std::tan(half_fov) * aspect));
  double dist = radius / std::sin(half);
  c.target = {cx, cy, cz};
  c.up = {0, 0, 1};
  auto place = [&](double r) { c.eye = {cx, cy - r * std::cos(pitch), cz + r * std::sin(pitch)}; };
  // Perspective: the nearest distance (bisection) at which all eight corners
  // of the extent box project inside the image; the enclosing sphere above
  // is the safe upper bound.
  if (projection == Projection::perspective) {
    auto fits = [&](double r) {
      place(r);
      c.near = std::max(0.1, r * 1e-3);
      const detail::Mat4 m =
          detail::mat_mul(detail::projection_matrix(c, aspect), detail::view_matrix(c, c.eye));
      for (int k = 0; k < 8; ++k) {
        const double x = k & 1 ? e.xmax : e.xmin, y = k & 2 ? e.ymax : e.ymin,
                     z = k & 4 ? zmax : zmin;
        double v[4] = {0, 0, 0, 0};
        for (int row = 0; row < 4; ++row)
          v[row] = m[row] * x + m[4 + row] * y + m[8 + row] * z + m[12 + row];
        if (v[3] <= 0 || std::abs(v[0] / v[3]) > 1 || std::abs(v[1] / v[3]) > 1) return false;
      }
      return true;
    };
    double lo = 0.05 * dist, hi = dist;
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      (fits(mid) ? hi : lo) = mid;
    }
    dist = hi * 1.02;
  }
  place(dist);
  c.near = std::max(0.1, dist - 2 * radius) * 0.5;
  c.ortho_h = 2 * radius;
  c.ortho_w = 2 * radius * aspect;
  c.depth_range = dist + 2 * radius;
  return c;
}

bool is_topdown(const Camera& c, uint32_t, uint32_t, Extent* extent) {
  if (c.projection != Projection::orthographic) return false;
  detail::Basis b = detail::camera_basis(c);
  if (!(std::abs(b.forward[2] + 1) < 1e-12 && std::abs(b.right[0] - 1) < 1e-12 &&
        std::abs(b.up[1] - 1) < 1e-12))
    return false;
  if (extent && c.topdown_extent) {
    *extent = *c.topdown_extent;
  } else if (extent) {
    extent->xmin = c.eye[0] - 0.5 * c.ortho_w;
    extent->xmax = c.eye[0] + 0.5 * c.ortho_w;
    extent->ymin = c.eye[1] - 0.5 * c.ortho_h;
    extent->ymax = c.eye[1] + 0.5 * c.ortho_h;
  }
  return true;
}

std::optional<Extent> ground_footprint(const Camera& c, uint32_t width, uint32_t height,
                                       double zmin, double zmax) {
  Extent top;
  if (is_topdown(c, width, height, &top)) return top;
  const detail::PixelRays rays(c, width, height);
  Extent b{INFINITY, INFINITY, -INFINITY, -INFINITY};
  // The image's corner rays on the slab zmin..zmax: a plane's view through
  // a rectangle is a convex quadrilateral, so its corners bound it.
  for (double nx : {-1.0, 1.0})
    for (double ny : {-1.0, 1.0}) {
      Vec3 o, d;
      rays.ray(nx, ny, o, d);
      if (!(d[2] < 0)) return std::nullopt;  // a corner sees the sky: no bound
      if (o[2] < zmax)  // inside the slab: the ray starts on the terrain's heights
        b = {std::min(b.xmin, o[0]), std::min(b.ymin, o[1]), std::max(b.xmax, o[0]),
             std::max(b.ymax, o[1])};
      for (double z : {zmin, zmax}) {
        const double t = (z - o[2]) / d[2];
        if (!(t > 0)) continue;  // the eye is below this plane
        const double x = o[0] + t * d[0], y = o[1] + t * d[1];
        b = {std::min(b.xmin, x), std::min(b.ymin, y), std::max(b.xmax, x), std::max(b.ymax, y)};
      }
    }
  if (!(b.xmax >= b.xmin)) return std::nullopt;
  return b;
}

double pixel_ground_size(const Camera& c, uint32_t width, uint32_t height, const Vec3& p) {
  if (c.projection == Projection::orthographic)
    return std::min(c.ortho_w / double(width), c.ortho_h / double(height));
  const double d = std::hypot(p[0] - c.eye[0], p[1] - c.eye[1], p[2] - c.eye[2]);
  return d * 2 * std::tan(c.fov_y_deg * std::numbers::pi / 360.0) / double(height);
}

}  // namespace prep::render
