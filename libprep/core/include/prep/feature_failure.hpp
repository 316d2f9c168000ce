// prep/feature_failure.hpp — per-feature failures and skip_failures
// (`decalprep build --skip-failures`, after ogr2ogr -skipfailures).
//
// A per-feature failure is a feature the pipeline cannot carry through a
// stage although the rest of the input is fine: a geometry OGR cannot
// decode, a vertex PROJ cannot transform into the scene frame, a GEOS error
// or a repair that stays invalid, a vertex the build stage cannot hold.
// It is not an ordinary drop (no geometry, zero area, a type the layer kind
// cannot draw): those are expected and never stop a build.
//
// Stages record a failure as the feature's drop reason (the bare "<what>")
// together with the stage it failed in (SourceFeature::failed_in,
// ManifestEntry::failed_in, a FailureStage of manifest_words.hpp); parallel
// stages then call the stage's own check after their loop, in input order, so
// the failure reported without skip_failures is the first one in input order
// at any thread count. Without skip_failures the first failure stops the
// build: fail_feature() (an input_error, exit code 3) names the
// stage, file, layer, fid and the bad value. With skip_failures the feature
// is dropped, its manifest entry (ManifestAction::dropped, failed_in set)
// carries the reason, written "failed in <stage>: <what>", and the build
// exits with ExitCode::partial.
#pragma once

#include <cstdint>
#include <string>

#include "prep/error.hpp"
#include "prep/features.hpp"
#include "prep/stage_error.hpp"

namespace prep {

// True for a manifest entry of a feature dropped for a failure.
inline bool is_skipped_failure(const ManifestEntry& e) {
  return e.action == ManifestAction::dropped && e.failed_in.has_value();
}

// Throws the error that stops a build at a failing feature (skip_failures
// off), an input_error:
//   "<stage>: <source> layer '<layer>' fid <fid>: <what> (--skip-failures drops ...)"
[[noreturn]] inline void fail_feature(FailureStage stage, const std::string& source,
                                      const std::string& layer, int64_t fid,
                                      const std::string& what) {
  fail<input_error>(word(stage), source + " layer '" + layer + "' fid " + std::to_string(fid) +
                                     ": " + what +
                                     " (--skip-failures drops failing features, records them in "
                                     "the manifest and exits 4)");
}

}  // namespace prep
