// Test fixtures for terrain matching: synthetic GeoTIFF DEMs written
// through GDAL, the GDAL bilinear oracle, and Monaco's roads as SceneLines.
#pragma once

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>
#include <GeographicLib/TransverseMercator.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "ogr_lines.hpp"
#include "prep/features.hpp"
#include "test_support.hpp"

namespace terraintest {

// The folders temp_dir made, removed when the test process exits (each test
// runs in a process of its own under ctest).
struct TempDirs {
  std::vector<std::filesystem::path> made;
  TempDirs() = default;
  TempDirs(const TempDirs&) = delete;
  TempDirs& operator=(const TempDirs&) = delete;
  ~TempDirs() {
    for (const auto& d : made) {
      std::error_code ec;
      std::filesystem::remove_all(d, ec);
    }
  }
};

inline std::string temp_dir(const std::string& name) {
  static TempDirs dirs;
  auto dir = std::filesystem::temp_directory_path() /
             ("decalprep_terrain_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  dirs.made.push_back(dir);
  return dir.string();
}

inline std::string wkt_of(const std::string& def) {
  OGRSpatialReference srs;
  if (srs.SetFromUserInput(def.c_str()) != OGRERR_NONE) throw std::runtime_error("bad CRS " + def);
  char* w = nullptr;
  srs.exportToWkt(&w);
  std::string s = w;
  CPLFree(w);
  return s;
}

// Writes a single-band Float32 GeoTIFF: cell (i, j) has value f(i, j);
// geotransform gt; CRS `crs` (any SetFromUserInput string); optional nodata.
inline std::string write_dem(const std::string& path, int w, int h, const double gt[6],
                             const std::string& crs, const std::function<double(int, int)>& f,
                             const double* nodata = nullptr, GDALDataType type = GDT_Float32) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GTiff");
  GDALDataset* ds = drv->Create(path.c_str(), w, h, 1, type, nullptr);
  if (!ds) throw std::runtime_error("cannot create " + path);
  double g[6];
  for (int i = 0; i < 6; ++i) g[i] = gt[i];
  ds->SetGeoTransform(g);
  const std::string wkt = wkt_of(crs);
  ds->SetProjection(wkt.c_str());
  std::vector<double> v(static_cast<size_t>(w) * h);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) v[static_cast<size_t>(j) * w + i] = f(i, j);
  auto* b = ds->GetRasterBand(1);
  if (nodata) b->SetNoDataValue(*nodata);
  if (b->RasterIO(GF_Write, 0, 0, w, h, v.data(), w, h, GDT_Float64, 0, 0, nullptr) != CE_None)
    throw std::runtime_error("cannot write " + path);
  GDALClose(ds);
  return path;
}

// The oracle: GDAL's own bilinear resampling (GDALRasterIO, GRIORA_Bilinear).
// GDAL 3.6 resamples in the band's data type (an Int16 SRTM band would
// round to whole metres), so the band is first copied to a Float64 MEM
// dataset; then a 1x1-pixel window at (px - 0.25, py - 0.25) is read into
// a 2x2 buffer (upsampling keeps the plain bilinear kernel, while a 1x1
// buffer would take GDAL's no-resampling path): buffer pixel (0, 0) has its
// centre at (px, py). Valid for 0.25 <= px <= width - 0.75 (same for y).
// The copy carries no no-data flag: cells can be patched with the values a
// fill policy gives them (patch()) before comparing.
class GdalBilinear {
 public:
  explicit GdalBilinear(const std::string& path) {
    GDALAllRegister();
    GDALDatasetUniquePtr src(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    if (!src) throw std::runtime_error("oracle cannot open " + path);
    w_ = src->GetRasterXSize();
    h_ = src->GetRasterYSize();
    src->GetGeoTransform(gt_);
    int ok = 0;
    nodata_ = src->GetRasterBand(1)->GetNoDataValue(&ok);
    has_nodata_ = ok != 0;
    raw_.resize(static_cast<size_t>(w_) * h_);
    if (src->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, w_, h_, raw_.data(), w_, h_, GDT_Float64, 0,
                                        0, nullptr) != CE_None)
      throw std::runtime_error("oracle cannot read " + path);
    mem_.reset(GetGDALDriverManager()->GetDriverByName("MEM")->Create("", w_, h_, 1, GDT_Float64,
                                                                      nullptr));
    if (mem_->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, w_, h_, raw_.data(), w_, h_, GDT_Float64,
                                         0, 0, nullptr) != CE_None)
      throw std::runtime_error("oracle cannot copy " + path);
  }
  double at_pixel(double px, double py) const {
    GDALRasterIOExtraArg ea;
    INIT_RASTERIO_EXTRA_ARG(ea);
    ea.eResampleAlg = GRIORA_Bilinear;
    ea.bFloatingPointWindowValidity = TRUE;
    ea.dfXOff = px - 0.25;
    ea.dfYOff = py - 0.25;
    ea.dfXSize = 1;
    ea.dfYSize = 1;
    double out[4] = {0, 0, 0, 0};
    const int x0 = std::clamp(static_cast<int>(std::floor(ea.dfXOff)), 0, w_ - 1);
    const int y0 = std::clamp(static_cast<int>(std::floor(ea.dfYOff)), 0, h_ - 1);
    if (mem_->GetRasterBand(1)->RasterIO(GF_Read, x0, y0, 1, 1, out, 2, 2, GDT_Float64, 0, 0,
                                         &ea) != CE_None)
      throw std::runtime_error("oracle RasterIO failed");
    return out[0];
  }
  // Georeferenced (DEM CRS) coordinates to pixel, north-up rasters.
  double px(double gx) const { return (gx - gt_[0]) / gt_[1]; }
  double py(double gy) const { return (gy - gt_[3]) / gt_[5]; }
  double at(double gx, double gy) const { return at_pixel(px(gx), py(gy)); }

  int width() const { return w_; }
  int height() const { return h_; }
  double raw(int i, int j) const { return raw_[static_cast<size_t>(j) * w_ + i]; }
  bool invalid(int i, int j) const {
    return std::isnan(raw(i, j)) || (has_nodata_ && raw(i, j) == nodata_);
  }
  void patch(int i, int j, double v) {
    if (mem_->GetRasterBand(1)->RasterIO(GF_Write, i, j, 1, 1, &v, 1, 1, GDT_Float64, 0, 0,
                                         nullptr) != CE_None)
      throw std::runtime_error("oracle cannot patch");
  }
  // Cells with non-zero bilinear weight at pixel position (px, py).
  std::vector<std::pair<int, int>> stencil(double x, double y) const {
    const double fx = x - 0.5, fy = y - 0.5;
    const int i0 = static_cast<int>(std::floor(fx)), j0 = static_cast<int>(std::floor(fy));
    const double tx = fx - i0, ty = fy - j0;
    std::vector<std::pair<int, int>> out;
    for (int dj = 0; dj < 2; ++dj)
      for (int di = 0; di < 2; ++di) {
        const double wgt = (di ? tx : 1 - tx) * (dj ? ty : 1 - ty);
        if (wgt > 0)
          out.emplace_back(std::clamp(i0 + di, 0, w_ - 1), std::clamp(j0 + dj, 0, h_ - 1));
      }
    return out;
  }

 private:
  int w_ = 0, h_ = 0;
  double gt_[6] = {0, 1, 0, 0, 0, 1};
  double nodata_ = 0;
  bool has_nodata_ = false;
  std::vector<double> raw_;
  GDALDatasetUniquePtr mem_;
};

