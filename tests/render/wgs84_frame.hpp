// The render tests' way from OpenStreetMap's lon/lat to a package's frame
// (OGR, independent of decalprep's own projection stage).
#pragma once

#include <ogr_spatialref.h>

#include <memory>
#include <stdexcept>

#include "prep/features.hpp"

namespace render_test {

// EPSG:4326 (lon, lat order) to the frame's CRS, in absolute frame
// coordinates (the origin not yet subtracted). Throws when PROJ has none.
inline std::unique_ptr<OGRCoordinateTransformation> wgs84_to_frame(const prep::SceneFrame& frame) {
  OGRSpatialReference wgs84, target;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  target.importFromWkt(frame.crs_wkt.c_str());
  target.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(
      OGRCreateCoordinateTransformation(&wgs84, &target));
  if (!ct) throw std::runtime_error("no transformation to the package frame");
  return ct;
}

}  // namespace render_test
