#include "test_support.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace prep::test {

TempDir::TempDir(const std::string& tag) {
  std::string tmpl = (std::filesystem::temp_directory_path() / (tag + "-XXXXXX")).string();
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed: " + tmpl);
  path_ = tmpl;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

ToolRun run_command(const std::string& cmd, const std::filesystem::path& dir,
                    const RunOptions& opt) {
  const std::string out = (dir / "command.out").string(), err = (dir / "command.err").string();
  std::string line = opt.env.empty() ? std::string() : opt.env + " ";
  line += cmd + " >" + shell_quote(out) + (opt.split_stderr ? " 2>" + shell_quote(err) : " 2>&1");
  const int status = std::system(line.c_str());
  ToolRun r;
  r.rc = WIFEXITED(status)     ? WEXITSTATUS(status)
         : WIFSIGNALED(status) ? 128 + WTERMSIG(status)
                               : -1;
  r.output = read_text(out);
  if (opt.split_stderr) r.err = read_text(err);
  std::error_code ec;
  std::filesystem::remove(out, ec);
  std::filesystem::remove(err, ec);
  return r;
}

ToolRun run_command(const std::string& cmd, const RunOptions& opt) {
  TempDir dir("decalprep-run");
  return run_command(cmd, dir.path(), opt);
}

ToolRun run_tool(const std::string& args, const std::filesystem::path& dir, const RunOptions& opt) {
  return run_command(shell_quote(DECALPREP_TOOL) + " " + args, dir, opt);
}

ToolRun run_tool(const std::string& args, const RunOptions& opt) {
  return run_command(shell_quote(DECALPREP_TOOL) + " " + args, opt);
}

std::string monaco_sample(const std::string& name) {
  return std::string(DECALPREP_SOURCE_DIR) + "/samples/monaco/" + name;
}

std::string shared_data(const std::string& rel) {
  return std::string(DECALPREP_SHARED_DATA) + "/" + rel;
}

std::string spdata_dir() {
  return DECALPREP_SPDATA;
}

namespace {
std::size_t g_default_samples = 1'000'000;
}

std::size_t sample_count() {
  const char* e = std::getenv("DECALPREP_SAMPLES");
  return e ? std::size_t(std::atoll(e)) : g_default_samples;
}

VariantSamples::VariantSamples() {
  g_default_samples = 250'000;
}
VariantSamples::~VariantSamples() {
  g_default_samples = 1'000'000;
}

}  // namespace prep::test
