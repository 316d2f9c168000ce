// fuzz_read — libFuzzer target for the package reader: any byte string must
// give a status, never a crash, leak, out-of-bounds read or UB. Accepted
// packages are walked completely (every blob byte read, index validation,
// typed views) so that a wrong span would be caught by ASan, and their
// decoded sizes must equal package_sizes_from_memory's.
//
// Random mutations almost never survive the checksums, so every input is
// also tried "resealed": with all checksums recomputed over the mutated
// bytes. That lets the fuzzer reach the structural checks and the decoder.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "reseal.hpp"  // tests/formats

namespace {

volatile unsigned g_sink = 0;

using decal_test::reseal;

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
