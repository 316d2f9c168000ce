// What the files of libprep/pipeline share (not a public header).
#pragma once

#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>

#include "prep/pipeline.hpp"
#include "prep/scene.hpp"

namespace prep::pipeline_internal {

// Writes a small text file whole, through a temp file and a rename, so that
// a reader never sees half of it. Throws output_error naming the path.
void write_text_file(const std::string& path, const std::string& text);

// The package metadata only the pipeline knows (write_model writes frame,
// grid, counts and the manifest itself): the manifest totals, the layers,
// provenance, scene file and build options.
nlohmann::json package_metadata(const SceneSpec& scene, const Manifest& manifest,
                                const nlohmann::json& provenance);

// What write_tileset() did, for the report.
struct TilesetOutcome {
  size_t tiles = 0;   // packages in the index
  size_t built = 0;   // of those, built by this run
  size_t reused = 0;  // of those, kept from an earlier run (they verified)
  size_t empty = 0;   // tiles reached by a part's box but left with no part
  uint64_t bytes = 0;
  double margin = 0;
};

// Stage 3b and the rest of the pipeline for a tileset (prep/tile.hpp):
// cuts the cleaned scene into tiles, builds and writes each tile's package
// (request.jobs side by side), then manifest.json, then tileset.json last.
TilesetOutcome write_tileset(const SceneSpec& spec, const SceneFeatures& scene,
                             const BuildRequest& request, const nlohmann::json& provenance);

}  // namespace prep::pipeline_internal
