// DEM access through GDAL: open, transform scene points to pixel space,
// read the used window, fill no-data, bilinear sampling (GDAL's kernel).
#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <sstream>

#include "prep/error.hpp"
#include "prep/terrain.hpp"

namespace prep {
namespace {

struct TransformDeleter {
  void operator()(OGRCoordinateTransformation* t) const { OGRCoordinateTransformation::DestroyCT(t); }
};
using TransformPtr = std::unique_ptr<OGRCoordinateTransformation, TransformDeleter>;

std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace

struct DemSampler::Impl {
  std::string path;
  GDALDatasetUniquePtr ds;
  GDALRasterBand* band = nullptr;
  int width = 0, height = 0;
  double gt[6] = {0, 1, 0, 0, 0, 1};
  double inv_gt[6] = {0, 1, 0, 0, 0, 1};
  double origin_x = 0, origin_y = 0;
  OGRSpatialReference scene_srs, dem_srs;
  bool same_crs = true;
  double z_scale = 1, scale = 1, offset = 0, unit = 1;
  std::optional<double> nodata_fill;
  bool has_nodata = false;
  double nodata = 0;
  // The window read: cells [wx0, wx0 + ww) x [wy0, wy0 + wh).
  int wx0 = 0, wy0 = 0, ww = 0, wh = 0;
  std::vector<double> z;
  std::vector<uint8_t> filled;
  TerrainStats stats;
  mutable tbb::enumerable_thread_specific<TransformPtr> forward, inverse;

