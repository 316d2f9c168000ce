// prep/project.hpp — stage 2: FeatureSet (source CRS) -> FeatureSet in the
// scene frame (ARCHITECTURE.md "2. project").
//
// The default frame is centred on the data's geographic extent (longitudes
// taken on the circle, so data across the antimeridian is centred near 180):
// a local Transverse Mercator (scale 1 on the central meridian, WGS84
// ellipsoid) while the data lies within 3900 km of the central meridian,
// else an oblique stereographic within 90 degrees of the data's centre (or
// the nearer pole), else Equal Earth (docs/build.md "The scene frame"). The
// transformation runs through PROJ (GDAL); the local TM's point scale factor
// comes from GeographicLib. `scene.crs` picks any other projected CRS.
// Every SRS is used with OAMS_TRADITIONAL_GIS_ORDER (x = easting/longitude).
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "prep/features.hpp"

namespace prep {

struct DemSpec;       // prep/dem.hpp
class Progress;       // prep/progress.hpp
class ProgressStage;  // prep/progress.hpp

// Features in frame coordinates (metres relative to frame.origin), plus the
// point scale factor of the frame at each part (frame metres per ground
// metre), in the same order as features.layers[i].features.
struct ProjectedFeatures {
  SceneFrame frame;
  FeatureSet features;                     // srs_wkt = frame.crs_wkt
  std::vector<std::vector<double>> scale;  // [layer][feature] point scale factor k
  std::optional<Extent> clip;              // scene coordinates; from --extent or the DEM
};

// Chooses the scene frame for `features`: `crs` when given (any PROJ/EPSG/
// WKT string, origin at the data centre rounded to 1 m), else the default
// frame above (origin at the projection's centre for the local TM and the
// stereographic, at the data centre rounded to 1 m for Equal Earth). Throws
// input_error for an unknown or geographic `crs`, when there is no data to
// centre on, or, without `crs`, for a layer whose longitudes lie beyond
// +-540 degrees.
SceneFrame choose_frame(const FeatureSet& features, const std::string& crs);

// Read features, layer by layer, whether held in memory (a FeatureSet) or
// not (a tileset's prepare step reads them back from a spill file): what
// choose_frame and a LayerProjection visit.
class FeatureSource {
 public:
  virtual ~FeatureSource() = default;
  virtual size_t layer_count() const = 0;
  virtual const LayerSpec& spec(size_t layer) const = 0;
  virtual const std::string& srs_wkt(size_t layer) const = 0;
  // Every feature (part) of `layer` in input order.
  virtual void for_each(size_t layer,
                        const std::function<void(const SourceFeature&)>& visit) const = 0;
};

// The same frame as choose_frame(FeatureSet) for the same features.
SceneFrame choose_frame(const FeatureSource& features, const std::string& crs);

// The transformation of one layer into the frame, as project() applies it,
// for a layer projected chunk by chunk: the verified approximation is fitted
// to the whole layer (`features.for_each(layer)`), so every chunk's vertices
// land exactly where project() puts them.
class LayerProjection {
 public:
  LayerProjection(const FeatureSource& features, size_t layer, const SceneFrame& frame,
                  const SceneSpec& scene);
  ~LayerProjection();
  LayerProjection(const LayerProjection&) = delete;
  LayerProjection& operator=(const LayerProjection&) = delete;
  // Projects `chunk` (features of the layer, in input order) in place and
  // returns each feature's point scale factor. Without scene.skip_failures
  // the chunk's first failing feature throws (as project() does for the
  // layer); `stage` (may be null) counts the parts.
  std::vector<double> apply(SourceLayer& chunk, ProgressStage* stage) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The clip extent project() sets (ProjectedFeatures::clip): scene.extent in
// scene.extent_crs, else the DEM's footprint, in scene coordinates.
// `features` are the read data in their source CRSs; their extent in the
// frame is computed only for the checks: an extent that looks like degrees
// (check_extent_units) is a usage_error; a DEM whose footprint misses the
// data's extent or the --extent is an input_error naming the DEM, its
// footprint and the other box in the frame CRS.
std::optional<Extent> clip_extent(const SceneFrame& frame, const SceneSpec& scene,
                                  const FeatureSource& features);

// The bounding box, in scene coordinates of `frame` (relative to its
// origin), of the DEM's footprint (prep/dem.hpp dem_footprint, transformed
// with densified edges). Opens the DEM under its rules; throws as
// dem_footprint does, or input_error when it cannot be transformed.
Extent dem_extent_in_frame(const DemSpec& dem, const SceneFrame& frame);

// The one check of `build --extent` and `render --extent` for numbers meant
// as degrees: with no `extent_crs`, in a projected frame, an `extent` whose
// numbers all lie within +-180 (x) and +-90 (y), which read as WGS84
// longitude/latitude meets `data` (the data's extent, scene coordinates),
// while read as frame units it misses `data` or its size is farther from
// the data's size (in log ratio) than the degree reading's, throws
// usage_error (exit 2), prefixed with `context`, that suggests
// --extent-crs EPSG:4326. Anything else returns.
void check_extent_units(const Extent& extent, const std::string& extent_crs,
                        const SceneFrame& frame, const Extent& data, const std::string& context);

// Transforms every feature into `frame` (parallel per feature; output order
// is the input order). A feature whose transform fails is dropped with a
// manifest entry. Also resolves the clip extent: scene.extent (in
// scene.extent_crs, default the frame CRS) or, when scene.dem is set, the
// DEM's extent transformed into the frame. Throws input_error/gdal_error
// naming the CRS or file at fault. `progress` (may be null) gets the stage
// "project", counted in parts.
ProjectedFeatures project(FeatureSet features, const SceneFrame& frame, const SceneSpec& scene,
                          Progress* progress = nullptr);

// `extent` given in `crs` (any PROJ/EPSG/WKT string; empty: the frame CRS
// itself) as ABSOLUTE coordinates of the frame CRS: unchanged when `crs` is
// empty, else GDAL's TransformBounds with densified edges (21 points per
// edge), every SRS in OAMS_TRADITIONAL_GIS_ORDER (x = easting/longitude).
// The one convention of `build --extent` and `render --extent`. Throws
// input_error, its message starting with `context` ("project", "render"),
// for an unknown CRS or an extent that cannot be transformed.
Extent extent_in_frame_crs(const Extent& extent, const std::string& crs, const SceneFrame& frame,
                           const std::string& context);

// The point scale factor of `frame` at frame coordinates (x, y) relative to
// the origin: ratio of frame distance to ground (ellipsoidal) distance, by
// which widths in ground metres are multiplied. For the local TM frame this
// is GeographicLib's k; for other conformal frames the scale of a 10 m
// geodesic step east; for equal-area frames (Equal Earth, Lambert azimuthal,
// Albers, ...) the geometric mean sqrt(a b) of Tissot's semi-axes (1 there).
double frame_scale_factor(const SceneFrame& frame, double x, double y);

}  // namespace prep
