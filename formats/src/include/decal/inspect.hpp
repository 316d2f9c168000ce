// decal/inspect.hpp — lower-level views of a .decals package for tools and
// loaders: the raw header and blob table (for `decalprep info`), and the
// index checks that need the blob contents (for `verify` and the GL loader).
//
// Like reader.hpp, nothing here throws (std::bad_alloc aside); failures are
// a Status with a one-line message. Depends on the standard library only.
#pragma once

#include <span>
#include <string_view>
#include <vector>

#include "decal/format.hpp"
#include "decal/reader.hpp"

namespace decal {

// Header and blob table of a package, as stored.
struct PackageLayout {
  FileHeader header{};
  std::vector<BlobTableEntry> entries;  // in table (= file) order
};

// Validates the header, the blob table and the placement of every region of
// `file` (everything Package::open checks except blob checksums and
// decoding) and fills `out`. On failure `out` is left empty.
Status read_layout(std::span<const std::byte> file, PackageLayout& out);

// Checks, from the blobs alone, that every index a blob holds points inside
// the blob it indexes (vertex indices < vertex count, (first, count) ranges
// inside their list blob, node types and child offsets in range, (prev, next)
// links in range, reserved record fields zero) and that blobs which run in
// parallel have equal counts. Absent or empty blobs are treated as empty.
// Returns the first problem found, naming the blob, element and value.
Status validate_indices(const Package& package);

// "none", "zstd", or "" for an unknown codec id.
constexpr std::string_view codec_name(uint32_t codec) {
  switch (static_cast<CodecId>(codec)) {
    case CodecId::none: return "none";
    case CodecId::zstd: return "zstd";
  }
  return "";
}

}  // namespace decal
