// The WKT2 of an EPSG CRS: a source layer's srs_wkt (tests/project), a test
// GeoTIFF's projection (tests/render).
// EPSG:4326 keeps its authority axis order (lat, lon) in the WKT; the data
// is (lon, lat) as every GIS file stores it.
#pragma once

#include <cpl_conv.h>
#include <ogr_spatialref.h>

#include <string>

inline std::string epsg_wkt(int code) {
  OGRSpatialReference srs;
  srs.importFromEPSG(code);
  char* wkt = nullptr;
  const char* opts[] = {"FORMAT=WKT2_2019", nullptr};
  srs.exportToWkt(&wkt, opts);
  std::string s = wkt;
  CPLFree(wkt);
  return s;
}
