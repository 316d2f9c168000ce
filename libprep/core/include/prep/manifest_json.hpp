// prep/manifest_json.hpp — one JSON form of a manifest entry, shared by the
// package's manifest_entries blob (libprep/write) and the build report
// (libprep/pipeline), so that both say the same thing in the same words.
#pragma once

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "prep/error.hpp"
#include "prep/features.hpp"
#include "prep/manifest_words.hpp"
#include "prep/stage_error.hpp"

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
          {"action", word(e.action)},
          {"reason", reason_text(e.failed_in, e.reason)},
          {"area_before", number_or_null(e.area_before)},
          {"area_after", number_or_null(e.area_after)}};
}

// The counts of one layer (or, without "layer", their totals) in the words
// formats/SPEC.md §Metadata lists, for the package metadata and the report
// alike.
inline nlohmann::json layer_counts_json(const LayerCounts& c) {
  nlohmann::json j = {{"layer", c.layer}};
  for (const auto& [name, m] : kLayerCountFields) j[name] = c.*m;
  return j;
}

// The inverse of manifest_entry_json(), for code that reads a package's
// manifest_entries or a build report back. Throws format_error for an
// action word formats/SPEC.md does not list.
inline ManifestEntry manifest_entry_from_json(const nlohmann::json& j) {
  ManifestEntry e;
  e.layer = j.at("layer").get<std::string>();
  e.fid = j.at("fid").get<int64_t>();
  e.part = j.at("part").get<int>();
  const std::string action = j.at("action").get<std::string>();
  const std::optional<ManifestAction> a = manifest_action_from_word(action);
  if (!a)
    fail<format_error>(kNoStage, "manifest entry of layer '" + e.layer + "' fid " +
                                     std::to_string(e.fid) + ": unknown action '" + action + "'");
  e.action = *a;
  ParsedReason r = parse_reason_text(j.at("reason").get<std::string>());
  e.failed_in = r.failed_in;
  e.reason = std::move(r.reason);
  auto number = [&](const char* key) {
    const nlohmann::json& v = j.at(key);
    return v.is_null() ? std::numeric_limits<double>::quiet_NaN() : v.get<double>();
  };
  e.area_before = number("area_before");
  e.area_after = number("area_after");
  return e;
}

}  // namespace prep
