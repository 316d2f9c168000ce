// reseal.hpp — recomputes every checksum of a (mutated) package image whose
// region lies inside it, so that a mutation reaches the structural checks
// and the decoder instead of stopping at a checksum. Header-only (xxHash and
// package_fields.hpp), shared by the fuzz targets (fuzz/fuzz_read.cpp,
// fuzz/fuzz_c_api.cpp) and the C API's hostile-input test.
#pragma once

#include <xxhash.h>

#include <cstddef>
#include <cstdint>
#include <vector>

#include "decal/format.hpp"
#include "package_fields.hpp"

namespace decal_test {

inline void reseal(std::vector<std::byte>& f) {
  using H = decal::FileHeader;
  using E = decal::BlobTableEntry;
  const uint64_t n = f.size();
  if (n < sizeof(H)) return;
  // Widened to 64 bits so that count * entry_size cannot wrap.
  const uint64_t entry_size = get<uint32_t>(f, offsetof(H, blob_entry_size));
  const uint64_t count = get<uint32_t>(f, offsetof(H, blob_count));
  const auto table = get<uint64_t>(f, offsetof(H, table_offset));
  if (entry_size >= sizeof(E) && table <= n && count * entry_size <= n - table) {
    for (uint64_t i = 0; i < count; ++i) {
      const uint64_t at = table + i * entry_size;
      const auto off = get<uint64_t>(f, at + offsetof(E, offset));
      const auto stored = get<uint64_t>(f, at + offsetof(E, stored_size));
      if (off <= n && stored <= n - off)
        put<uint64_t>(f, at + offsetof(E, checksum), XXH64(f.data() + off, stored, 0));
    }
    put<uint64_t>(f, offsetof(H, table_checksum), XXH64(f.data() + table, count * entry_size, 0));
  }
  const auto moff = get<uint64_t>(f, offsetof(H, metadata_offset));
  const auto msize = get<uint64_t>(f, offsetof(H, metadata_size));
  if (moff <= n && msize <= n - moff)
    put<uint64_t>(f, offsetof(H, metadata_checksum), XXH64(f.data() + moff, msize, 0));
  const uint64_t hsize = get<uint32_t>(f, offsetof(H, header_size));
  if (hsize >= sizeof(H) && hsize <= n) put<uint64_t>(f, hsize - 8, XXH64(f.data(), hsize - 8, 0));
}

}  // namespace decal_test
