// prep/manifest_words.hpp — the manifest's closed vocabularies and the one
// place they turn into the JSON words of the package's manifest_entries blob
// and the build report (formats/SPEC.md §Blob catalogue, manifest_entries),
// and back.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace prep {

// What happened to a feature (or part); `action` in the manifest.
enum class ManifestAction {
  repaired,      // kept, changed by a repair (reason: what was done)
  part_dropped,  // one part of a kept feature left out (reason: why)
  dropped,       // the whole feature left out (reason: why)
  clipped_away,  // entirely outside the scene extent
  note,          // kept; a fact about it (e.g. no LOD segments)
};

// The stage a per-feature failure happened in (prep/feature_failure.hpp).
enum class FailureStage { read, project, clean, build };

inline const char* word(ManifestAction a) {
  switch (a) {
    case ManifestAction::repaired: return "repaired";
    case ManifestAction::part_dropped: return "part_dropped";
    case ManifestAction::dropped: return "dropped";
    case ManifestAction::clipped_away: return "clipped_away";
    case ManifestAction::note: return "note";
  }
  return "?";
}

inline const char* word(FailureStage s) {
  switch (s) {
    case FailureStage::read: return "read";
    case FailureStage::project: return "project";
    case FailureStage::clean: return "clean";
    case FailureStage::build: return "build";
  }
  return "?";
}

inline std::optional<ManifestAction> manifest_action_from_word(std::string_view w) {
  for (ManifestAction a :
       {ManifestAction::repaired, ManifestAction::part_dropped, ManifestAction::dropped,
        ManifestAction::clipped_away, ManifestAction::note})
    if (w == word(a)) return a;
  return std::nullopt;
}

inline std::optional<FailureStage> failure_stage_from_word(std::string_view w) {
  for (FailureStage s :
       {FailureStage::read, FailureStage::project, FailureStage::clean, FailureStage::build})
    if (w == word(s)) return s;
  return std::nullopt;
}

// The manifest reason of a feature dropped for a per-feature failure:
// "failed in <stage>: <what>"; any other reason is written as it is.
inline constexpr std::string_view kFailedInPrefix = "failed in ";
// "failed in <stage>", the part of such a reason that names the stage.
inline std::string failure_label(FailureStage stage) {
  return std::string(kFailedInPrefix) + std::string(word(stage));
}
inline std::string reason_text(const std::optional<FailureStage>& failed_in,
                               const std::string& reason) {
  if (!failed_in) return reason;
  return failure_label(*failed_in) + ": " + reason;
}

// The inverse of reason_text(): the stage (if the reason names a failure)
// and the bare reason.
struct ParsedReason {
  std::optional<FailureStage> failed_in;
  std::string reason;
};
inline ParsedReason parse_reason_text(const std::string& text) {
  const std::string_view prefix = kFailedInPrefix;
  if (text.rfind(prefix, 0) == 0) {
    const size_t colon = text.find(": ", prefix.size());
    if (colon != std::string::npos) {
      const auto stage = failure_stage_from_word(
          std::string_view(text).substr(prefix.size(), colon - prefix.size()));
      if (stage) return {stage, text.substr(colon + 2)};
    }
  }
  return {std::nullopt, text};
}

}  // namespace prep
