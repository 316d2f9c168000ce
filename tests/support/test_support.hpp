// What many tests share: an RAII temp directory, small file helpers, running
// the decalprep tool (DECALPREP_TOOL) or any command line and capturing its
// exit code and output, where the shipped and the shared real data live, and
// the sample count of the statistical evaluator tests.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

namespace prep::test {

// A fresh directory under the system temp directory, removed with everything
// in it when the object goes.
class TempDir {
 public:
  explicit TempDir(const std::string& tag = "decalprep");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

void write_text(const std::string& path, const std::string& text);
std::string read_text(const std::string& path);
// `s` in single quotes for /bin/sh.
std::string shell_quote(const std::string& s);

struct ToolRun {
  int rc = -1;         // exit status; 128 + signal when killed by one
  std::string output;  // stdout, and stderr too unless split_stderr
  std::string err;     // stderr when split_stderr
};

struct RunOptions {
  std::string env;            // "NAME=VALUE ..." put before the command
  bool split_stderr = false;  // keep stderr apart in ToolRun::err
};

// Runs `cmd` through /bin/sh, capturing its output in files under `dir`.
ToolRun run_command(const std::string& cmd, const std::filesystem::path& dir,
                    const RunOptions& opt = {});
inline ToolRun run_command(const std::string& cmd, const TempDir& dir, const RunOptions& opt = {}) {
  return run_command(cmd, dir.path(), opt);
}
// The same in a temp directory of its own.
ToolRun run_command(const std::string& cmd, const RunOptions& opt = {});

// Runs the decalprep tool with `args` (already quoted for the shell).
ToolRun run_tool(const std::string& args, const std::filesystem::path& dir,
                 const RunOptions& opt = {});
inline ToolRun run_tool(const std::string& args, const TempDir& dir, const RunOptions& opt = {}) {
  return run_tool(args, dir.path(), opt);
}
ToolRun run_tool(const std::string& args, const RunOptions& opt = {});

// The repository's shipped Monaco sample, samples/monaco/<name>.
std::string monaco_sample(const std::string& name);
// The shared real data folder beside the checkout (DECALPREP_SHARED_DATA):
// Liechtenstein lives only there; tests skip, naming the path, when missing.
std::string shared_data(const std::string& rel);
// The R package spData unpacked by scripts/fetch-data (CMake cache variable
// DECALPREP_SPDATA), e.g. spdata_dir() + "/shapes/world.gpkg"; tests skip,
// naming the path and the script, when it is missing.
std::string spdata_dir();
inline bool exists(const std::string& p) {
  return std::filesystem::exists(p);
}

// xorshift64: the same sequence of doubles on every platform and standard
// library (<random>'s distributions differ between them).
class Rng {
 public:
  explicit Rng(uint64_t seed) : s_(seed) {}
  double uniform() {  // [0, 1)
    s_ ^= s_ << 13;
    s_ ^= s_ >> 7;
    s_ ^= s_ << 17;
    return double(s_ >> 11) / double(uint64_t(1) << 53);
  }
  double in(double a, double b) { return a + (b - a) * uniform(); }
  int below(int n) { return static_cast<int>(uniform() * n); }

 private:
  uint64_t s_;
};

// Samples of the statistical evaluator tests: the current default (10^6, or
// 2.5x10^5 while a VariantSamples lives), DECALPREP_SAMPLES overriding it.
std::size_t sample_count();
struct VariantSamples {
  VariantSamples();
  ~VariantSamples();
  VariantSamples(const VariantSamples&) = delete;
  VariantSamples& operator=(const VariantSamples&) = delete;
};

}  // namespace prep::test
