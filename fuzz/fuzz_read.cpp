// fuzz_read — libFuzzer target for the package reader: any byte string must
// give a status, never a crash, leak, out-of-bounds read or UB. Accepted
// packages are walked completely (every blob byte read, index validation,
// typed views) so that a wrong span would be caught by ASan, and their
// decoded sizes must equal package_sizes_from_memory's.
//
// Random mutations almost never survive the checksums, so every input is
// also tried "resealed": with all checksums recomputed over the mutated
// bytes. That lets the fuzzer reach the structural checks and the decoder.
#include <xxhash.h>

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "package_fields.hpp"  // tests/formats: get / put

namespace {

volatile unsigned g_sink = 0;

using decal_test::get;
using decal_test::put;

// Recomputes every checksum whose region lies inside the file.
void reseal(std::vector<std::byte>& f) {
  using H = decal::FileHeader;
  using E = decal::BlobTableEntry;
  const uint64_t n = f.size();
  if (n < sizeof(H)) return;
  const uint64_t entry_size = get<uint32_t>(f, offsetof(H, blob_entry_size));
  const uint64_t count = get<uint32_t>(f, offsetof(H, blob_count));
  const uint64_t table = get<uint64_t>(f, offsetof(H, table_offset));
  if (entry_size >= sizeof(E) && table <= n && count * entry_size <= n - table) {
    for (uint64_t i = 0; i < count; ++i) {
      const uint64_t at = table + i * entry_size;
      const uint64_t off = get<uint64_t>(f, at + offsetof(E, offset));
      const uint64_t stored = get<uint64_t>(f, at + offsetof(E, stored_size));
      if (off <= n && stored <= n - off)
        put<uint64_t>(f, at + offsetof(E, checksum), XXH64(f.data() + off, stored, 0));
    }
    put<uint64_t>(f, offsetof(H, table_checksum), XXH64(f.data() + table, count * entry_size, 0));
  }
  const uint64_t moff = get<uint64_t>(f, offsetof(H, metadata_offset));
  const uint64_t msize = get<uint64_t>(f, offsetof(H, metadata_size));
  if (moff <= n && msize <= n - moff)
    put<uint64_t>(f, offsetof(H, metadata_checksum), XXH64(f.data() + moff, msize, 0));
  const uint64_t hsize = get<uint32_t>(f, offsetof(H, header_size));
  if (hsize >= sizeof(H) && hsize <= n) put<uint64_t>(f, hsize - 8, XXH64(f.data(), hsize - 8, 0));
}

void exercise(std::span<const std::byte> bytes) {
  decal::PackageLayout layout;
  (void)decal::read_layout(bytes, layout);
  // The sizes read from the header and table alone (read_package_sizes):
  // whatever a full read accepts, they accept, with its decoded sizes.
  decal::PackageSizes sizes;
  const decal::Status sized = decal::package_sizes_from_memory(bytes, sizes);
  if (!sized && sized.message.empty()) __builtin_trap();
  decal::OpenOptions options;
  options.max_raw_bytes = uint64_t(64) << 20;  // keep each input's inflation small
  for (bool verify : {true, false}) {
    options.verify_checksums = verify;
    decal::Package p;
    const decal::Status s = decal::Package::from_memory(bytes, p, options);
    if (!s) {
      if (s.message.empty()) __builtin_trap();  // a failure must say why
      continue;
    }
    if (!sized || sizes.blobs.size() != p.blobs().size()) __builtin_trap();
    unsigned sum = 0;
    uint64_t decoded = 0;
    for (size_t i = 0; i < p.blobs().size(); ++i) {
      const decal::BlobView& b = p.blobs()[i];
      if (b.bytes.size() != b.count * b.stride) __builtin_trap();
      if (sizes.blobs[i].id != b.id || sizes.blobs[i].raw_bytes != b.bytes.size()) __builtin_trap();
      decoded += b.bytes.size();
      for (std::byte x : b.bytes) sum += static_cast<unsigned>(x);
    }
    if (decoded != sizes.raw_bytes) __builtin_trap();
    for (char c : p.metadata_json()) sum += static_cast<unsigned char>(c);
    g_sink = sum;  // keeps the reads above from being optimised away
    (void)decal::validate_indices(p);
    (void)p.array<decal::BlobId::line_props>();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data), size);
  exercise(bytes);
  std::vector<std::byte> sealed(bytes.begin(), bytes.end());
  reseal(sealed);
  exercise(sealed);
  return 0;
}
