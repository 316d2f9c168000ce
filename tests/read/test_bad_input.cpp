// Bad input gets a clear error naming what is wrong,
// a non-zero exit code, and no package. Runs the real decalprep binary.
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <filesystem>

#include "fixtures.hpp"

namespace {

using prep::test::run_tool;
using prep::test::shell_quote;
using prep::test::TempDir;

constexpr int kUsage = 2;
constexpr int kInput = 3;

// A small line shapefile; without a .prj when `with_crs` is false.
void write_shapefile(const std::string& path, bool with_crs, int features = 50) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("ESRI Shapefile");
  std::unique_ptr<GDALDataset> ds(drv->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  OGRSpatialReference srs;
  srs.importFromEPSG(4326);
  OGRLayer* layer = ds->CreateLayer("roads", with_crs ? &srs : nullptr, wkbLineString, nullptr);
  for (int i = 0; i < features; ++i) {
    OGRFeature f(layer->GetLayerDefn());
    OGRLineString ls;
    for (int k = 0; k < 20; ++k) ls.addPoint(7.4 + 0.001 * k, 43.7 + 0.0001 * i + 0.00001 * k);
    f.SetGeometry(&ls);
    if (layer->CreateFeature(&f) != OGRERR_NONE) throw std::runtime_error("CreateFeature failed");
  }
}

// No package and no temp file next to it.
void expect_no_output(const TempDir& dir) {
  for (const auto& e : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(e.path().string().find(".decals"), std::string::npos) << e.path();
  }
}

TEST(BadInput, MissingFileNamesTheFile) {
  TempDir dir;
  auto r = run_tool("build " + shell_quote(dir.file("nope.shp")) + " -o " +
                        shell_quote(dir.file("out.decals")) + " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("nope.shp: no such file"), std::string::npos) << r.output;
  expect_no_output(dir);
}

TEST(BadInput, AFailedBuildStillWritesAReportSayingWhy) {
  TempDir dir;
  auto r = run_tool("build " + shell_quote(dir.file("nope.shp")) + " -o " +
                        shell_quote(dir.file("out.decals")) + " --report " +
                        shell_quote(dir.file("r.json")),
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  const std::string report = prep::test::read_text(dir.file("r.json"));
  EXPECT_NE(report.find("\"package_written\": false"), std::string::npos) << report;
  EXPECT_NE(report.find("nope.shp: no such file"), std::string::npos) << report;
  EXPECT_NE(report.find("\"exit_code\": 3"), std::string::npos) << report;
  expect_no_output(dir);
}

TEST(BadInput, GarbageShapefileIsRejectedNamingTheFile) {
  TempDir dir;
  prep::test::write_text(dir.file("junk.shp"), std::string(300, '\x5a'));
  auto r = run_tool("build " + shell_quote(dir.file("junk.shp")) + " -o " +
                        shell_quote(dir.file("out.decals")),
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("junk.shp"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("cannot open"), std::string::npos) << r.output;
  expect_no_output(dir);
}

TEST(BadInput, TruncatedShapefileIsRejectedNamingFileAndLayer) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), true);
  // Cut the .shp in the middle of its records; the .shx still points past it.
  std::filesystem::resize_file(dir.file("roads.shp"),
                               std::filesystem::file_size(dir.file("roads.shp")) / 2);
  auto r = run_tool("build " + shell_quote(dir.file("roads.shp")) + " -o " +
                        shell_quote(dir.file("out.decals")) + " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("roads.shp layer 'roads': reading failed at fid "), std::string::npos)
      << r.output;
  expect_no_output(dir);
}

TEST(BadInput, UnknownLayerListsTheLayersThereAre) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), true);
  auto r = run_tool("build " + shell_quote(dir.file("roads.shp")) + " --layer rods -o " +
                        shell_quote(dir.file("out.decals")) + " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("unknown layer 'rods' (layers: roads)"), std::string::npos) << r.output;
  expect_no_output(dir);
}

