// Terrain heightfield: DEM sampling in the scene frame and ray casting of the
// mesh the GL path rasterises (the CPU path's terrain).
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "detail/math.hpp"
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

Heightfield load_heightfield(const std::string& dem, const SceneFrame& frame, const Extent& e,
                             uint32_t max_samples, double z_scale) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(dem.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!ds) throw input_error("render: DEM '" + dem + "' cannot be opened: " + CPLGetLastErrorMsg());
  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None || gt[2] != 0 || gt[4] != 0)
    throw input_error("render: DEM '" + dem + "' has no north-up geotransform");
  OGRSpatialReference dem_srs, scene_srs;
  if (const OGRSpatialReference* s = ds->GetSpatialRef()) dem_srs = *s;
  else dem_srs.importFromEPSG(4326);
  dem_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  if (scene_srs.importFromWkt(frame.crs_wkt.c_str()) != OGRERR_NONE)
    throw input_error("render: package frame CRS cannot be parsed for DEM '" + dem + "'");
  scene_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&scene_srs, &dem_srs));
  if (!ct) throw input_error("render: no transformation from the scene frame to the CRS of DEM '" + dem + "'");

  GDALRasterBand* band = ds->GetRasterBand(1);
  const int W = ds->GetRasterXSize(), H = ds->GetRasterYSize();
  int has_nodata = 0;
  double nodata = band->GetNoDataValue(&has_nodata);

  // Grid in the scene frame: spacing about the DEM cell size there.
  double cx = 0.5 * (e.xmin + e.xmax), cy = 0.5 * (e.ymin + e.ymax);
  double px = cx + frame.origin_x, py = cy + frame.origin_y, qx = px + 1.0, qy = py;
  double cell = 30.0;
  if (ct->Transform(1, &px, &py) && ct->Transform(1, &qx, &qy)) {
    double per_metre = std::hypot(qx - px, qy - py);  // DEM units per scene metre
    if (per_metre > 0) cell = std::abs(gt[1]) / per_metre;
  }
  Heightfield h;
  h.nx = std::clamp<uint32_t>(uint32_t(std::ceil((e.xmax - e.xmin) / cell)) + 1, 2, max_samples);
  h.ny = std::clamp<uint32_t>(uint32_t(std::ceil((e.ymax - e.ymin) / cell)) + 1, 2, max_samples);
  h.x0 = e.xmin;
  h.y0 = e.ymin;
  h.dx = (e.xmax - e.xmin) / (h.nx - 1);
  h.dy = (e.ymax - e.ymin) / (h.ny - 1);
  std::vector<double> xs(size_t(h.nx) * h.ny), ys(xs.size());
  for (uint32_t j = 0; j < h.ny; ++j)
    for (uint32_t i = 0; i < h.nx; ++i) {
      xs[i + size_t(h.nx) * j] = frame.origin_x + h.x0 + i * h.dx;
      ys[i + size_t(h.nx) * j] = frame.origin_y + h.y0 + j * h.dy;
    }
  std::vector<int> ok(xs.size());
  ct->Transform(xs.size(), xs.data(), ys.data(), nullptr, ok.data());
  // Read the DEM window the samples need.
  double cmin = 1e300, cmax = -1e300, rmin = 1e300, rmax = -1e300;
  for (size_t k = 0; k < xs.size(); ++k) {
    if (!ok[k]) continue;
    double c = (xs[k] - gt[0]) / gt[1] - 0.5, r = (ys[k] - gt[3]) / gt[5] - 0.5;
    xs[k] = c;
    ys[k] = r;
    cmin = std::min(cmin, c); cmax = std::max(cmax, c); rmin = std::min(rmin, r); rmax = std::max(rmax, r);
  }
  int c0 = std::clamp(int(std::floor(cmin)), 0, W - 1), c1 = std::clamp(int(std::floor(cmax)) + 1, 0, W - 1);
  int r0 = std::clamp(int(std::floor(rmin)), 0, H - 1), r1 = std::clamp(int(std::floor(rmax)) + 1, 0, H - 1);
  int ww = c1 - c0 + 1, wh = r1 - r0 + 1;
  std::vector<double> win(size_t(ww) * wh);
  if (band->RasterIO(GF_Read, c0, r0, ww, wh, win.data(), ww, wh, GDT_Float64, 0, 0) != CE_None)
    throw input_error("render: DEM '" + dem + "' cannot be read: " + CPLGetLastErrorMsg());
  auto at = [&](int c, int r) {
    c = std::clamp(c, c0, c1) - c0;
    r = std::clamp(r, r0, r1) - r0;
    double v = win[size_t(c) + size_t(ww) * r];
    return (has_nodata && v == nodata) || std::isnan(v) ? 0.0 : v;
  };
  h.z.resize(xs.size());
  h.zmin = std::numeric_limits<double>::max();
  h.zmax = std::numeric_limits<double>::lowest();
  for (size_t k = 0; k < xs.size(); ++k) {
    double z = 0;
    if (ok[k] && xs[k] > -1 && xs[k] < W && ys[k] > -1 && ys[k] < H) {
      // Bilinear between pixel centres.
      int ci = int(std::floor(xs[k])), ri = int(std::floor(ys[k]));
      double fx = xs[k] - ci, fy = ys[k] - ri;
      z = (1 - fy) * ((1 - fx) * at(ci, ri) + fx * at(ci + 1, ri)) + fy * ((1 - fx) * at(ci, ri + 1) + fx * at(ci + 1, ri + 1));
    }
    h.z[k] = z * z_scale;
    h.zmin = std::min(h.zmin, h.z[k]);
    h.zmax = std::max(h.zmax, h.z[k]);
  }
  return h;
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
  const double dtx = std::abs(d[0]) < 1e-300 ? std::numeric_limits<double>::max() : dx / std::abs(d[0]);
  const double dty = std::abs(d[1]) < 1e-300 ? std::numeric_limits<double>::max() : dy / std::abs(d[1]);
  auto P = [&](int a, int b) -> Vec3 { return {x0 + a * dx, y0 + b * dy, z[size_t(a) + size_t(nx) * b]}; };
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
