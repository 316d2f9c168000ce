// fixtures.hpp — packages for the format tests, the seed-corpus generator
// and the fuzzer seeds. Everything is generated from code; no hand-made bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "decal/format.hpp"
#include "prep/model.hpp"
#include "prep/write.hpp"

namespace decal_test {

// A small model with every blob non-empty and every index consistent
// (validate_indices passes): 2 cells, 2 static lines, an exterior polygon
// with one hole, BVHs, 2 dynamic lines and one LOD line.
prep::DecalModel small_model();

// Writes `model` with write_model and returns the file's bytes.
std::vector<std::byte> model_package_bytes(const prep::DecalModel& model,
                                           const prep::WriteOptions& options,
                                           const std::string& extra_metadata_json = "");

std::vector<std::byte> read_file(const std::string& path);
void write_file(const std::string& path, const std::vector<std::byte>& bytes);

// A fresh empty directory under the system temp dir, removed by the caller.
std::string make_temp_dir(const std::string& tag);

// Field access in a package image (little-endian, no alignment needed).
template <class T>
T get(const std::vector<std::byte>& f, size_t at);
template <class T>
void put(std::vector<std::byte>& f, size_t at, T v);

// Byte offset of blob table entry `i`.
size_t entry_at(size_t i);

// Recomputes the table, metadata and header checksums after a test edited
// the image, so that the reader's structural checks (not the checksums) are
// what must reject the edit.
void reseal(std::vector<std::byte>& f);

}  // namespace decal_test
