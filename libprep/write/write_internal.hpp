// write_internal.hpp — write_package for callers that hand over their blob
// list and may finish it while the writer runs (write_model): internal to
// libprep/write.
#pragma once

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "prep/write.hpp"

namespace prep {

// The blobs of a package, in table order, some of them (`deferred`) made
// only by `complete`, which the writer calls once, on one of its threads,
// while it compresses the others. A deferred blob has its id, type and
// stride from the start and its bytes (and count) after `complete`.
struct PackageSource {
  std::vector<BlobInput> blobs;
  std::vector<size_t> deferred;
  // Fills the deferred blobs and returns the metadata JSON object text.
  std::function<std::string()> complete;
};

// write_package (prep/write.hpp) of `source`. Each blob's `owner` is
// dropped as soon as the blob is compressed (or, stored as is, written), so
// that encoded copies (model_blobs) are freed during the write; the blobs'
// spans must not be read afterwards.
void write_package_consuming(const std::string& path, PackageSource& source,
                             const WriteOptions& options);

// The blob list of model_blobs(model, /*include_empty=*/true), in the same
// order, with the encoded blobs (formats/include/decal/layout.hpp) deferred:
// `encode` makes them. `source.complete` is left to the caller.
struct ModelBlobPlan {
  PackageSource source;
  std::function<void(std::vector<BlobInput>&)> encode;
};
ModelBlobPlan model_blob_plan(const DecalModel& model);

}  // namespace prep
