// --max-memory: the size parser and the limit check (prep/memory_estimate.hpp).
// The model's accuracy against measured peaks is max_memory_test.py's job.
#include <gtest/gtest.h>

#include "prep/error.hpp"
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

}  // namespace
