// --max-memory: the size parser and the limit check (prep/memory_estimate.hpp).
// The model's accuracy against measured peaks is max_memory_test.py's job.
#include <gtest/gtest.h>

#include "prep/error.hpp"
#include "prep/features.hpp"
#include "prep/memory_estimate.hpp"

namespace {

TEST(MemorySize, ParsesBinarySuffixesCaseInsensitively) {
  EXPECT_EQ(prep::parse_memory_size("2G"), 2ull << 30);
  EXPECT_EQ(prep::parse_memory_size("512M"), 512ull << 20);
  EXPECT_EQ(prep::parse_memory_size("512m"), 512ull << 20);
  EXPECT_EQ(prep::parse_memory_size("1.5G"), 3ull << 29);
  EXPECT_EQ(prep::parse_memory_size("64KiB"), 64ull << 10);
  EXPECT_EQ(prep::parse_memory_size("3 GB"), 3ull << 30);
  EXPECT_EQ(prep::parse_memory_size("1T"), 1ull << 40);
  EXPECT_EQ(prep::parse_memory_size("1073741824"), 1ull << 30);
}

TEST(MemorySize, RejectsWhatIsNotAPositiveSize) {
  for (const char* bad : {"", "abc", "0", "0G", "-1G", "2X", "G", "2GG", "nan", "inf"}) {
    EXPECT_THROW(prep::parse_memory_size(bad), prep::usage_error) << '"' << bad << '"';
  }
}

TEST(MemoryLimit, AnEstimateOverTheLimitStopsWithAResourceErrorThatSaysWhatToDo) {
  prep::MemoryEstimate e;
  e.point = "after read";
  e.bytes = 300.0 * 1024 * 1024;
  e.basis = "1000000 polygon vertices, 0 line vertices, 5000 parts";
  EXPECT_NO_THROW(prep::check_memory(prep::MemoryLimit{300ull << 20}, e));
  EXPECT_NO_THROW(prep::check_memory(prep::MemoryLimit{0}, e));  // no limit
  try {
    prep::check_memory(prep::MemoryLimit{(300ull << 20) - 1}, e);
    FAIL() << "no error one byte under the estimate";
  } catch (const prep::resource_error& err) {
    const std::string m = err.what();
    EXPECT_EQ(err.code(), prep::ExitCode::resource);
    EXPECT_NE(m.find("300.0 MiB"), std::string::npos) << m;
    EXPECT_NE(m.find("after read"), std::string::npos) << m;
    EXPECT_NE(m.find("1000000 polygon vertices"), std::string::npos) << m;
    EXPECT_NE(m.find("--max-memory"), std::string::npos) << m;
    EXPECT_NE(m.find("--resolution"), std::string::npos) << m;
    EXPECT_NE(m.find("--extent"), std::string::npos) << m;
    EXPECT_NE(m.find("split the scene"), std::string::npos) << m;
  }
}

// A tile's estimate is the resident set plus the jobs times one tile's
// part, and that part grows with the tile's vertices; its advice is about
// tiles (jobs, tile size, resume), not about splitting into tiles.
TEST(MemoryTile, TheEstimateIsTheResidentSetPlusJobsTimesTheTilesPart) {
  auto square_tile = [](int polygons) {
    prep::SceneFeatures t;
    for (int i = 0; i < polygons; ++i) {
      prep::ScenePolygon p;
      const double x = 10.0 * i;
      p.shell = {{x, 0}, {x + 5, 0}, {x + 5, 5}, {x, 5}, {x, 0}};
      t.polygons.push_back(p);
    }
    return t;
  };
  const double resident = 100.0 * 1024 * 1024;
  const prep::SceneFeatures small = square_tile(10), large = square_tile(10000);
  const prep::MemoryEstimate one = prep::estimate_tile(small, resident, 1, "tiles/x0_y0.decals");
  const prep::MemoryEstimate three = prep::estimate_tile(small, resident, 3, "tiles/x0_y0.decals");
  const prep::MemoryEstimate big = prep::estimate_tile(large, resident, 1, "tiles/x1_y0.decals");
  EXPECT_GT(one.bytes, resident);
  EXPECT_NEAR(three.bytes - resident, 3 * (one.bytes - resident), 1.0);
  EXPECT_GT(big.bytes, one.bytes);
  EXPECT_EQ(big.polygon_vertices, 50000);
  EXPECT_EQ(three.jobs, 3u);
  EXPECT_EQ(three.tile, "tiles/x0_y0.decals");
  EXPECT_EQ(prep::estimate_tile(small, resident, 0, "t").jobs, 1u);  // 0 jobs: one
  try {
    prep::check_memory(prep::MemoryLimit{uint64_t(one.bytes) + 1}, three);
    FAIL() << "three tiles at once passed a limit one tile just fits";
  } catch (const prep::resource_error& err) {
    const std::string m = err.what();
    EXPECT_NE(m.find("tiles/x0_y0.decals"), std::string::npos) << m;
    EXPECT_NE(m.find("--jobs"), std::string::npos) << m;
    EXPECT_NE(m.find("--tile-size"), std::string::npos) << m;
    EXPECT_EQ(m.find("split the scene"), std::string::npos) << m;
  }
  EXPECT_NO_THROW(prep::check_memory(prep::MemoryLimit{uint64_t(one.bytes) + 1}, one));
}

}  // namespace
