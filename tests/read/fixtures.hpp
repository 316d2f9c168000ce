// Fixtures of the read/project/clean tests beyond tests/support: ogrinfo as
// an independent counting oracle and a big GeoJSON polygon.
#pragma once

#include <gtest/gtest.h>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "test_support.hpp"

namespace prep::test {

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
