// The work folder of a tileset build (not a public header): what the
// prepare step leaves on disk for the tile step and the finalize step
// (ARCHITECTURE.md "3b. tile", formats/SPEC.md "Tilesets": DIR/.work).
//
//   DIR/.work/parts.bin      every cleaned part, back to back in scene
//                            order (tileset_work.cpp, PartHead),
//                            coordinates relative to the scene origin in
//                            the frame CRS
//   DIR/.work/boxes.bin      each part's kind, place in parts.bin and box,
//                            in order (BoxRecord, part_index.hpp)
//   DIR/.work/parts.idx      the packed R-tree of those boxes (part_index.hpp)
//   DIR/.work/entries.json   the manifest entries, already in manifest.json's
//                            form (clean's, in layer order)
//   DIR/.work/read_entries.json  the read stage's entries (they follow)
//   DIR/.work/plan.json      frame, extent, margins, per-layer counts,
//                            notes, provenance, entry count, tile keys
//   DIR/.work/tiles/<x>_<y>.json  what the tile step made of each tile
//   DIR/.work/tiles/L<L>_<x>_<y>.json  the same for overview level L
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "prep/features.hpp"
#include "prep/tile.hpp"
#include "tileset_internal.hpp"

namespace prep::tiling {

// Part kinds as the intermediate stores them (and the order of the scene's
// vectors: polygons, static lines, dynamic lines).
enum class PartKind : int { polygon = 0, line = 1, dynamic_line = 2 };

// Writes cleaned parts to parts.bin in scene order, chunk by chunk (so the
// file's order within each kind is the scene's, which a tile restores),
// their boxes to boxes.bin, and keeps the running extent and the widest
// static stroke. Throws output_error naming the file.
class PartWriter {
 public:
  explicit PartWriter(const WorkPaths& paths);
  ~PartWriter();
  PartWriter(const PartWriter&) = delete;
  PartWriter& operator=(const PartWriter&) = delete;

  // Appends a chunk's polygons, lines and dynamic lines (in that order
  // within each kind; `chunk.layers` gives the outline modes).
  void add(const SceneFeatures& chunk);
  // Closes the files and writes the box index (parts.idx).
  void close();

  // The box of every kept shell and line so far, kept_extent()'s way
  // (Extent{} when nothing is kept).
  Extent extent() const;
  double half_width() const { return half_width_; }
  uint64_t parts() const { return seq_[0] + seq_[1] + seq_[2]; }
  uint64_t parts(PartKind kind) const { return seq_[static_cast<int>(kind)]; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  uint64_t seq_[3] = {0, 0, 0};
  Extent box_{INFINITY, INFINITY, -INFINITY, -INFINITY};
  double half_width_ = 0;
};

// The most tiles one level's plan may have: far above what tileset.json's
// size limit lets an index list (formats/SPEC.md "Tilesets"), low enough that
// planning them takes seconds.
inline constexpr size_t kMaxPlannedTiles = 2'000'000;

// The tile keys the parts of boxes.bin reach (tile_range with the plan's
// margins), in key order. More than kMaxPlannedTiles: resource_error.
std::vector<TileKey> planned_tiles(const WorkPaths& paths, const TilePlan& plan);

// What an overview level does to each part a tile's window holds, as the
// part is read (tileset_build.cpp), so that a tile holds only what it
// keeps: a level tile near the top has the whole scene in its window.
// False drops the part. Called once for each part that reaches the tile.
class PartFilter {
 public:
  virtual ~PartFilter() = default;
  virtual bool polygon(ScenePolygon& p) = 0;
  virtual bool line(SceneLine& l, bool dynamic) = 0;
};

// Reads the parts a tile's plan entry holds from parts.bin: every part whose
// box reaches `key` (tile_range, as tile_plan places it), in scene order,
// found through parts.idx and read with pread. Every record is checked
// against its box record and the file's size. One reader per thread.
class PartReader {
 public:
  explicit PartReader(const WorkPaths& paths);
  ~PartReader();
  PartReader(const PartReader&) = delete;
  PartReader& operator=(const PartReader&) = delete;
  // Fills `scene`'s polygons, lines and dynamic lines (cleared first); with
  // a `filter`, only the parts it keeps, as it leaves them.
  void read_tile(const TilePlan& plan, const TileKey& key, SceneFeatures& scene,
                 PartFilter* filter = nullptr);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Appends manifest entries to a file in the form they take inside
// manifest.json's "entries" array (nlohmann dump(1), two levels deep).
class EntryWriter {
 public:
  explicit EntryWriter(const std::string& path);
  ~EntryWriter();
  EntryWriter(const EntryWriter&) = delete;
  EntryWriter& operator=(const EntryWriter&) = delete;
  void add(const ManifestEntry& e);
  void close();
  uint64_t count() const { return count_; }

 private:
  std::FILE* f_ = nullptr;
  std::string path_;
  uint64_t count_ = 0;
};

// Writes manifest.json ({"entries": [...]} as nlohmann's dump(1) writes it)
// from the entry files, in order, streaming. Atomic (temp file and rename).
void write_manifest_from(const std::vector<std::string>& entry_files, uint64_t entries,
                         const std::string& path);

// The plan.json document and back.
nlohmann::json frame_to_json(const SceneFrame& f);
SceneFrame frame_from_json(const nlohmann::json& j);
nlohmann::json counts_to_json(const std::vector<LayerCounts>& layers);
std::vector<LayerCounts> counts_from_json(const nlohmann::json& j);

// Removes `path` and everything under it (the work folder); errors ignored.
void remove_tree(const std::string& path);

}  // namespace prep::tiling
