// Shared test fixtures for the read/project/clean tests: a temp directory,
// file writing, running the decalprep tool, and ogrinfo as an independent
// counting oracle.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace prep::test {

class TempDir {
 public:
  TempDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "decalprep-XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

struct ToolRun {
  int rc = -1;
  std::string output;  // stdout + stderr
};

// Runs a command line through /bin/sh, capturing stdout and stderr.
inline ToolRun run_command(const std::string& cmd, const TempDir& dir) {
  const std::string log = dir.file("command.log");
  int status = std::system((cmd + " >" + shell_quote(log) + " 2>&1").c_str());
  ToolRun r;
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : 128;
  r.output = read_text(log);
  return r;
}

inline ToolRun run_tool(const std::string& args, const TempDir& dir) {
  return run_command(shell_quote(DECALPREP_TOOL) + " " + args, dir);
}

inline std::string shared_data(const std::string& rel) {
  return std::string(DECALPREP_SHARED_DATA) + "/" + rel;
}

inline bool exists(const std::string& p) { return std::filesystem::exists(p); }

// ogrinfo's answer to `SELECT COUNT(*) ...` over `source`: the independent
// oracle for read counts (GDAL's own command-line program, not our reader;
// for OSM, `ogrinfo -so` reports -1, so the count is asked in SQL). Returns
// -1 when ogrinfo is unavailable or prints no count. `env` ("NAME=VALUE ...")
// goes into ogrinfo's environment, e.g. GDAL configuration options.
inline long long ogrinfo_count_sql(const std::string& source, const std::string& count_sql,
                                   const std::string& dialect, const TempDir& dir,
                                   const std::string& env = "") {
  std::string cmd = (env.empty() ? std::string() : "env " + env + " ") + "ogrinfo -ro -q " +
                    shell_quote(source) + " -sql " + shell_quote(count_sql);
  if (!dialect.empty()) cmd += " -dialect " + dialect;
  ToolRun r = run_command(cmd, dir);
  auto at = r.output.find("(Integer) = ");
  if (r.rc != 0 || at == std::string::npos) return -1;
  return std::atoll(r.output.c_str() + at + 12);
}

// A polygon of `n` vertices on a circle, one feature, coordinates padded with
// `pad` zeros (which GDAL's size estimate does not count).
// Streams through stdio, so no copy of the text is held in memory.
inline void write_big_polygon(const std::string& path, size_t n, size_t pad) {
  FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr) << path;
  const std::string zeros(pad, '0');
  std::fputs(
      R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":{"name":"big"},)"
      R"("geometry":{"type":"Polygon","coordinates":[[)",
      f);
  for (size_t i = 0; i <= n; ++i) {
    const double a = 2 * M_PI * double(i % n) / double(n);
    std::fprintf(f, "%s[%.9f%s,%.9f%s]", i ? "," : "", 7.42 + 0.01 * std::cos(a), zeros.c_str(),
                 43.73 + 0.01 * std::sin(a), zeros.c_str());
  }
  std::fputs("]]}}]}\n", f);
  ASSERT_EQ(std::fclose(f), 0);
}

}  // namespace prep::test
