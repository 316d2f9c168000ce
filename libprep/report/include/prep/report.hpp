// prep/report.hpp — what a build tells about itself: the report (JSON of
// the cleaned scene's frame, layers and manifest, with timings), the
// provenance of its sources, and the metadata a package records beside its
// blobs (formats/SPEC.md "Metadata"). The single-package build (pipeline)
// and the tileset build (tile) both write them.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "prep/features.hpp"
#include "prep/model.hpp"

namespace prep {

// The report of a cleaned scene as JSON (layer counts, manifest entries and
// notes, frame, timings in seconds, output path).
std::string report_json(const SceneFeatures& scene, const std::string& output,
                        const std::vector<std::pair<std::string, double>>& timings,
                        bool package_written);

// Sums every field of the per-layer counts (the report's manifest "totals").
LayerCounts manifest_totals(const Manifest& manifest);

// The manifest's "totals": every count summed over the layers, without "layer".
nlohmann::json totals_json(const Manifest& manifest);

// Provenance: path, size and XXH64 of every local source and the DEM, sorted
// by path (formats/SPEC.md "Metadata").
nlohmann::json provenance_json(const BuildSpec& scene);

// The report as a JSON object (report_json is its text).
nlohmann::json report_object(const SceneFeatures& scene, const std::string& output,
                             const std::vector<std::pair<std::string, double>>& timings,
                             bool package_written);

// Rewrites the source and DEM paths in the manifest's notes and entry
// reasons as a package records them (relative to the scene file's folder),
// so that the package's bytes do not depend on where the checkout is.
void record_manifest_paths(const BuildSpec& scene, Manifest& manifest);

// The package metadata only the build knows (write_model writes frame,
// grid, counts and the manifest itself): the manifest totals, the layers,
// provenance, scene file and build options. Paths are recorded relative to
// the scene file's folder; build_options.dem relative to the folder of
// `package_path` (the package being written; empty: as the scene gives it).
nlohmann::json package_metadata(const BuildSpec& scene, const Manifest& manifest,
                                const nlohmann::json& provenance,
                                const std::string& package_path = {});

}  // namespace prep
