// What the files of libprep/pipeline share (not a public header).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "prep/features.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/pipeline.hpp"
#include "prep/tile.hpp"

namespace prep::pipeline_internal {

// Writes a small text file whole, through a temp file and a rename, so that
// a reader never sees half of it. Throws output_error naming the path.
void write_text_file(const std::string& path, const std::string& text);

// The package metadata only the pipeline knows (write_model writes frame,
// grid, counts and the manifest itself): the manifest totals, the layers,
// provenance, scene file and build options. Paths are recorded relative to
// the scene file's folder; build_options.dem relative to the folder of
// `package_path` (the package being written; empty: as the scene gives it).
nlohmann::json package_metadata(const BuildSpec& scene, const Manifest& manifest,
                                const nlohmann::json& provenance,
                                const std::string& package_path = {});

// Rewrites the source and DEM paths in the manifest's notes and entry
// reasons as a package records them (relative to the scene file's folder),
// so that the package's bytes do not depend on where the checkout is.
void record_manifest_paths(const BuildSpec& scene, Manifest& manifest);

// What write_tileset() did, for the report.
struct TilesetOutcome {
  size_t tiles = 0;   // packages in the index
  size_t built = 0;   // of those, built by this run
  size_t reused = 0;  // of those, kept from an earlier run (they verified)
  size_t empty = 0;   // tiles reached by a part's box but left with no part
  uint64_t bytes = 0;
  double margin = 0;
  // Overview levels (formats/SPEC.md "Overview levels"), all together; the
  // fields above are level 0's.
  int levels = 0;
  size_t level_tiles = 0, level_built = 0, level_reused = 0, level_empty = 0;
  uint64_t level_bytes = 0;
};

// A tileset build in three steps whose state is on disk only, in the work
// folder request.output/.work (tileset_work.hpp), so that each may run in a
// process of its own:
//  1. prepare: the cleaned parts, chunk by chunk in scene order, into the
//     intermediate, the manifest entries into their files, then the plan
//     (which tiles exist, margins, frame, counts, notes, provenance);
//  2. build_tiles: any subset of the plan's tiles, each from its window of
//     the intermediate (tile_scene, build_model, write_model; request.jobs
//     side by side), each with a record of what it made;
//  3. finalize: manifest.json (streamed), then tileset.json last; removes
//     the work folder.

class PartWriter;
class EntryWriter;
struct WorkPaths {
  std::string dir;  // the tileset
  std::string work() const { return dir + "/.work"; }
  std::string parts() const { return work() + "/parts.gpkg"; }
  std::string boxes() const { return work() + "/boxes.bin"; }
  std::string entries() const { return work() + "/entries.json"; }
  std::string read_entries() const { return work() + "/read_entries.json"; }
  std::string plan() const { return work() + "/plan.json"; }
  std::string tile_records() const { return work() + "/tiles"; }
  std::string tile_record(const TileKey& k) const {
    return tile_records() + "/" + tile_name(k) + ".json";
  }
  // Overview level `level` (0: the tile_record above).
  std::string tile_record(const TileKey& k, int level) const {
    if (level == 0) return tile_record(k);
    return tile_records() + "/L" + std::to_string(level) + "_" + tile_name(k) + ".json";
  }
};

// Step 1, fed by the caller. Creates the tileset folder and a fresh work
// folder. Parts must come in scene order (layer by layer, each layer's
// features in input order), clean's entries in layer order; the read
// stage's entries follow them in manifest.json.
class TilesetPreparer {
 public:
  TilesetPreparer(const BuildSpec& spec, const std::string& dir);
  ~TilesetPreparer();
  TilesetPreparer(const TilesetPreparer&) = delete;
  TilesetPreparer& operator=(const TilesetPreparer&) = delete;
  void add_parts(const SceneFeatures& chunk);
  void add_entry(const ManifestEntry& e);
  void add_read_entry(const ManifestEntry& e);
  // The stroke margin of the parts so far (stroke_margin of the whole
  // scene once every part is in).
  double margin() const;
  // Closes the intermediate and writes the plan. `counts_and_notes`: the
  // scene's per-layer counts and notes (its entries are ignored).
  void finish(const SceneFrame& frame, const Manifest& counts_and_notes,
              const nlohmann::json& provenance);
  // After finish(): the box of every kept part (scene coordinates; Extent{}
  // when none), the parts per kind (polygons, lines, dynamic lines), the
  // entries written.
  Extent extent() const;
  uint64_t parts(int kind) const;
  uint64_t entries() const;

 private:
  const BuildSpec& spec_;
  WorkPaths paths_;
  std::unique_ptr<PartWriter> parts_;
  std::unique_ptr<EntryWriter> entries_, read_entries_;
};

// Step 1 out of core: every source read once, in chunks, its features
// spilled to the work folder; the frame chosen from the spill; each layer
// projected (its approximation fitted to the whole layer), cleaned and
// written to the intermediate chunk by chunk; entries streamed. Memory: a
// chunk, the tile keys, the per-layer counts and the read stage's entries.
// The same intermediate, plan and entries as prepare_tileset() of the
// scene read, projected and cleaned in memory.
struct PreparedScene {
  SceneFrame frame;
  Extent extent;  // scene coordinates, as clean sets it
  std::vector<LayerSpec> layers;
  Manifest manifest;  // per-layer counts and notes; no entries
  uint64_t entry_count = 0;
  size_t skipped_failures = 0;  // entries for features skip_failures dropped
  uint64_t polygons = 0, lines = 0, dynamic_lines = 0;
  double read_s = 0, project_s = 0, clean_s = 0;
};
PreparedScene prepare_tileset_streaming(const BuildSpec& spec, const BuildRequest& request,
                                        const std::function<const nlohmann::json&()>& provenance);

// After a failed step: removes the work folder and, when `made_dir` (the
// build created `dir`), `dir`/tiles and `dir` if they are empty; tiles
// already written stay for the next run to keep.
void discard_work(const std::string& dir, bool made_dir);

// Step 2: the plan's tiles i with i % parts == part (parts <= 1: all).
// Each tile to build is checked against request.max_memory once its window
// is cut (estimate_tile); `estimates` (may be null) receives the largest
// tile's estimate, or the one that stopped the build, also when it throws.
struct TileStepOutcome {
  size_t tiles = 0, built = 0, reused = 0, empty = 0;
  // Dynamic-line vertices of the tiles built by this step whose heights
  // came from beyond the DEM, on how many lines, of how many vertices.
  uint64_t dyn_vertices_outside_dem = 0, dyn_lines_outside_dem = 0, dyn_vertices = 0;
};
TileStepOutcome build_tiles(const BuildSpec& spec, const BuildRequest& request, size_t part,
                            size_t parts, std::vector<MemoryEstimate>* estimates = nullptr);

// Step 3: every tile of the plan must have its record. `manifest` (may be
// null) receives the scene's counts and notes.
TilesetOutcome finalize_tileset(const BuildSpec& spec, const BuildRequest& request,
                                Manifest* manifest = nullptr);

}  // namespace prep::pipeline_internal