// A local Transverse Mercator frame for Monaco, known to both GeographicLib
// (used by the tests as the independent inverse) and PROJ (the code).
struct MonacoFrame {
  static constexpr double lon0 = 7.42, lat0 = 43.73;
  GeographicLib::TransverseMercator tm{GeographicLib::Constants::WGS84_a(),
                                       GeographicLib::Constants::WGS84_f(), 1.0};
  double y0 = 0;
  MonacoFrame() {
    double x;
    tm.Forward(lon0, lat0, lon0, x, y0);
  }
  prep::SceneFrame frame() const {
    prep::SceneFrame f;
    f.crs_wkt = wkt_of(
        "+proj=tmerc +lat_0=43.73 +lon_0=7.42 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs");
    f.description = "local TM lon0=7.42 lat0=43.73";
    return f;
  }
  prep::Point2 forward(double lon, double lat) const {
    double x, y;
    tm.Forward(lon0, lat, lon, x, y);
    return {x, y - y0};
  }
  void reverse(double x, double y, double& lon, double& lat) const {
    tm.Reverse(lon0, x, y + y0, lat, lon);
  }
};

// The shipped Monaco sample (samples/monaco).
inline std::string monaco_pbf() {
  return prep::test::monaco_sample("monaco.osm.pbf");
}
inline std::string monaco_dem() {
  return "/vsizip/" + prep::test::monaco_sample("N43E007.hgt.zip/N43E007.hgt");
}
inline bool monaco_available() {
  return std::filesystem::exists(monaco_pbf()) &&
         std::filesystem::exists(prep::test::monaco_sample("N43E007.hgt.zip"));
}

// Monaco's roads (OSM `lines` with a highway tag) as dynamic SceneLines.
inline std::vector<prep::SceneLine> monaco_roads(const MonacoFrame& mf) {
  GDALAllRegister();
  CPLPushErrorHandler(CPLQuietErrorHandler);  // the OSM driver warns about unclosed rings
  std::vector<prep::SceneLine> out;
  GDALDatasetUniquePtr ds(
      GDALDataset::Open(monaco_pbf().c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (!ds) {
    CPLPopErrorHandler();
    return out;
  }
  OGRLayer* layer = ds->GetLayerByName("lines");
  layer->SetAttributeFilter("highway IS NOT NULL");
  prep::test::for_each_line_string(*layer, [&](OGRFeature& f, const OGRLineString& ls) {
    prep::SceneLine l;
    for (int i = 0; i < ls.getNumPoints(); ++i) {
      const prep::Point2 p = mf.forward(ls.getX(i), ls.getY(i));
      if (!l.points.empty() && std::hypot(p.x - l.points.back().x, p.y - l.points.back().y) < 0.01)
        continue;
      l.points.push_back(p);
    }
    if (l.points.size() > 3 && std::hypot(l.points.front().x - l.points.back().x,
                                          l.points.front().y - l.points.back().y) < 0.01) {
      l.points.pop_back();
      l.closed = true;
    }
    if (l.points.size() < 2) return;
    l.fid = f.GetFID();
    l.width = 3;
    for (size_t i = 1; i < l.points.size(); ++i)
      l.length += std::hypot(l.points[i].x - l.points[i - 1].x, l.points[i].y - l.points[i - 1].y);
    out.push_back(std::move(l));
  });
  CPLPopErrorHandler();
  return out;
}

}  // namespace terraintest
