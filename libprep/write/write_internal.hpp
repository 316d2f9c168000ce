// write_internal.hpp — write_package for callers that hand over their blob
// list (write_model): internal to libprep/write.
#pragma once

#include <string>
#include <vector>

#include "prep/write.hpp"

namespace prep {

// write_package (prep/write.hpp), which drops each blob's `owner` as soon as
// the blob is compressed (or, stored as is, written), so that encoded copies
// (model_blobs) are freed during the write; `blobs` is left with spans that
// must not be read.
void write_package_consuming(const std::string& path, const std::string& metadata_json,
                             std::vector<BlobInput>& blobs, const WriteOptions& options);

}  // namespace prep
