// Atomic output (ARCHITECTURE.md "Guarantees" 6): a killed, interrupted or
// failing writer leaves the previous file at the target untouched and no
// temporary file behind. The writers run in forked children so that they
// can be killed for real.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <set>
#include <thread>

#include "fixtures.hpp"
#include "prep/error.hpp"
#include "prep/write.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace write_atomic_write {

namespace {

namespace fs = std::filesystem;

std::set<std::string> names_in(const std::string& dir) {
  std::set<std::string> s;
  for (const auto& e : fs::directory_iterator(dir)) s.insert(e.path().filename().string());
  return s;
}

// Writes `mib` MiB of uncompressed data to `path` (runs in the child).
void write_big(const std::string& path, size_t mib) {
  std::vector<uint32_t> v(mib << 18);
  for (size_t i = 0; i < v.size(); ++i) v[i] = static_cast<uint32_t>(i * 2654435761u);
  prep::BlobInput b{decal::BlobId::line_vertex_line, decal::ElementType::u32, 4, v.size(),
                    std::as_bytes(std::span(v))};
  prep::write_package(path, "{}", {&b, 1}, {prep::Codec::none, 0});
}

// Size of the largest file the child has open for writing in `dir`
// (an O_TMPFILE shows as "<dir>/#<inode> (deleted)"), or -1.
long long child_file_size(pid_t pid, const std::string& dir) {
  long long best = -1;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
    std::error_code ec2;
    const fs::path target = fs::read_symlink(e.path(), ec2);
    if (ec2 || target.string().rfind(dir + "/", 0) != 0) continue;
    struct stat st;
    if (::stat(e.path().c_str(), &st) == 0) best = std::max<long long>(best, st.st_size);
  }
  return best;
}

class AtomicWrite : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = decal_test::make_temp_dir("atomic");
    target_ = dir_ + "/out.decals";
    old_ = decal_test::model_package_bytes(decal_test::small_model(), {});
    decal_test::write_file(target_, old_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Forks a child writing a big package to target_, sends `sig` once the
  // child's temp file holds more than 4 MiB, and returns the wait status.
  int kill_writer_mid_write(int sig) {
    const pid_t pid = ::fork();
    if (pid == 0) {
      write_big(target_, 128);
      ::_exit(0);
    }
    bool sent = false;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (std::chrono::steady_clock::now() < deadline) {
      if (child_file_size(pid, dir_) > (4 << 20)) {
        ::kill(pid, sig);
        sent = true;
        break;
      }
      int st;
      if (::waitpid(pid, &st, WNOHANG) == pid) return st;  // finished before we could kill it
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    if (!sent) ::kill(pid, SIGKILL);
    int status = 0;
    ::waitpid(pid, &status, 0);
    return status;
  }

  // The old package is still the target, and nothing else (no temp file)
  // is left beside it.
  void expect_old_target_and_no_temp_file() {
    EXPECT_EQ(decal_test::read_file(target_), old_);
    EXPECT_EQ(names_in(dir_), std::set<std::string>{"out.decals"});
  }

  std::string dir_, target_;
  std::vector<std::byte> old_;
};

TEST_F(AtomicWrite, WriterKilledMidWriteLeavesOldTargetAndNoTempFile) {
  const int status = kill_writer_mid_write(SIGKILL);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL)
      << "the writer was not killed mid-write (status " << status << ")";
  expect_old_target_and_no_temp_file();
}

TEST_F(AtomicWrite, WriterInterruptedBySigtermLeavesOldTargetAndNoTempFile) {
  const int status = kill_writer_mid_write(SIGTERM);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM)
      << "the writer did not die of SIGTERM mid-write (status " << status << ")";
  expect_old_target_and_no_temp_file();
}

TEST_F(AtomicWrite, FailingWriteThrowsAndLeavesOldTargetAndNoTempFile) {
  // A real failure, not a mock: the child may write at most 1 MiB per file,
  // so the 8 MiB package fails with EFBIG part way through.
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    rlimit lim{1 << 20, 1 << 20};
    ::setrlimit(RLIMIT_FSIZE, &lim);
    try {
      write_big(target_, 8);
    } catch (const prep::output_error& e) {
      const bool names_target = std::string(e.what()).find(target_) != std::string::npos;
      ::_exit(names_target ? 10 : 11);
    } catch (...) {
      ::_exit(12);
    }
    ::_exit(0);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 10)
      << "0: no failure, 11: message lacks the path, 12: wrong exception";
  expect_old_target_and_no_temp_file();
}

TEST_F(AtomicWrite, ModelMetadataRefusedOnAWriterThreadThrowsAndLeavesOldTargetAndNoTempFile) {
  // write_model makes the metadata on one of the writer's threads once the
  // temporary file exists (libprep/write/metadata.cpp), so a refusal there
  // must clean up like any failing write: extra metadata whose key
  // conflicts with one write_model sets.
  const prep::DecalModel m = decal_test::small_model();
  for (size_t threads : {1, 4}) {
    SCOPED_TRACE(std::to_string(threads) + " threads");
    const tbb::global_control cap(tbb::global_control::max_allowed_parallelism, threads);
    try {
      prep::write_model(target_, m, R"({"grid": 7})");
      ADD_FAILURE() << "no exception";
    } catch (const prep::output_error& e) {
      EXPECT_NE(std::string(e.what()).find("extra metadata key 'grid' conflicts"),
                std::string::npos)
          << e.what();
    }
    expect_old_target_and_no_temp_file();
  }
}

TEST_F(AtomicWrite, RenameOntoADirectoryFailsAndLeavesNoTempFile) {
  fs::create_directory(dir_ + "/taken");
  EXPECT_THROW(write_big(dir_ + "/taken", 1), prep::output_error);
  EXPECT_EQ(names_in(dir_), (std::set<std::string>{"out.decals", "taken"}));
  EXPECT_TRUE(fs::is_empty(dir_ + "/taken"));
}

TEST_F(AtomicWrite, MissingDirectoryIsAnOutputErrorNamingIt) {
  try {
    write_big(dir_ + "/no/such/dir/p.decals", 1);
    FAIL() << "no exception";
  } catch (const prep::output_error& e) {
    EXPECT_NE(std::string(e.what()).find(dir_ + "/no/such/dir"), std::string::npos) << e.what();
  }
}

TEST_F(AtomicWrite, SuccessfulWriteReplacesTheTargetAndLeavesNothingElse) {
  write_big(target_, 1);
  EXPECT_NE(decal_test::read_file(target_), old_);
  // header 96 + one entry 96 + "{}" 2, padded to 256, then the blob.
  EXPECT_EQ(fs::file_size(target_), 256 + (1u << 20));
  EXPECT_EQ(names_in(dir_), std::set<std::string>{"out.decals"});
}

}  // namespace

}  // namespace write_atomic_write
