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

// The blobs of a package, in table order, and `complete`, which the writer
// calls once, on one of its threads, while it compresses the blobs.
struct PackageSource {
  std::vector<BlobInput> blobs;
  // Returns the metadata JSON object text.
  std::function<std::string()> complete;
};

// write_package (prep/write.hpp) of `source`. Each blob's `owner` is
// dropped as soon as the blob is compressed (or, stored as is, written), so
// that copies a caller made are freed during the write; the blobs' spans
// must not be read afterwards.
void write_package_consuming(const std::string& path, PackageSource& source,
                             const WriteOptions& options);

}  // namespace prep
