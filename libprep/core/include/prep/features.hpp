// prep/features.hpp — the data that flows through the first stages:
//
//   sources --read--> FeatureSet --project--> --clean--> SceneFeatures
//
// No GDAL, GEOS or CGAL types appear here; stages keep those in their .cpp
// files. Coordinates are double precision throughout these stages.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "prep/manifest.hpp"
#include "prep/spec.hpp"

namespace prep {

struct Point2 {
  double x = 0, y = 0;
};
using Ring = std::vector<Point2>;  // not closed: first point is not repeated

// A box that holds no point yet (minima +inf, maxima -inf); extend() grows
// a box to take in points.
inline Extent no_points() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return {inf, inf, -inf, -inf};
}
inline void extend(Extent& b, const Point2& p) {
  b.xmin = std::min(b.xmin, p.x);
  b.ymin = std::min(b.ymin, p.y);
  b.xmax = std::max(b.xmax, p.x);
  b.ymax = std::max(b.ymax, p.y);
}
inline void extend(Extent& b, const Ring& r) {
  for (const Point2& p : r) extend(b, p);
}

// What a part carries from its source feature into the package: the
// feature id, the part index after splitting multi-geometries, and the
// attribute values for the drawing order and the colour (NaN when none).
struct FeatureKeys {
  int64_t fid = -1;
  int part = 0;
  double order_value = std::numeric_limits<double>::quiet_NaN();
  double color_value = std::numeric_limits<double>::quiet_NaN();
};

// Output of `read`: geometry in the source CRS, multi-geometries split.
struct SourceFeature : FeatureKeys {
  uint64_t feature = 0;                   // index of the input feature in its layer (read order)
  std::string repairs;                    // what read/project already fixed ("closed an open ring")
  std::string drop_reason;                // non-empty: unusable; clean records it as dropped
  std::optional<FailureStage> failed_in;  // set: drop_reason is a per-feature failure
  bool is_polygon = false;
  bool is_point = false;    // rings = {{the point}} (a point layer's part)
  std::vector<Ring> rings;  // polygon: [0] shell, then holes; line: [0]
};

struct SourceLayer {
  LayerSpec spec;
  std::string srs_wkt;  // empty when the source has none
  std::vector<SourceFeature> features;
};

struct FeatureSet {
  std::vector<SourceLayer> layers;
  Manifest manifest;
};

// The local scene frame. Scene coordinates are metres relative to `origin`,
// expressed in `crs_wkt` (a projected CRS).
struct SceneFrame {
  std::string crs_wkt;
  std::string description;            // e.g. "local TM lon0=7.42 lat0=43.73"
  double origin_x = 0, origin_y = 0;  // in the frame CRS
  // Local TM frames only (else NaN): the central meridian and the latitude of
  // origin, degrees, WGS84 ellipsoid, scale 1 on the central meridian.
  double tm_lon0 = std::numeric_limits<double>::quiet_NaN();
  double tm_lat0 = std::numeric_limits<double>::quiet_NaN();
};

// Output of `clean`: valid, oriented (shell CCW, holes CW), clipped and
// simplified; coordinates in metres relative to frame.origin.
struct ScenePolygon : FeatureKeys {
  Ring shell;
  std::vector<Ring> holes;
  uint32_t layer = 0;  // index into SceneFeatures::layers
  double area = 0;     // m², for drawing order
};

struct SceneLine : FeatureKeys {
  Ring points;
  bool closed = false;  // polygon ring used as an outline
  uint32_t layer = 0;
  double length = 0;  // ground metres (geodesic), for drawing order
  double width = 0;   // ground metres (static) corrected by the frame scale; pixels (dynamic)
  // A dashed static line cut by a tile: the whole line's length up to
  // points[0], summed over its vertices quantised as a package quantises
  // them (formats/SPEC.md "Dashed lines"); 0 otherwise.
  double dash_start = 0;
};

struct SceneFeatures {
  SceneFrame frame;
  Extent extent;  // scene coordinates (relative to origin)
  std::vector<LayerSpec> layers;
  std::vector<ScenePolygon> polygons;
  std::vector<SceneLine> lines;          // static lines and outlines
  std::vector<SceneLine> dynamic_lines;  // terrain-matched, width in pixels
  Manifest manifest;
};

}  // namespace prep
