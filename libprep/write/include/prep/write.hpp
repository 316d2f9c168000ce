// prep/write.hpp — stage 5: lay out, compress, checksum and atomically write
// a .decals package (formats/SPEC.md).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "decal/format.hpp"
#include "prep/features.hpp"
#include "prep/model.hpp"

namespace prep {

class Progress;  // prep/progress.hpp

enum class Codec { none, zstd };

struct WriteOptions {
  Codec codec = Codec::zstd;
  // Level 2 is the knee of the size/CPU curve (bench/zstd_levels.py,
  // bench/report/zstd_levels.csv, bench/REPORT.md "zstd level"; sizes exact,
  // CPU seconds of the 1-thread write): against level 1 it makes packages
  // 8.4% smaller for 1.08-1.20x the CPU; level 3 only 1.2-2.6% smaller again
  // for 1.18-1.39x (1.6x for the compression alone at 10^7 vertices, whose
  // largest blob, the critical path on two threads, takes 1.7x as long),
  // level 4 nothing, level 6 6-7% for 2-3.8x, level 19 26-28% for 50-130x.
  int zstd_level = 2;
  // Stage "write", counted in blob bytes compressed and checksummed. Null:
  // silent. Output only: the package bytes do not depend on it.
  Progress* progress = nullptr;
  // write_model first runs the structural check `decalprep verify` runs
  // (decal::validate_blobs) and writes nothing when it fails (output_error).
  // Tests that make hostile packages on purpose turn it off.
  bool check_blobs = true;
};

// One blob to write: `count` elements of `stride` bytes at `bytes`.
struct BlobInput {
  decal::BlobId id;
  decal::ElementType type;
  uint32_t stride;
  uint64_t count;
  std::span<const std::byte> bytes;   // count * stride
  std::shared_ptr<const void> owner;  // keeps `bytes` alive when the blob owns them
};

// Writes a package atomically: temp file in the target directory, fsync,
// rename. On any failure throws output_error and leaves `path` as it was,
// with no temp file behind. Not thread-safe for the same path. The blobs are
// compressed and checksummed in parallel (oneTBB, one blob per task, as many
// threads as a tbb::global_control allows: `--threads`); each is one
// single-threaded zstd frame, so the bytes do not depend on the thread count.
void write_package(const std::string& path, const std::string& metadata_json,
                   std::span<const BlobInput> blobs, const WriteOptions& options = {});

// The blob list of a model, in catalogue order: its own arrays, which hold
// the layout of the current format version (prep/model.hpp); superseded ids
// are not listed. Empty arrays are included as empty blobs only when
// `include_empty`.
std::vector<BlobInput> model_blobs(const DecalModel& model, bool include_empty = false);
// model_blobs(model, true), taking the arrays: each blob owns its array
// (`owner`), and the model's blob arrays are left empty.
std::vector<BlobInput> take_model_blobs(DecalModel& model);

// Writes a model with its metadata chunk. `extra_metadata_json` is an object
// merged into the metadata (build options, provenance, timings).
void write_model(const std::string& path, const DecalModel& model,
                 const std::string& extra_metadata_json, const WriteOptions& options = {});
// The same bytes, consuming the model: each array is freed as soon as its
// blob is compressed (or, stored, written), so the writer holds the
// compressed frames in place of the arrays rather than on top of them.
void write_model(const std::string& path, DecalModel&& model,
                 const std::string& extra_metadata_json, const WriteOptions& options = {});

// ------------------------------------------------- report and metadata --

// what a build tells about itself: the report (JSON of
// the cleaned scene's frame, layers and manifest, with timings), the
// provenance of its sources, and the metadata a package records beside its
// blobs (formats/SPEC.md "Metadata"). The single-package build (pipeline)
// and the tileset build (tile) both write them.

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
