// dem_tiff.hpp — the DEMs tests write: north-up single-band GeoTIFFs
// through GDAL's GTiff driver. Header-only: for tests that link GDAL.
#pragma once

#include <gdal_priv.h>

#include <string>

// Creates the GeoTIFF `path`: w x h cells of `cell` metres and band type
// `type`, its upper-left corner at (x0, y0), in the CRS `wkt` (none when
// empty). The caller writes the band (and its no-data value, scale...).
// Null when GDAL cannot create it.
inline GDALDatasetUniquePtr create_dem_tiff(const std::string& path, int w, int h,
                                            GDALDataType type, double x0, double y0, double cell,
                                            const std::string& wkt) {
  GDALAllRegister();
  GDALDriver* gtiff = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (gtiff == nullptr) return nullptr;
  GDALDatasetUniquePtr ds(gtiff->Create(path.c_str(), w, h, 1, type, nullptr));
  if (!ds) return ds;
  double gt[6] = {x0, cell, 0, y0, 0, -cell};
  ds->SetGeoTransform(gt);
  if (!wkt.empty()) ds->SetProjection(wkt.c_str());
  return ds;
}
