// prep/manifest.hpp — the manifest: what happened to every input feature
// (kept, repaired, clipped, dropped, and why), and the per-layer counts. Read
// starts it, every later stage adds to it, the report and the package's
// metadata carry it (prep/manifest_json.hpp).
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "prep/manifest_words.hpp"

namespace prep {

// One line of the manifest: what happened to one input feature (or part).
struct ManifestEntry {
  std::string layer;
  int64_t fid = -1;
  int part = -1;  // -1: the whole feature
  ManifestAction action = ManifestAction::dropped;
  std::string reason;  // human-readable: what was wrong / what was done
  double area_before = std::numeric_limits<double>::quiet_NaN();
  double area_after = std::numeric_limits<double>::quiet_NaN();
  // Set for a feature dropped for a per-feature failure (feature_failure.hpp):
  // the stage it failed in; `reason` is then the bare "<what>", and the JSON
  // reason reads "failed in <stage>: <what>" (manifest_words.hpp).
  std::optional<FailureStage> failed_in;
};

// Per-layer accounting. Invariant: read == kept + clipped_away + dropped.
struct LayerCounts {
  std::string layer;
  uint64_t read = 0;          // features read from the source
  uint64_t kept = 0;          // features with at least one part in the package
  uint64_t repaired = 0;      // of kept: changed by a repair
  uint64_t clipped_away = 0;  // entirely outside the extent
  uint64_t dropped = 0;       // unusable; one entry each, with a reason
  uint64_t parts = 0;         // parts after splitting multi-geometries
  uint64_t vertices_in = 0;   // before simplification
  uint64_t vertices_out = 0;  // after simplification
  // Overview levels only (prep/tile.hpp TileLevel::layers): parts left
  // out of the level for being below its min_area / min_length (or
  // collapsing under its simplification). Never written elsewhere.
  uint64_t dropped_small = 0;
  // Overview levels only: holes of the level's kept polygon parts left out
  // for being below its min_area (the part itself stays).
  uint64_t holes_dropped_small = 0;

  // Adds every count of `o` (not the layer name).
  LayerCounts& operator+=(const LayerCounts& o);
};

// The counts of a layer record in formats/SPEC.md §Metadata, in its words
// and order: the one list the package metadata, the report, the tileset
// index and their readers go by (dropped_small, an overview level's, is
// not among them).
inline constexpr std::pair<const char*, uint64_t LayerCounts::*> kLayerCountFields[] = {
    {"read", &LayerCounts::read},
    {"kept", &LayerCounts::kept},
    {"repaired", &LayerCounts::repaired},
    {"clipped_away", &LayerCounts::clipped_away},
    {"dropped", &LayerCounts::dropped},
    {"parts", &LayerCounts::parts},
    {"vertices_in", &LayerCounts::vertices_in},
    {"vertices_out", &LayerCounts::vertices_out}};

inline LayerCounts& LayerCounts::operator+=(const LayerCounts& o) {
  for (const auto& [name, m] : kLayerCountFields) this->*m += o.*m;
  dropped_small += o.dropped_small;
  holes_dropped_small += o.holes_dropped_small;
  return *this;
}

struct Manifest {
  std::vector<LayerCounts> layers;
  std::vector<ManifestEntry> entries;
  std::vector<std::string> notes;  // scene-wide facts ("Z values dropped", "flat terrain")
};

}  // namespace prep
