// prep/manifest_json.hpp — one JSON form of a manifest entry, shared by the
// package's manifest_entries blob (libprep/write) and the build report
// (libprep/pipeline), so that both say the same thing in the same words.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>

#include "prep/scene.hpp"

namespace prep {

// JSON has no NaN: a value that was not measured is null.
inline nlohmann::json number_or_null(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

// {layer, fid, part, action, reason, area_before, area_after}; see SPEC.md
// §Blob catalogue, manifest_entries.
inline nlohmann::json manifest_entry_json(const ManifestEntry& e) {
  return {{"layer", e.layer},
          {"fid", e.fid},
          {"part", e.part},
          {"action", e.action},
          {"reason", e.reason},
          {"area_before", number_or_null(e.area_before)},
          {"area_after", number_or_null(e.area_after)}};
}

}  // namespace prep
