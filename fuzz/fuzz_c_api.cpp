// fuzz_c_api — libFuzzer target for the C API (decal/decal.h, libdecal):
// any byte string given to decal_open_memory must give a status, never a
// crash, leak, out-of-bounds access or UB. A failure must carry its code
// and a message; an accepted package is walked through the C API alone:
// every blob's info, its name and id found again, every blob decoded into
// an exactly sized buffer (after a size query) and read in place, the
// metadata read to its terminating NUL.
//
// As in fuzz_read, every input is also tried resealed (checksums
// recomputed, tests/formats/reseal.hpp) so that mutations reach the
// structural checks, the decoder and the index check.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "decal/decal.h"
#include "reseal.hpp"  // tests/formats

namespace {

volatile unsigned g_sink = 0;

void walk(const decal_package* p) {
  unsigned sum = 0;
  const char* text = nullptr;
  size_t size = 0;
  if (decal_metadata(p, &text, &size, nullptr) != DECAL_OK || text[size] != '\0') __builtin_trap();
  for (size_t i = 0; i < size; ++i) sum += static_cast<unsigned char>(text[i]);
  std::vector<unsigned char> buffer;
  for (uint32_t i = 0; i < decal_blob_count(p); ++i) {
    decal_blob_info info;
    if (decal_blob_info_at(p, i, &info, nullptr) != DECAL_OK) __builtin_trap();
    if (info.raw_size != info.count * info.stride) __builtin_trap();
    uint32_t found = 0;
    // Ids and names are unique in an accepted package (formats/SPEC.md
    // "Validation" step 8).
    if (decal_find_blob(p, info.name, &found, nullptr) != DECAL_OK || found != i) __builtin_trap();
    if (decal_find_blob_id(p, info.id, &found, nullptr) != DECAL_OK || found != i) __builtin_trap();
    size_t needed = 0;
    const decal_status query = decal_blob_read(p, i, nullptr, 0, &needed, nullptr);
    if (needed != info.raw_size || (query == DECAL_OK) != (needed == 0)) __builtin_trap();
    buffer.assign(needed, 0);
    if (decal_blob_read(p, i, buffer.data(), buffer.size(), &needed, nullptr) != DECAL_OK)
      __builtin_trap();
    const void* data = nullptr;
    size_t in_place = 0;
    if (decal_blob_data(p, i, &data, &in_place, nullptr) != DECAL_OK || in_place != needed ||
        (needed && std::memcmp(data, buffer.data(), needed) != 0))
      __builtin_trap();
    for (unsigned char c : buffer) sum += c;
  }
  g_sink = sum;  // keeps the reads above from being optimised away
}

void exercise(const std::vector<std::byte>& bytes) {
  decal_open_options options{};
  options.max_raw_size = uint64_t(64) << 20;  // keep each input's inflation small
  for (uint32_t flags : {0u, unsigned(DECAL_OPEN_SKIP_INDEX_CHECK)}) {
    options.flags = flags;
    decal_package* p = nullptr;
    decal_error error;
    const decal_status s = decal_open_memory(bytes.data(), bytes.size(), &options, &p, &error);
    if (s != DECAL_OK) {
      // A failure says what and why, and hands out nothing.
      if (p || error.code != s || error.message[0] == '\0') __builtin_trap();
      continue;
    }
    walk(p);
    decal_close(p);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<std::byte> bytes(size);
  if (size) std::memcpy(bytes.data(), data, size);
  exercise(bytes);
  decal_test::reseal(bytes);
  exercise(bytes);
  return 0;
}
