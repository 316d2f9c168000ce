#include "gdal_util.hpp"

#include <cpl_conv.h>
#include <ogr_spatialref.h>

namespace prep {

std::string crs_wkt2(const OGRSpatialReference& srs) {
  const char* opts[] = {"FORMAT=WKT2_2019", "MULTILINE=NO", nullptr};
  char* wkt = nullptr;
  srs.exportToWkt(&wkt, opts);
  std::string s = wkt ? wkt : "";
  CPLFree(wkt);
  return s;
}

}  // namespace prep
