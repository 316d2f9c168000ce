// prep/write.hpp — stage 5: lay out, compress, checksum and atomically write
// a .decals package (formats/SPEC.md).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "decal/format.hpp"
#include "prep/model.hpp"

namespace prep {

class Progress;  // prep/progress.hpp

enum class Codec { none, zstd };

struct WriteOptions {
  Codec codec = Codec::zstd;
  // Level 3 is the knee of the size/time curve (bench/zstd_levels.py,
  // bench/report/zstd_levels.csv: 10^6 synthetic polygon vertices, Monaco;
  // sizes exact, times of one run on a shared 2-core machine): against
  // level 1 it makes packages 9-12% smaller for at most 1.5x the write
  // time; level 6 makes them only 4% smaller again for another 1.9-2.3x,
  // levels 9 and 12 at most 2% more, and 19 23-25% smaller at 40-60x.
  int zstd_level = 3;
  // Stage "write", counted in blob bytes compressed and checksummed. Null:
  // silent. Output only: the package bytes do not depend on it.
  Progress* progress = nullptr;
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

// The blob list of a model, in catalogue order, in the layout of the current
// format version: the model's per-cell ranges and leaf segments (the v1.2
// layout the model and the evaluator work in) encoded as the v1.3 blobs
// (decal/layout.hpp), which own their bytes; superseded ids are not listed.
// Empty arrays are included as empty blobs only when `include_empty`.
std::vector<BlobInput> model_blobs(const DecalModel& model, bool include_empty = false);

// Writes a model with its metadata chunk. `extra_metadata_json` is an object
// merged into the metadata (build options, provenance, timings).
void write_model(const std::string& path, const DecalModel& model,
                 const std::string& extra_metadata_json, const WriteOptions& options = {});

}  // namespace prep
