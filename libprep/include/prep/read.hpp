// prep/read.hpp — stage 1: GDAL/OGR sources -> FeatureSet (ARCHITECTURE.md "1. read").
//
// Geometry stays in the source CRS, in double precision. Multi-geometries and
// geometry collections are split into parts; curves are linearised; Z and M
// are dropped (with a manifest note). A geometry the layer kind cannot use is
// dropped with a manifest entry. A per-feature failure (NaN/Inf coordinates,
// a feature OGR cannot decode; prep/feature_failure.hpp) fails the build with
// its fid, or, with skip_failures, is dropped with reason "failed in read: ...".
#pragma once

#include <string>

#include "prep/scene.hpp"

namespace prep {

class Progress;  // prep/progress.hpp

struct ReadOptions {
  // Stage "read" (features; the total is an estimate for sources that do not
  // know their feature count, such as OSM). Null: silent.
  Progress* progress = nullptr;
};

// Reads every layer of `scene` (in scene order). Throws:
//   gdal_error  — a source GDAL cannot open, an unknown layer, invalid SQL,
//                 a read failure (message names file, layer and GDAL's text);
//   input_error — a source without CRS and no scene.assume_crs, an invalid
//                 assume_crs, a NaN/Inf coordinate (unless skip_failures;
//                 a feature OGR cannot decode is a gdal_error then),
//                 an unknown order/colour attribute.
// OSM XML whose node ids do not increase (Overpass output) is read with
// OSM_USE_CUSTOM_INDEXING=NO, and the manifest says so; OSM XML listing a
// node after a way or relation (which GDAL would silently drop ways for) is
// an input_error that says how to reorder it. A GeoJSON object of any size
// is read (OGR_GEOJSON_MAX_OBJ_SIZE=0 unless the user set it).
// Thread-safe with respect to other reads (GDAL config is set thread-locally
// for the read and restored after it).
FeatureSet read_scene(const SceneSpec& scene, const ReadOptions& options = {});

// Reads one layer, appending its counts, entries and notes to `manifest`.
SourceLayer read_layer(const LayerSpec& spec, const SceneSpec& scene, Manifest& manifest,
                       const ReadOptions& options = {});

}  // namespace prep
