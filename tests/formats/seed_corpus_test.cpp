// The checked-in fuzz seed corpus (fuzz/corpus/read/) is exactly what the
// generator (make_seeds, fixtures.cpp) writes today, and its packages are
// judged as their names say: valid_* open and validate, broken_* do not.
#include <gtest/gtest.h>

#include <filesystem>

#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "fixtures.hpp"

namespace {

const std::string kCorpus = std::string(DECALPREP_SOURCE_DIR) + "/fuzz/corpus/read";

TEST(SeedCorpus, CheckedInFilesAreWhatTheGeneratorWrites) {
  for (const auto& [name, bytes] : decal_test::seed_corpus()) {
    const std::string path = kCorpus + "/" + name;
    ASSERT_TRUE(std::filesystem::exists(path))
        << path << " missing; regenerate with make_seeds (see make_seeds.cpp)";
    EXPECT_EQ(decal_test::read_file(path), bytes)
        << path << " is stale; regenerate with make_seeds";
  }
}

TEST(SeedCorpus, ValidSeedsPassAndBrokenSeedsFail) {
  size_t valid = 0, broken = 0;
  for (const auto& e : std::filesystem::directory_iterator(kCorpus)) {
    const std::string name = e.path().filename().string();
    decal::Package p;
    decal::Status s = decal::Package::open(e.path().string(), p);
    if (s) s = decal::validate_indices(p);
    if (name.rfind("valid_", 0) == 0) {
      EXPECT_TRUE(s) << name << ": " << s.message;
      ++valid;
    } else {
      EXPECT_FALSE(s) << name;
      ++broken;
    }
  }
  EXPECT_GE(valid, 3u);
  EXPECT_GE(broken, 10u);
}

}  // namespace
