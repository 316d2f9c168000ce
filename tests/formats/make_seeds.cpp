// make_seeds — writes the fuzz seed corpus: small valid packages and the
// hostile variants of fixtures.cpp. The corpus is checked in under
// fuzz/corpus/read/; the test SeedCorpus.CheckedInFilesAreWhatTheGeneratorWrites
// keeps it current. Regenerate with:
//   cmake --build build/dev --target make_seeds && build/dev/tests/formats/make_seeds
//   fuzz/corpus/read
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
  for (const auto& [name, bytes] : decal_test::seed_corpus())
    decal_test::write_file(dir + "/" + name, bytes);
  return 0;
}
