// libprep/evaluate/compact_view.hpp — the v1.3 compact blobs (formats/SPEC.md
// "Compact layout (v1.3)") of a model or a package, decoded into the v1.2
// arrays a StaticView walks. Internal to libprep/evaluate.
#pragma once

#include <cstdint>
#include <span>

#include "prep/evaluate.hpp"

namespace prep {

struct CompactBlobs {
#define PREP_COMPACT_MEMBER(T, name) std::span<const T> name;
  PREP_COMPACT_BLOBS(PREP_COMPACT_MEMBER)
#undef PREP_COMPACT_MEMBER
};

// Sets v's per-cell ranges, BVH ranges and boxes, cell_polys and leaf
// ranges and segments from the compact blobs that are present (a kind
// whose compact blobs are empty keeps what v holds), on v.grid. The decoded
// arrays live in v.storage.
void decode_compact(const CompactBlobs& c, StaticView& v);

}  // namespace prep
