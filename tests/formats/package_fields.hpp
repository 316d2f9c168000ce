// package_fields.hpp — field access in a package image (little-endian, no
// alignment needed). Header-only and standard library only, so that the
// fuzz targets (fuzz/fuzz_read.cpp) share it with the format tests.
#pragma once

#include <cstddef>
#include <cstring>
#include <vector>

namespace decal_test {

template <class T>
T get(const std::vector<std::byte>& f, size_t at) {
  T v;
  std::memcpy(&v, f.data() + at, sizeof v);
  return v;
}
template <class T>
void put(std::vector<std::byte>& f, size_t at, T v) {
  std::memcpy(f.data() + at, &v, sizeof v);
}

}  // namespace decal_test
