// A GeoJSON file whose one feature is larger than 250 MB builds with no
// environment variable set: GDAL's GeoJSON reader refuses an object it
// estimates above 200 MB unless OGR_GEOJSON_MAX_OBJ_SIZE says otherwise, and
// the read lifts that limit itself (libprep/read/read.cpp, ReadConfig).
// Label `slow` (about half a minute on 2 cores); it runs in the default suite.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "fixtures.hpp"

namespace {

using prep::test::run_command;
using prep::test::shell_quote;
using prep::test::TempDir;

TEST(BigGeoJson, OneFeatureOver250MbBuildsWithNoEnvironmentVariable) {
  TempDir dir;  // removed with everything in it at the end
  const std::string path = dir.file("coast.geojson");
  const auto t0 = std::chrono::steady_clock::now();
  // 1.4 million vertices (GDAL's estimate: about 245 MB), each coordinate
  // padded with zeros to take the file past 250 MiB.
  constexpr size_t kVertices = 1'400'000;
  prep::test::write_big_polygon(path, kVertices, 90);
  const auto bytes = std::filesystem::file_size(path);
  ASSERT_GT(bytes, 250ull << 20);
  const auto t1 = std::chrono::steady_clock::now();

  // The oracle that the file needs the option: GDAL's own ogrinfo, with the
  // option unset, refuses it.
  auto gdal =
      run_command("env -u OGR_GEOJSON_MAX_OBJ_SIZE ogrinfo -ro -so -al " + shell_quote(path), dir);
  EXPECT_NE(gdal.output.find("too complex/large"), std::string::npos) << gdal.output;
  const auto t2 = std::chrono::steady_clock::now();

  const std::string report = dir.file("report.json");
  auto r =
      run_command("env -u OGR_GEOJSON_MAX_OBJ_SIZE " + shell_quote(DECALPREP_TOOL) + " build " +
                      shell_quote(path) + " --kind polygon -q -o " +
                      shell_quote(dir.file("coast.decals")) + " --report " + shell_quote(report),
                  dir);
  const auto t3 = std::chrono::steady_clock::now();
  ASSERT_EQ(r.rc, 0) << r.output;
  const auto rep = nlohmann::json::parse(prep::test::read_text(report));
  const auto& layer = rep.at("manifest").at("layers").at(0);
  EXPECT_EQ(layer.at("read").get<int>(), 1);
  EXPECT_EQ(layer.at("kept").get<int>(), 1);
  auto s = [](auto a, auto b) { return std::chrono::duration<double>(b - a).count(); };
  std::printf("%llu bytes, %zu vertices: write %.1f s, ogrinfo %.1f s, decalprep build %.1f s\n",
              static_cast<unsigned long long>(bytes), kVertices, s(t0, t1), s(t1, t2), s(t2, t3));
  RecordProperty("bytes", std::to_string(bytes));
  RecordProperty("build_s", std::to_string(s(t2, t3)));
}

}  // namespace
