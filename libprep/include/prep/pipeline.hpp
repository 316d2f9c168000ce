// prep/pipeline.hpp — the whole build: read -> project -> clean -> build ->
// write, with the JSON report (`decalprep build`).
#pragma once

#include <string>

#include "prep/read.hpp"
#include "prep/scene.hpp"

namespace prep {

struct BuildRequest {
  std::string output;       // package path; written atomically
  std::string report;       // JSON report path; empty: none
  bool dry_run = false;     // stop after clean: write the report, no package
  bool compress = true;
  int zstd_level = 3;
  // --max-memory in bytes (0: none): the build stops with resource_error
  // (exit 6) as soon as an estimate of its peak RSS exceeds it
  // (prep/memory_estimate.hpp); no package is written.
  uint64_t max_memory = 0;
  // Progress of every stage, in pipeline order: read, project, clean,
  // build.lines, build.quadtrees, build.grid, build.cells, build.dynamic,
  // write (prep/progress.hpp). Null: silent. Output only.
  Progress* progress = nullptr;
};

struct BuildResult {
  SceneFeatures scene;      // what clean produced
  std::string report_json;  // the report (also written to request.report)
  bool package_written = false;
  // Features dropped for a per-feature failure under scene.skip_failures
  // (prep/feature_failure.hpp); > 0 makes the build partial (exit code 4).
  size_t skipped_failures = 0;
};

// Runs the pipeline. Throws prep::error subclasses; on any failure no
// package is written at request.output (the writer is atomic and runs last),
// and request.report (if set) receives {"error", "exit_code",
// "package_written": false} before the exception propagates.
// Throws error(ExitCode::internal) when a package is asked for but this build
// has no build/write stage linked (use dry_run).
BuildResult run_build(const SceneSpec& scene, const BuildRequest& request);

// The report of a cleaned scene as JSON (layer counts, manifest entries and
// notes, frame, timings in seconds, output path).
std::string report_json(const SceneFeatures& scene, const std::string& output,
                        const std::vector<std::pair<std::string, double>>& timings,
                        bool package_written);

}  // namespace prep
