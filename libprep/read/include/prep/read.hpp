// prep/read.hpp — stage 1: GDAL/OGR sources -> FeatureSet (ARCHITECTURE.md "1. read").
//
// Geometry stays in the source CRS, in double precision. Multi-geometries and
// geometry collections are split into parts; curves are linearised; Z and M
// are dropped (with a manifest note). A geometry the layer kind cannot use is
// dropped with a manifest entry. A per-feature failure (NaN/Inf coordinates,
// a feature OGR cannot decode; prep/feature_failure.hpp) fails the build with
// its fid, or, with skip_failures, is dropped with reason "failed in read: ...".
//
// The TOML scene file (what to read and how to draw it; every key is
// described in samples/README.md) is parsed here too, with toml++: it is the
// read stage's specification.
#pragma once

#include <cstddef>
#include <functional>
#include <string>

#include "prep/features.hpp"

namespace prep {

class Progress;  // prep/progress.hpp

// The streaming form of the read (a tileset's prepare step): features are
// handed over in chunks instead of being kept in the FeatureSet.
struct ReadChunks {
  // A chunk ends after the input feature (every part of it) that brings it
  // to this many parts or this many vertices.
  size_t parts = 4096;
  size_t vertices = 65536;
  // Takes a chunk of scene layer `layer`'s features (in input order,
  // continuing its previous chunk; the caller may move them out). Layers
  // are read concurrently: calls for different layers may come from
  // different threads at once, never two for the same layer.
  std::function<void(size_t layer, SourceLayer& chunk)> take;
  // Layer `layer` is read again from its start (GDAL's OSM driver needed
  // another node index, or a shared OSM pass fell back to one read per
  // layer): forget every chunk of it taken so far.
  std::function<void(size_t layer)> restart;
};

struct ReadOptions {
  // Stage "read" (features; the total is an estimate for sources that do not
  // know their feature count, such as OSM). Null: silent.
  Progress* progress = nullptr;
  // Set (read_scene only): the features go to chunks->take, and the
  // FeatureSet's layers come back without features (spec, CRS; the
  // manifest as always).
  const ReadChunks* chunks = nullptr;
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
