// What the files of the tileset build share (not a public header): the
// work folder's paths and the writer of the prepare step.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "prep/features.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/tile.hpp"

namespace prep::tiling {

class PartWriter;
class EntryWriter;
struct WorkPaths {
  std::string dir;  // the tileset
  std::string work() const { return dir + "/.work"; }
  std::string parts() const { return work() + "/parts.bin"; }
  std::string parts_index() const { return work() + "/parts.idx"; }
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

}  // namespace prep::tiling
