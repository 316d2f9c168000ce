// fixtures.hpp — packages for the format tests, the seed-corpus generator
// and the fuzzer seeds. Everything is generated from code; no hand-made bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "decal/format.hpp"
#include "package_fields.hpp"  // get / put
#include "prep/model.hpp"
#include "prep/write.hpp"
#include "v12_cells.hpp"

namespace decal_test {

// A small model with every blob non-empty and every index consistent
// (validate_indices passes): 2 cells, 2 static lines, an exterior polygon
// with one hole, BVHs, 2 dynamic lines and one LOD line.
prep::DecalModel small_model();
// small_model()'s per-cell lists and BVHs in the v1.2 layout (plain ranges
// and full boxes), which it stores in the v1.3 arrays with
// prep::test::set_cells.
prep::test::V12Cells small_model_cells();

// Writes `model` with write_model and returns the file's bytes.
std::vector<std::byte> model_package_bytes(const prep::DecalModel& model,
                                           const prep::WriteOptions& options,
                                           const std::string& extra_metadata_json = "");

std::vector<std::byte> read_file(const std::string& path);
void write_file(const std::string& path, const std::vector<std::byte>& bytes);

// A fresh empty directory under the system temp dir, removed by the caller.
std::string make_temp_dir(const std::string& tag);

// Byte offset of blob table entry `i`.
size_t entry_at(size_t i);

// Recomputes the table, metadata and header checksums after a test edited
// the image, so that the reader's structural checks (not the checksums) are
// what must reject the edit.
void reseal(std::vector<std::byte>& f);

// A named hostile variant of a package image and a fragment its rejection
// message must contain ("" when any message will do).
struct Hostile {
  std::string name;
  std::vector<std::byte> bytes;
  std::string expect;
  bool structure_valid = false;  // Package::open accepts it; validate_indices must not
};

// The hostile package cases built from `good`, the image of
// small_model() written with zstd: truncation, zero length, not a package,
// unknown major version, offsets past the end, overlapping blobs, count x
// stride overflow, bit flips, bad indices and more. Resealed where needed so
// that the structural check, not a checksum, is what must catch them.
std::vector<Hostile> hostile_variants(const std::vector<std::byte>& good);

// The fuzz seed corpus (fuzz/corpus/read/): file name -> bytes. Small
// valid packages plus every hostile variant.
std::vector<std::pair<std::string, std::vector<std::byte>>> seed_corpus();

// A blob the writer tests own: its table fields and its element bytes.
struct OwnedBlob {
  decal::BlobId id;
  decal::ElementType type;
  uint32_t stride;
  std::vector<std::byte> bytes;
  uint64_t count() const { return bytes.size() / stride; }
  prep::BlobInput input() const { return {id, type, stride, count(), bytes}; }
};

// `n` elements of `stride` bytes, random but reproducible from `seed`: a
// random walk of 32-bit words (compressible like coordinates), random bytes
// after the last whole word.
inline OwnedBlob walk_blob(decal::BlobId id, decal::ElementType type, uint32_t stride, uint64_t n,
                           uint64_t seed) {
  OwnedBlob b{id, type, stride, std::vector<std::byte>(n * stride)};
  std::mt19937_64 rng(seed);
  int32_t walk = 0;
  for (size_t i = 0; i + 4 <= b.bytes.size(); i += 4) {
    walk += static_cast<int32_t>(rng() % 2001) - 1000;
    std::memcpy(b.bytes.data() + i, &walk, 4);
  }
  for (size_t i = b.bytes.size() / 4 * 4; i < b.bytes.size(); ++i) b.bytes[i] = std::byte(rng());
  return b;
}

// The writer's inputs viewing `blobs`.
inline std::vector<prep::BlobInput> inputs(const std::vector<OwnedBlob>& blobs) {
  std::vector<prep::BlobInput> v;
  for (const auto& b : blobs) v.push_back(b.input());
  return v;
}

}  // namespace decal_test
