// make_seeds — writes the fuzz seed corpus (fuzz/corpus/read/): small valid
// packages and the hostile variants of fixtures.cpp. The corpus is checked
// in; the test SeedCorpus.IsWhatTheGeneratorWrites keeps it current.
// Usage: make_seeds DIR
#include <cstdio>
#include <filesystem>

#include "fixtures.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_seeds DIR\n");
    return 2;
  }
  const std::string dir = argv[1];
  std::filesystem::create_directories(dir);
  const auto small = decal_test::small_model();
  const auto good = decal_test::model_package_bytes(small, {prep::Codec::zstd, 3});
  decal_test::write_file(dir + "/valid_small_zstd.decals", good);
  decal_test::write_file(dir + "/valid_small_none.decals",
                         decal_test::model_package_bytes(small, {prep::Codec::none, 0}));
  decal_test::write_file(dir + "/valid_empty_model.decals",
                         decal_test::model_package_bytes(prep::DecalModel{}, {prep::Codec::zstd, 3}));
  for (const auto& h : decal_test::hostile_variants(good))
    decal_test::write_file(dir + "/broken_" + h.name + ".decals", h.bytes);
  return 0;
}
