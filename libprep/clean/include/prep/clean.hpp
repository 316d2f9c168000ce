// prep/clean.hpp — stage 3: projected features -> SceneFeatures
// (ARCHITECTURE.md "3. clean"). GEOS (reentrant C API), one context per worker thread.
//
// For every part: duplicate vertices and zero-length segments removed;
// polygons made valid (GEOSMakeValid; with 64 holes or more by parts, with
// the same result: libprep/clean/detail/repair_by_parts.hpp) with every hole
// attached to its shell and nested islands kept as separate polygons; shells CCW, holes CW; parts
// clipped to the clip extent and simplified (topology-preserving) to
// `scene.resolution`. Every repair and drop lands in the manifest, with the
// area before/after when a repair changes the area by more than 1e-6.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "prep/features.hpp"
#include "prep/project.hpp"

namespace prep {

class Progress;       // prep/progress.hpp
class ProgressStage;  // prep/progress.hpp

struct CleanOptions {
  unsigned threads = 0;  // 0: all hardware threads; the output does not depend on it
  // Stage "clean", counted in parts; every part in GEOS is watched (the
  // watchdog names one that takes longer than the Progress's threshold).
  // Null: silent.
  Progress* progress = nullptr;
  // For tests only; the pipeline never sets it. The feature with this fid
  // has its simplification run with tolerance -1, which GEOS rejects
  // ("Tolerance must be non-negative"), so that a real GEOS error travels
  // the per-feature failure path (tests/hostile/test_clean_failure.cpp): no
  // input is known to make GEOS 3.11 fail on its own.
  std::optional<int64_t> test_geos_failure_fid;
};

// Cleans `input`. Bad geometry that is expected (zero area, too few
// vertices) is dropped and recorded. A per-feature failure (a GEOS error, a
// repair that is still invalid, a non-finite coordinate; feature_failure.hpp)
// throws input_error naming the first failing feature in input order, or,
// with scene.skip_failures, drops the whole feature with reason
// "failed in <stage>: ..." (also for failures read/project recorded).
// Invariant on return, per layer: read == kept + clipped_away + dropped.
SceneFeatures clean(const ProjectedFeatures& input, const SceneSpec& scene,
                    const CleanOptions& options = {});

// The same, taking the parts' coordinates out of `input` instead of copying
// them (the pipeline's call: `input` is not used afterwards).
SceneFeatures clean(ProjectedFeatures&& input, const SceneSpec& scene,
                    const CleanOptions& options = {});

// clean() for a scene that comes chunk by chunk (a tileset's prepare step):
// the same parts, entries and counts as clean() of the whole scene, in the
// same order, when the layers come in scene order and each layer's chunks
// in input order. Throws what clean() throws, at the same feature.
class ChunkCleaner {
 public:
  // `clip`: ProjectedFeatures::clip; `stage` (may be null): counts parts and
  // watches them (prep/progress.hpp).
  ChunkCleaner(const SceneSpec& scene, const std::optional<Extent>& clip,
               const CleanOptions& options, ProgressStage* stage);
  ~ChunkCleaner();
  ChunkCleaner(const ChunkCleaner&) = delete;
  ChunkCleaner& operator=(const ChunkCleaner&) = delete;
  // Starts scene layer `layer_index` (`read_manifest`: the read stage's,
  // for the layer's read count).
  void begin_layer(uint32_t layer_index, const LayerSpec& spec, const Manifest& read_manifest);
  // Cleans a chunk of the layer (whole features; `scale` from the
  // projection, one per feature), taking its coordinates: kept parts are
  // appended to out.polygons, out.lines, out.dynamic_lines, the layer's
  // entries to out.manifest.entries.
  void clean_chunk(SourceLayer& chunk, const std::vector<double>& scale, SceneFeatures& out);
  // The layer's counts; read == kept + clipped_away + dropped, or an error.
  LayerCounts end_layer();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// A cleaned part simplified again for a tileset's overview level
// (formats/SPEC.md "Overview levels"). A polygon: each ring by Douglas-
// Peucker with `tolerance`, then proved valid by the near-linear sweep
// clean() uses (detail/certainly_valid.hpp); where the sweep finds a
// problem, the sections of the rings in it that the simplifier replaced by
// a chord get their vertices back, and the sweep runs again. Where the sweep
// cannot decide, GEOS TopologyPreserveSimplify of the part does it, and the
// unsimplified part is kept when GEOS calls that result invalid. A line:
// GEOS TopologyPreserveSimplify. Shells stay CCW, holes CW. Every vertex of
// the result is a vertex of the part and the part lies within `tolerance`
// of the result (Douglas-Peucker's bound). Drawing-order keys (area,
// length) are left as they are: they are the whole feature's. One per
// thread (it owns a GEOS context).
class PartSimplifier {
 public:
  explicit PartSimplifier(double tolerance);
  ~PartSimplifier();
  PartSimplifier(const PartSimplifier&) = delete;
  PartSimplifier& operator=(const PartSimplifier&) = delete;
  // Simplify in place; false when nothing is left (a ring collapsed to zero
  // area, a line to one point, a closed line to fewer than three). A GEOS
  // error throws input_error naming `what` (layer, fid and part).
  bool polygon(ScenePolygon& p, const std::string& what);
  bool line(SceneLine& l, const std::string& what);
  // The same with another tolerance for this line.
  bool line(SceneLine& l, const std::string& what, double tolerance);

  // How the polygons simplified so far were decided: by the sweep (and in
  // how many of them it gave sections back), or by GEOS.
  struct Counts {
    uint64_t proved = 0, with_sections_back = 0, sections_back = 0, geos = 0;
  };
  const Counts& counts() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The area of a polygon part (shell minus holes, GEOS's shoelace) and the
// length of a line part (with its closing segment when closed): what an
// overview level's min_area / min_length are compared with.
double part_area(const ScenePolygon& p);
// The area of one ring (unsigned, as part_area counts it): what a level's
// min_area is compared with for a hole.
double ring_area(const Ring& r);
double part_length(const SceneLine& l);

// The bounding box of every kept polygon shell and line (empty when nothing
// is kept): SceneFeatures::extent as clean sets it.
Extent kept_extent(const SceneFeatures& scene);

}  // namespace prep