  TransformPtr make(bool to_dem) const {
    if (same_crs) return nullptr;
    OGRCoordinateTransformation* t = to_dem ? OGRCreateCoordinateTransformation(&scene_srs, &dem_srs)
                                            : OGRCreateCoordinateTransformation(&dem_srs, &scene_srs);
    if (!t)
      throw gdal_error("terrain: " + path + ": cannot transform between the scene CRS and the DEM CRS: " +
                       CPLGetLastErrorMsg());
    return TransformPtr(t);
  }
  OGRCoordinateTransformation* fwd() const {
    auto& t = forward.local();
    if (!t && !same_crs) t = make(true);
    return t.get();
  }
  OGRCoordinateTransformation* inv() const {
    auto& t = inverse.local();
    if (!t && !same_crs) t = make(false);
    return t.get();
  }
  double cell(int i, int j) const { return z[static_cast<size_t>(j - wy0) * ww + (i - wx0)]; }
  bool cell_filled(int i, int j) const { return filled[static_cast<size_t>(j - wy0) * ww + (i - wx0)]; }
};

DemSampler::DemSampler(const std::string& path, const SceneFrame& frame, double z_scale,
                       std::optional<double> nodata_fill)
    : impl_(std::make_unique<Impl>()) {
  GDALAllRegister();
  Impl& m = *impl_;
  m.path = path;
  m.z_scale = z_scale;
  m.nodata_fill = nodata_fill;
  m.origin_x = frame.origin_x;
  m.origin_y = frame.origin_y;
  m.ds.reset(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (!m.ds) throw gdal_error("terrain: " + path + ": cannot open DEM: " + CPLGetLastErrorMsg());
  if (m.ds->GetRasterCount() < 1) throw gdal_error("terrain: " + path + ": DEM has no raster band");
  m.band = m.ds->GetRasterBand(1);
  m.width = m.ds->GetRasterXSize();
  m.height = m.ds->GetRasterYSize();
  if (m.ds->GetGeoTransform(m.gt) != CE_None)
    throw gdal_error("terrain: " + path + ": DEM has no geotransform");
  if (!GDALInvGeoTransform(m.gt, m.inv_gt))
    throw gdal_error("terrain: " + path + ": DEM geotransform is not invertible");
  int ok = 0;
  m.scale = m.band->GetScale(&ok);
  if (!ok) m.scale = 1;
  m.offset = m.band->GetOffset(&ok);
  if (!ok) m.offset = 0;
  const std::string unit = lower(m.band->GetUnitType() ? m.band->GetUnitType() : "");
  if (unit == "ft" || unit == "foot" || unit == "feet" || unit == "international foot") m.unit = 0.3048;
  if (unit == "us-ft" || unit == "us survey foot" || unit == "ftus") m.unit = 1200.0 / 3937.0;
  m.nodata = m.band->GetNoDataValue(&ok);
  m.has_nodata = ok != 0;

  const OGRSpatialReference* dem_srs = m.ds->GetSpatialRef();
  if (!frame.crs_wkt.empty()) {
    if (!dem_srs) throw gdal_error("terrain: " + path + ": DEM has no CRS but the scene has one");
    m.dem_srs = *dem_srs;
    if (m.scene_srs.importFromWkt(frame.crs_wkt.c_str()) != OGRERR_NONE)
      throw gdal_error("terrain: " + path + ": the scene CRS WKT cannot be read");
    m.scene_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    m.dem_srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    m.same_crs = m.scene_srs.IsSame(&m.dem_srs) != 0;
    (void)m.fwd();  // fail early when PROJ cannot make the transformation
  }
  std::ostringstream d;
  d << "DEM " << path << " (" << m.ds->GetDriver()->GetDescription() << ", " << m.width << "x"
    << m.height << ", CRS " << (dem_srs && dem_srs->GetName() ? dem_srs->GetName() : "none")
    << (m.same_crs ? ", same as scene" : ", points transformed") << ", unit '" << unit
    << "' x" << m.unit << ", scale " << m.scale << ", offset " << m.offset << ", z-scale "
    << z_scale << ")";
  m.stats.description = d.str();
  m.stats.fill_policy =
      nodata_fill ? "value " + std::to_string(*nodata_fill) : std::string("nearest valid cell");
}

DemSampler::~DemSampler() = default;

void DemSampler::to_pixel(std::span<const Point2> scene, std::span<Point2> pixel) const {
  const Impl& m = *impl_;
  std::vector<double> xs(scene.size()), ys(scene.size());
  for (size_t i = 0; i < scene.size(); ++i) {
    xs[i] = scene[i].x + m.origin_x;
    ys[i] = scene[i].y + m.origin_y;
  }
  if (auto* t = m.fwd(); t && !scene.empty()) {
    std::vector<int> ok(scene.size(), 0);
    if (!t->Transform(static_cast<int>(scene.size()), xs.data(), ys.data(), nullptr, ok.data()))
      for (size_t i = 0; i < scene.size(); ++i)
        if (!ok[i])
          throw gdal_error("terrain: " + m.path + ": cannot transform scene point (" +
                           std::to_string(scene[i].x) + ", " + std::to_string(scene[i].y) +
                           ") to the DEM CRS");
  }
  for (size_t i = 0; i < scene.size(); ++i) {
    pixel[i].x = m.inv_gt[0] + m.inv_gt[1] * xs[i] + m.inv_gt[2] * ys[i];
    pixel[i].y = m.inv_gt[3] + m.inv_gt[4] * xs[i] + m.inv_gt[5] * ys[i];
  }
}

Point2 DemSampler::to_pixel(Point2 scene) const {
  Point2 out;
  to_pixel(std::span<const Point2>(&scene, 1), std::span<Point2>(&out, 1));
  return out;
}

double DemSampler::cell_size_metres(Point2 p) const {
  const Impl& m = *impl_;
  const Point2 c = to_pixel(p);
  // Scene positions of the cell's edge midpoints around c.
  double px[4] = {c.x - 0.5, c.x + 0.5, c.x, c.x};
  double py[4] = {c.y, c.y, c.y - 0.5, c.y + 0.5};
  double xs[4], ys[4];
  for (int i = 0; i < 4; ++i) {
    xs[i] = m.gt[0] + m.gt[1] * px[i] + m.gt[2] * py[i];
    ys[i] = m.gt[3] + m.gt[4] * px[i] + m.gt[5] * py[i];
  }
  if (auto* t = m.inv()) {
    int ok[4] = {0, 0, 0, 0};
    if (!t->Transform(4, xs, ys, nullptr, ok))
      throw gdal_error("terrain: " + m.path + ": cannot transform DEM cell corners to the scene CRS");
  }
  const double w = std::hypot(xs[1] - xs[0], ys[1] - ys[0]);
  const double h = std::hypot(xs[3] - xs[2], ys[3] - ys[2]);
  return std::min(w, h);
}

void DemSampler::load(double px0, double py0, double px1, double py1) {
  Impl& m = *impl_;
  constexpr int kMargin = 16;
  auto clampi = [](double v, int lo, int hi) {
    if (!(v > lo)) return lo;  // NaN too
    if (v > hi) return hi;
    return static_cast<int>(v);
  };
  const int x0 = clampi(std::floor(px0) - kMargin, 0, m.width - 1);
  const int x1 = clampi(std::ceil(px1) + kMargin, 0, m.width - 1);
  const int y0 = clampi(std::floor(py0) - kMargin, 0, m.height - 1);
  const int y1 = clampi(std::ceil(py1) + kMargin, 0, m.height - 1);
  m.wx0 = x0;
  m.wy0 = y0;
  m.ww = x1 - x0 + 1;
  m.wh = y1 - y0 + 1;
  const size_t n = static_cast<size_t>(m.ww) * m.wh;
  m.z.assign(n, 0.0);
  m.filled.assign(n, 0);
  if (m.band->RasterIO(GF_Read, x0, y0, m.ww, m.wh, m.z.data(), m.ww, m.wh, GDT_Float64, 0, 0,
                       nullptr) != CE_None)
    throw gdal_error("terrain: " + m.path + ": cannot read DEM window: " + CPLGetLastErrorMsg());

  // No-data policy (documented in terrain.hpp).
  std::deque<size_t> queue;
  for (size_t i = 0; i < n; ++i) {
    const bool invalid = std::isnan(m.z[i]) || (m.has_nodata && m.z[i] == m.nodata);
    if (invalid) {
      m.filled[i] = 1;
      if (m.nodata_fill) m.z[i] = *m.nodata_fill;
    } else {
      queue.push_back(i);
    }
  }
  const uint64_t invalid_count = static_cast<uint64_t>(std::count(m.filled.begin(), m.filled.end(), 1));
  if (!m.nodata_fill && invalid_count > 0) {
    if (queue.empty()) {
      std::fill(m.z.begin(), m.z.end(), 0.0);  // no valid cell at all: flat
    } else {
      std::vector<uint8_t> done(n, 0);
      for (size_t i : queue) done[i] = 1;
      while (!queue.empty()) {
        const size_t i = queue.front();
        queue.pop_front();
        const int ix = static_cast<int>(i % m.ww), iy = static_cast<int>(i / m.ww);
        for (int dy = -1; dy <= 1; ++dy)
          for (int dx = -1; dx <= 1; ++dx) {
            const int jx = ix + dx, jy = iy + dy;
            if (jx < 0 || jy < 0 || jx >= m.ww || jy >= m.wh) continue;
            const size_t j = static_cast<size_t>(jy) * m.ww + jx;
            if (done[j]) continue;
            done[j] = 1;
            m.z[j] = m.z[i];
            queue.push_back(j);
          }
      }
    }
  }
  const double k = m.unit * m.z_scale;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (auto& v : m.z) {
    v = (v * m.scale + m.offset) * k;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  m.stats.window_cells = n;
  m.stats.nodata_cells = invalid_count;
  m.stats.min = lo;
  m.stats.max = hi;
}

double DemSampler::height(double px, double py, bool* touched_fill) const {
  const Impl& m = *impl_;
  // GDAL bilinear: cell centres at i + 0.5; beyond the outermost centres
  // the kernel renormalises onto the edge cell, which equals clamping.
  const double fx = px - 0.5, fy = py - 0.5;
  const double flx = std::floor(fx), fly = std::floor(fy);
  const double tx = fx - flx, ty = fy - fly;
  auto cx = [&](double i) {
    return static_cast<int>(std::clamp(i, double(m.wx0), double(m.wx0 + m.ww - 1)));
  };
  auto cy = [&](double j) {
    return static_cast<int>(std::clamp(j, double(m.wy0), double(m.wy0 + m.wh - 1)));
  };
  const int i0 = cx(flx), i1 = cx(flx + 1), j0 = cy(fly), j1 = cy(fly + 1);
  const double a = m.cell(i0, j0), b = m.cell(i1, j0), c = m.cell(i0, j1), d = m.cell(i1, j1);
  if (touched_fill) {
    *touched_fill = ((1 - tx) * (1 - ty) > 0 && m.cell_filled(i0, j0)) ||
                    (tx * (1 - ty) > 0 && m.cell_filled(i1, j0)) ||
                    ((1 - tx) * ty > 0 && m.cell_filled(i0, j1)) || (tx * ty > 0 && m.cell_filled(i1, j1));
  }
  return (1 - ty) * ((1 - tx) * a + tx * b) + ty * ((1 - tx) * c + tx * d);
}

bool DemSampler::outside(double px, double py) const {
  const Impl& m = *impl_;
  return !(px >= 0 && py >= 0 && px <= m.width && py <= m.height);
}

const TerrainStats& DemSampler::stats() const { return impl_->stats; }

}  // namespace prep
