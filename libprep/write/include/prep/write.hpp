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

}  // namespace prep