TEST(BadInput, InvalidSqlQuotesTheStatementAndGdalsMessage) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), true);
  auto r = run_tool("build " + shell_quote(dir.file("roads.shp")) +
                        " --sql 'SELEC * FROM roads' -o " + shell_quote(dir.file("out.decals")) +
                        " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("invalid SQL \"SELEC * FROM roads\""), std::string::npos) << r.output;
  expect_no_output(dir);
}

TEST(BadInput, InvalidWhereIsRejected) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), true);
  auto r = run_tool("build " + shell_quote(dir.file("roads.shp")) +
                        " --where 'nosuchfield = 3' -o " + shell_quote(dir.file("out.decals")) +
                        " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("invalid where"), std::string::npos) << r.output;
  expect_no_output(dir);
}

TEST(BadInput, SourceWithoutCrsIsAnErrorUnlessAssumeCrsIsGiven) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), false);
  auto r = run_tool("build " + shell_quote(dir.file("roads.shp")) + " -o " +
                        shell_quote(dir.file("out.decals")) + " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("roads.shp layer 'roads': the source has no CRS"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("--assume-crs"), std::string::npos) << r.output;
  expect_no_output(dir);

  auto ok = run_tool("build " + shell_quote(dir.file("roads.shp")) +
                         " --assume-crs EPSG:4326 --dry-run -q --kind line --report " +
                         shell_quote(dir.file("r.json")),
                     dir);
  EXPECT_EQ(ok.rc, 0) << ok.output;
  EXPECT_NE(prep::test::read_text(dir.file("r.json")).find("assumed EPSG:4326"), std::string::npos);
}

TEST(BadInput, InvalidCrsIsRejectedNamingIt) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), true);
  auto r = run_tool("build " + shell_quote(dir.file("roads.shp")) + " --crs EPSG:999999 -o " +
                        shell_quote(dir.file("out.decals")) + " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("invalid --crs 'EPSG:999999'"), std::string::npos) << r.output;
  expect_no_output(dir);

  auto geo = run_tool("build " + shell_quote(dir.file("roads.shp")) + " --crs EPSG:4326 -o " +
                          shell_quote(dir.file("out.decals")) + " --kind line",
                      dir);
  EXPECT_EQ(geo.rc, kInput) << geo.output;
  EXPECT_NE(geo.output.find("not a projected CRS"), std::string::npos) << geo.output;
  expect_no_output(dir);
}

TEST(BadInput, InvalidSceneFileNamesKeyAndLine) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), true);
  prep::test::write_text(dir.file("scene.toml"),
                         "source = \"roads.shp\"\n\n[[layer]]\nkind = \"line\"\nwidht = 4\n");
  auto r = run_tool("build " + shell_quote(dir.file("scene.toml")) + " -o " +
                        shell_quote(dir.file("out.decals")),
                    dir);
  EXPECT_EQ(r.rc, kInput) << r.output;
  EXPECT_NE(r.output.find("scene.toml:5: layer[0].widht: unknown key"), std::string::npos)
      << r.output;
  expect_no_output(dir);
}

TEST(BadInput, BadOptionValueIsAUsageError) {
  TempDir dir;
  write_shapefile(dir.file("roads.shp"), true);
  auto r = run_tool("build " + shell_quote(dir.file("roads.shp")) + " --corner sharp -o " +
                        shell_quote(dir.file("out.decals")) + " --kind line",
                    dir);
  EXPECT_EQ(r.rc, kUsage) << r.output;
  EXPECT_NE(r.output.find("round|miter|bevel"), std::string::npos) << r.output;
  auto g = run_tool("build " + shell_quote(dir.file("roads.shp")) + " --grid 500 -o " +
                        shell_quote(dir.file("out.decals")) + " --kind line",
                    dir);
  EXPECT_EQ(g.rc, kUsage) << g.output;
  expect_no_output(dir);
}

}  // namespace
