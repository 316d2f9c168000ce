// decal/inspect.hpp — lower-level views of a .decals package for tools and
// loaders: the raw header and blob table (for `decalprep info`), and the
// structural check of the blob contents (for `verify`, the evaluator and the
// GL loader).
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

// Decoded blob bytes, as a loader holds them (from a Package, or from a
// model in memory).
struct BlobBytes {
  BlobId id{};
  uint64_t count = 0;                // elements
  std::span<const std::byte> bytes;  // count * catalogue stride
};

// The decal grid (thesis Eq. 4.3/4.4), in quanta relative to the origin.
struct Grid {
  int64_t origin_x = 0, origin_y = 0;
  int64_t cell_w = 1, cell_h = 1;
  uint32_t nx = 0, ny = 0;
};

struct ValidateOptions {
  const Grid* grid = nullptr;  // when known: per-cell blobs hold one element per cell
  bool newer_minor = false;    // the file is of a newer minor version: reserved fields are ignored
};

// The structural check of decoded blobs, the one every consumer runs (the
// `verify` command, the CPU evaluator, the GL loader): sizes against the
// catalogue stride; every index inside the blob it indexes (vertex, line,
// polygon, node, hole, box, LOD point), every (first, count) range inside
// its list; quad-tree node types 0..3 with children after their parent (so
// every descent ends); per-cell BVHs that are full binary trees over their
// list; blobs that run in parallel of equal counts; dynamic lines as
// consecutive vertex runs; reserved record fields zero; with a grid, its
// int32 range and one per-cell element per cell. Unknown ids are skipped;
// absent blobs are empty. Returns the first problem, naming the blob,
// element and value. Thread-safe; reads nothing outside `blobs`.
Status validate_blobs(std::span<const BlobBytes> blobs, const ValidateOptions& options = {});

// The known blobs of an opened package, as BlobBytes (views into it).
std::vector<BlobBytes> blobs_of(const Package& package);

// validate_blobs over an opened package (newer_minor from its header).
Status validate_indices(const Package& package, const Grid* grid = nullptr);

// "none", "zstd", or "" for an unknown codec id.
constexpr std::string_view codec_name(uint32_t codec) {
  switch (static_cast<CodecId>(codec)) {
    case CodecId::none: return "none";
    case CodecId::zstd: return "zstd";
  }
  return "";
}

}  // namespace decal
