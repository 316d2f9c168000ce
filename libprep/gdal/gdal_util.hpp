// gdal_util.hpp — GDAL helpers shared by read, project and the DEM module.
#pragma once

#include <string>

class OGRSpatialReference;

namespace prep {

// The CRS as one-line WKT2 (2019), the form every CRS string of a package
// and a FeatureSet takes; "" when GDAL cannot export it.
std::string crs_wkt2(const OGRSpatialReference& srs);

}  // namespace prep
