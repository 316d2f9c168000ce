// Terrain heightfield: the mesh of the DEM surface (prep/dem.hpp) that the GL
// path rasterises and the CPU path ray-casts, and --extent-crs transforms.
#include <ogr_spatialref.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>

#include "detail/math.hpp"
#include "prep/dem.hpp"
#include "prep/error.hpp"

namespace prep::render {

using detail::cross;
using detail::dot;
using detail::sub;

Heightfield flat_heightfield(const Extent& e) {
  Heightfield h;
  h.nx = h.ny = 2;
  h.x0 = e.xmin;
  h.y0 = e.ymin;
  h.dx = e.xmax - e.xmin;
  h.dy = e.ymax - e.ymin;
  h.z.assign(4, 0.0);
  return h;
}

namespace {

// Nodes base + k * step, k = k0 .. k0 + n - 1, covering [lo, hi].
struct AxisNodes {
  double first = 0, step = 1;
  uint32_t n = 2;
};

AxisNodes lattice_axis(double lo, double hi, double base, double step) {
  const double k0 = std::floor((lo - base) / step), k1 = std::ceil((hi - base) / step);
  AxisNodes a;
  a.first = base + k0 * step;
  a.step = step;
  a.n = uint32_t(std::max(2.0, std::min(k1 - k0 + 1, 1e9)));
  return a;
}

}  // namespace

Heightfield load_heightfield(const DemSpec& spec, const SceneFrame& frame, const Extent& e,
                             uint32_t max_samples) {
  max_samples = std::max<uint32_t>(max_samples, 2);
  DemSampler dem(spec, frame);
  // The DEM window under the extent: its boundary, densely sampled.
  auto pixel_box = [&](const std::vector<Point2>& scene, double box[4]) {
    std::vector<Point2> px(scene.size());
    dem.to_pixel(scene, px);
    for (const Point2& p : px) {
      box[0] = std::min(box[0], p.x);
      box[1] = std::min(box[1], p.y);
      box[2] = std::max(box[2], p.x);
      box[3] = std::max(box[3], p.y);
    }
  };
  constexpr double inf = std::numeric_limits<double>::infinity();
  double box[4] = {inf, inf, -inf, -inf};
  {
    std::vector<Point2> edge;
    for (int k = 0; k <= 20; ++k) {
      const double t = k / 20.0, x = e.xmin + t * (e.xmax - e.xmin),
                   y = e.ymin + t * (e.ymax - e.ymin);
      edge.insert(edge.end(), {{x, e.ymin}, {x, e.ymax}, {e.xmin, y}, {e.xmax, y}});
    }
    pixel_box(edge, box);
  }
  dem.load(box[0], box[1], box[2], box[3]);

  // Splits per DEM cell that keep the triangles within kMeshTolerance of the
  // bilinear surface (prep/dem.hpp: twist / (4 s^2)).
  const double twist = dem.max_twist();
  const uint32_t splits =
      twist > 4 * kMeshTolerance
          ? uint32_t(std::min(1e4, std::ceil(std::sqrt(twist / (4 * kMeshTolerance)))))
          : 1u;
  Heightfield h;
  h.surface_error_bound = inf;
  if (const std::optional<DemLattice> lat = dem.lattice()) {
    // Vertices on the lattice: every cell split s times per axis, fewer when
    // max_samples says so; decimated lattice lines when even s = 1 is too fine.
    auto axis = [&](double lo, double hi, double base, double cell, uint32_t& s) {
      for (s = splits; s > 1; --s) {
        const AxisNodes a = lattice_axis(lo, hi, base, cell / s);
        if (a.n <= max_samples) return a;
      }
      AxisNodes a = lattice_axis(lo, hi, base, cell);
      if (a.n <= max_samples) return a;
      for (double m = std::ceil(double(a.n) / double(max_samples - 1)); a.n > max_samples; ++m)
        a = lattice_axis(lo, hi, base, cell * m);
      return a;
    };
    uint32_t sx = 1, sy = 1;
    const AxisNodes ax = axis(e.xmin, e.xmax, lat->x0, std::abs(lat->dx), sx);
    const AxisNodes ay = axis(e.ymin, e.ymax, lat->y0, std::abs(lat->dy), sy);
    h.x0 = ax.first;
    h.dx = ax.step;
    h.nx = ax.n;
    h.y0 = ay.first;
    h.dy = ay.step;
    h.ny = ay.n;
    if (ax.step <= std::abs(lat->dx) * (1 + 1e-12) && ay.step <= std::abs(lat->dy) * (1 + 1e-12))
      h.surface_error_bound = -1;  // set below from the window's twist
  } else {
    // The frame grid at the spacing of the DEM cell near the centre. Its
    // vertices are surface heights, but the lattice's edges (where the
    // bilinear surface bends) run across its triangles, so no split count
    // gives a bound; finer grids would only cost ray-casting time.
    const double cell = dem.cell_size_metres({0.5 * (e.xmin + e.xmax), 0.5 * (e.ymin + e.ymax)});
    const double step = cell > 0 && std::isfinite(cell) ? cell : 30.0;
    h.nx = std::clamp<uint32_t>(uint32_t(std::min(std::ceil((e.xmax - e.xmin) / step), 1e9)) + 1, 2,
                                max_samples);
    h.ny = std::clamp<uint32_t>(uint32_t(std::min(std::ceil((e.ymax - e.ymin) / step), 1e9)) + 1, 2,
                                max_samples);
    h.x0 = e.xmin;
    h.y0 = e.ymin;
    h.dx = (e.xmax - e.xmin) / (h.nx - 1);
    h.dy = (e.ymax - e.ymin) / (h.ny - 1);
  }
  std::vector<Point2> nodes(size_t(h.nx) * h.ny), px(nodes.size());
  for (uint32_t j = 0; j < h.ny; ++j)
    for (uint32_t i = 0; i < h.nx; ++i)
      nodes[i + size_t(h.nx) * j] = {h.x0 + i * h.dx, h.y0 + j * h.dy};
  dem.to_pixel(nodes, px);
  // Vertices beyond the window read (the lattice overhangs the extent by up
  // to a step): read again with them, so that every vertex sees its cells.
  double nbox[4] = {box[0], box[1], box[2], box[3]};
  for (const Point2& p : px) {
    nbox[0] = std::min(nbox[0], p.x);
    nbox[1] = std::min(nbox[1], p.y);
    nbox[2] = std::max(nbox[2], p.x);
    nbox[3] = std::max(nbox[3], p.y);
  }
  if (nbox[0] < box[0] || nbox[1] < box[1] || nbox[2] > box[2] || nbox[3] > box[3])
    dem.load(nbox[0], nbox[1], nbox[2], nbox[3]);
  if (h.surface_error_bound < 0) {
    const double sx = std::abs(h.dx) > 0 ? std::round(std::abs(dem.lattice()->dx) / h.dx) : 1;
    const double sy = std::abs(h.dy) > 0 ? std::round(std::abs(dem.lattice()->dy) / h.dy) : 1;
    h.surface_error_bound = dem.max_twist() / (4 * sx * sy);
  }
  h.z.resize(nodes.size());
  h.zmin = std::numeric_limits<double>::max();
  h.zmax = std::numeric_limits<double>::lowest();
  for (size_t k = 0; k < nodes.size(); ++k) {
    h.z[k] = dem.height(px[k].x, px[k].y);
    h.zmin = std::min(h.zmin, h.z[k]);
    h.zmax = std::max(h.zmax, h.z[k]);
  }
  return h;
}

namespace {

// A recorded relative path resolved against `dir` (the package's folder).
std::string resolve_recorded(const std::string& path, const std::string& dir) {
  if (path.empty() || dir.empty() || path.find("://") != std::string::npos) return path;
  std::string prefix, rest = path;
  for (std::string_view p : {"/vsizip/", "/vsigzip/", "/vsitar/", "/vsi7z/"})
    if (path.rfind(p, 0) == 0) prefix = p;
  if (!prefix.empty()) rest = path.substr(prefix.size());
  if (rest.empty() || rest[0] == '/' || rest[0] == '{') return path;
  const auto colon = rest.find(':');
  if (colon != std::string::npos && colon > 1 && rest.find('/') > colon) return path;  // "PG:..."
  return prefix + (std::filesystem::path(dir) / rest).lexically_normal().string();
}

}  // namespace

DemSpec recorded_dem(const std::string& metadata_json, const std::string& package_path) {
  DemSpec spec;
  const auto meta = nlohmann::json::parse(metadata_json, nullptr, /*allow_exceptions=*/false);
  if (!meta.is_object() || !meta.contains("build_options") || !meta["build_options"].is_object())
    return spec;
  const auto& bo = meta["build_options"];
  const std::string dir = package_path.empty()
                              ? std::string()
                              : std::filesystem::path(package_path).parent_path().string();
  // One path, or a mosaic's list of them (each resolved alike); a list that
  // is not all strings records no DEM, as any other value does.
  std::vector<std::string> paths;
  if (bo.contains("dem") && bo["dem"].is_string()) paths.push_back(bo["dem"].get<std::string>());
  if (bo.contains("dem") && bo["dem"].is_array() &&
      std::all_of(bo["dem"].begin(), bo["dem"].end(), [](const auto& p) { return p.is_string(); }))
    for (const auto& p : bo["dem"]) paths.push_back(p.get<std::string>());
  if (!paths.empty()) {
    spec.path = resolve_recorded(paths[0], dir);
    for (size_t i = 1; i < paths.size(); ++i)
      spec.more_paths.push_back(resolve_recorded(paths[i], dir));
  }
  // A path from the package, not from the user (prep/dem.hpp).
  spec.named_by_package = true;
  if (bo.contains("dem_assume_crs") && bo["dem_assume_crs"].is_string())
    spec.assume_crs = bo["dem_assume_crs"].get<std::string>();
  if (bo.contains("z_scale") && bo["z_scale"].is_number())
    spec.z_scale = bo["z_scale"].get<double>();
  if (bo.contains("nodata_fill") && bo["nodata_fill"].is_number())
    spec.nodata_fill = bo["nodata_fill"].get<double>();
  return spec;
}

double Heightfield::height_at(double x, double y) const {
  const double fx = (x - x0) / dx, fy = (y - y0) / dy;
  if (!(fx >= 0 && fy >= 0 && fx <= nx - 1 && fy <= ny - 1))
    return std::numeric_limits<double>::quiet_NaN();
  const uint32_t i = std::min(uint32_t(fx), nx - 2), j = std::min(uint32_t(fy), ny - 2);
  const double u = fx - i, v = fy - j;
  auto at = [&](uint32_t a, uint32_t b) { return z[a + size_t(nx) * b]; };
  const double z00 = at(i, j), z10 = at(i + 1, j), z01 = at(i, j + 1), z11 = at(i + 1, j + 1);
  // Triangles (00, 10, 11) below the diagonal u = v, (00, 11, 01) above it.
  if (u >= v) return z00 + u * (z10 - z00) + v * (z11 - z10);
  return z00 + v * (z01 - z00) + u * (z11 - z01);
}

std::array<double, 2> Heightfield::triangle_gradient(uint32_t i, uint32_t j, bool upper) const {
  auto at = [&](uint32_t a, uint32_t b) { return z[a + size_t(nx) * b]; };
  const double z00 = at(i, j), z10 = at(i + 1, j), z01 = at(i, j + 1), z11 = at(i + 1, j + 1);
  // As height_at: z00 + u (z10 - z00) + v (z11 - z10) below the diagonal,
  // z00 + v (z01 - z00) + u (z11 - z01) above it.
  if (!upper) return {(z10 - z00) / dx, (z11 - z10) / dy};
  return {(z11 - z01) / dx, (z01 - z00) / dy};
}

std::array<double, 2> Heightfield::gradient_at(double x, double y) const {
  const double fx = (x - x0) / dx, fy = (y - y0) / dy;
  if (!(fx >= 0 && fy >= 0 && fx <= nx - 1 && fy <= ny - 1)) return {0, 0};
  const uint32_t i = std::min(uint32_t(fx), nx - 2), j = std::min(uint32_t(fy), ny - 2);
  return triangle_gradient(i, j, fx - i < fy - j);
}

Vec3 Heightfield::normal_at(uint32_t i, uint32_t j) const {
  auto zat = [&](int a, int b) {
    a = std::clamp(a, 0, int(nx) - 1);
    b = std::clamp(b, 0, int(ny) - 1);
    return z[size_t(a) + size_t(nx) * b];
  };
  double gx = (zat(int(i) + 1, int(j)) - zat(int(i) - 1, int(j))) / (2 * dx);
  double gy = (zat(int(i), int(j) + 1) - zat(int(i), int(j) - 1)) / (2 * dy);
  return detail::normalize({-gx, -gy, 1.0});
}

namespace {

// Möller–Trumbore, double precision; returns t > 0 or -1.
double ray_triangle(const Vec3& o, const Vec3& d, const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec3 e1 = sub(b, a), e2 = sub(c, a), pv = cross(d, e2);
  double det = dot(e1, pv);
  if (std::abs(det) < 1e-300) return -1;
  double inv = 1.0 / det;
  Vec3 tv = sub(o, a);
  double u = dot(tv, pv) * inv;
  if (u < -1e-12 || u > 1 + 1e-12) return -1;
  Vec3 qv = cross(tv, e1);
  double v = dot(d, qv) * inv;
  if (v < -1e-12 || u + v > 1 + 1e-12) return -1;
  double t = dot(e2, qv) * inv;
  return t > 0 ? t : -1;
}

}  // namespace

std::optional<double> Heightfield::intersect(const Vec3& o, const Vec3& d) const {
  // 2D DDA over the mesh cells along the ray's ground track (Amanatides & Woo),
  // testing the two triangles of each cell; the first hit is the nearest.
  const double xmax = x0 + dx * (nx - 1), ymax = y0 + dy * (ny - 1);
  double t0 = 0, t1 = std::numeric_limits<double>::max();
  const double lo[2] = {x0, y0}, hi[2] = {xmax, ymax};
  for (int k = 0; k < 2; ++k) {
    if (std::abs(d[k]) < 1e-300) {
      if (o[k] < lo[k] || o[k] > hi[k]) return std::nullopt;
    } else {
      double ta = (lo[k] - o[k]) / d[k], tb = (hi[k] - o[k]) / d[k];
      if (ta > tb) std::swap(ta, tb);
      t0 = std::max(t0, ta);
      t1 = std::min(t1, tb);
    }
  }
  if (t0 > t1) return std::nullopt;
  double sx = o[0] + t0 * d[0], sy = o[1] + t0 * d[1];
  int i = std::clamp(int(std::floor((sx - x0) / dx)), 0, int(nx) - 2);
  int j = std::clamp(int(std::floor((sy - y0) / dy)), 0, int(ny) - 2);
  const int step_i = d[0] > 0 ? 1 : -1, step_j = d[1] > 0 ? 1 : -1;
  auto next_boundary = [&](int idx, int step, double origin, double cellsz, double dir, double o0) {
    if (std::abs(dir) < 1e-300) return std::numeric_limits<double>::max();
    double edge = origin + (idx + (step > 0 ? 1 : 0)) * cellsz;
    return (edge - o0) / dir;
  };
  double tx = next_boundary(i, step_i, x0, dx, d[0], o[0]);
  double ty = next_boundary(j, step_j, y0, dy, d[1], o[1]);
  const double dtx =
      std::abs(d[0]) < 1e-300 ? std::numeric_limits<double>::max() : dx / std::abs(d[0]);
  const double dty =
      std::abs(d[1]) < 1e-300 ? std::numeric_limits<double>::max() : dy / std::abs(d[1]);
  auto P = [&](int a, int b) -> Vec3 {
    return {x0 + a * dx, y0 + b * dy, z[size_t(a) + size_t(nx) * b]};
  };
  for (int guard = 0; guard < int(nx + ny) + 4; ++guard) {
    Vec3 p00 = P(i, j), p10 = P(i + 1, j), p11 = P(i + 1, j + 1), p01 = P(i, j + 1);
    double ta = ray_triangle(o, d, p00, p10, p11), tb = ray_triangle(o, d, p00, p11, p01);
    double best = -1;
    if (ta > 0) best = ta;
    if (tb > 0 && (best < 0 || tb < best)) best = tb;
    if (best > 0) return best;
    if (tx < ty) {
      i += step_i;
      tx += dtx;
    } else {
      j += step_j;
      ty += dty;
    }
    if (i < 0 || j < 0 || i > int(nx) - 2 || j > int(ny) - 2) break;
  }
  return std::nullopt;
}

}  // namespace prep::render
