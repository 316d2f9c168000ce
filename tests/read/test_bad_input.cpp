// Bad input gets a clear error naming what is wrong,
// a non-zero exit code, and no package. Runs the real decalprep binary.
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <filesystem>
#include <string>
#include <vector>

#include "fixtures.hpp"

namespace {

using prep::test::read_text;
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
  for (const auto& [name, type] :
       {std::pair{"highway", OFTString}, std::pair{"lanes", OFTInteger}}) {
    OGRFieldDefn field(name, type);
    if (layer->CreateField(&field) != OGRERR_NONE) throw std::runtime_error("CreateField failed");
  }
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

// What a case writes into its temp directory before running the tool.
enum class Input {
  none,
  garbage_shp,
  shapefile,
  truncated_shapefile,
  shapefile_without_crs,
  scene_bad_where,
  bad_scene
};

void write_input(Input in, const TempDir& dir) {
  switch (in) {
    case Input::none: break;
    case Input::garbage_shp:
      prep::test::write_text(dir.file("junk.shp"), std::string(300, '\x5a'));
      break;
    case Input::shapefile: write_shapefile(dir.file("roads.shp"), true); break;
    case Input::truncated_shapefile:
      write_shapefile(dir.file("roads.shp"), true);
      // Cut the .shp in the middle of its records; the .shx still points past it.
      std::filesystem::resize_file(dir.file("roads.shp"),
                                   std::filesystem::file_size(dir.file("roads.shp")) / 2);
      break;
    case Input::shapefile_without_crs: write_shapefile(dir.file("roads.shp"), false); break;
    case Input::scene_bad_where:
      write_shapefile(dir.file("roads.shp"), true);
      prep::test::write_text(dir.file("scene.toml"),
                             "source = \"roads.shp\"\n\n[[layer]]\nname = \"streets\"\n"
                             "kind = \"line\"\nwhere = \"nosuchfield = 3\"\n");
      break;
    case Input::bad_scene:
      write_shapefile(dir.file("roads.shp"), true);
      prep::test::write_text(dir.file("scene.toml"),
                             "source = \"roads.shp\"\n\n[[layer]]\nkind = \"line\"\nwidht = 4\n");
      break;
  }
}

// One run of the tool: `args` with every `@name` standing for the quoted path
// of `name` in the case's temp directory.
struct Step {
  std::string args;
  int rc;
  std::vector<std::string> output_has;  // substrings of stdout + stderr
  std::vector<std::string> report_has;  // substrings of @r.json afterwards
  bool no_package = true;               // no .decals left in the directory
};

struct Case {
  const char* name;  // the test's name
  Input input;
  std::vector<Step> steps;
};

std::ostream& operator<<(std::ostream& os, const Case& c) {
  return os << c.name;
}

std::string expand(const std::string& args, const TempDir& dir) {
  std::string out;
  for (size_t i = 0; i < args.size();) {
    if (args[i] != '@') {
      out += args[i++];
      continue;
    }
    const size_t end = std::min(args.find(' ', i), args.size());
    out += shell_quote(dir.file(args.substr(i + 1, end - i - 1)));
    i = end;
  }
  return out;
}

const std::vector<Case> kCases = {
    {"MissingFileNamesTheFile",
     Input::none,
     {{"build @nope.shp -o @out.decals --kind line", kInput, {"nope.shp: no such file"}, {}}}},
    {"AFailedBuildStillWritesAReportSayingWhy",
     Input::none,
     {{"build @nope.shp -o @out.decals --report @r.json",
       kInput,
       {},
       {"\"package_written\": false", "nope.shp: no such file", "\"exit_code\": 3"}}}},
    {"GarbageShapefileIsRejectedNamingTheFile",
     Input::garbage_shp,
     {{"build @junk.shp -o @out.decals", kInput, {"junk.shp", "cannot open"}, {}}}},
    {"TruncatedShapefileIsRejectedNamingFileAndLayer",
     Input::truncated_shapefile,
     {{"build @roads.shp -o @out.decals --kind line",
       kInput,
       {"roads.shp layer 'roads': reading failed at fid "},
       {}}}},
    {"UnknownLayerListsTheLayersThereAre",
     Input::shapefile,
     {{"build @roads.shp --layer rods -o @out.decals --kind line",
       kInput,
       {"unknown layer 'rods' (layers: roads)"},
       {}}}},
    {"InvalidSqlQuotesTheStatementAndGdalsMessage",
     Input::shapefile,
     {{"build @roads.shp --sql 'SELEC * FROM roads' -o @out.decals --kind line",
       kInput,
       {"invalid SQL \"SELEC * FROM roads\""},
       {}}}},
    {"InvalidWhereIsRejected",
     Input::shapefile,
     {{"build @roads.shp --where 'nosuchfield = 3' -o @out.decals --kind line",
       kInput,
       {"invalid where", "scene layer 'layer0'", "(fields: highway, lanes)"},
       {}}}},
    // The scene layer and its line in the file, and the fields it may use.
    {"InvalidWhereInASceneNamesTheLayerItsLineAndTheFields",
     Input::scene_bad_where,
     {{"build @scene.toml -o @out.decals",
       kInput,
       {"scene layer 'streets' (", "scene.toml:3): invalid where \"nosuchfield = 3\"",
        "(fields: highway, lanes)"},
       {}}}},
    {"InvalidSqlListsTheLayersAndTheirFields",
     Input::shapefile,
     {{"build @roads.shp --sql 'SELECT nosuch FROM roads' -o @out.decals --kind line",
       kInput,
       {"invalid SQL \"SELECT nosuch FROM roads\"", "layer 'roads' fields: highway, lanes"},
       {}}}},
    {"SourceWithoutCrsIsAnErrorUnlessAssumeCrsIsGiven",
     Input::shapefile_without_crs,
     {{"build @roads.shp -o @out.decals --kind line",
       kInput,
       {"roads.shp layer 'roads': the source has no CRS", "--assume-crs"},
       {}},
      {"build @roads.shp --assume-crs EPSG:4326 --dry-run -q --kind line --report @r.json",
       0,
       {},
       {"assumed EPSG:4326"},
       false}}},
    {"InvalidCrsIsRejectedNamingIt",
     Input::shapefile,
     {{"build @roads.shp --crs EPSG:999999 -o @out.decals --kind line",
       kInput,
       {"invalid --crs 'EPSG:999999'"},
       {}},
      {"build @roads.shp --crs EPSG:4326 -o @out.decals --kind line",
       kInput,
       {"not a projected CRS"},
       {}}}},
    {"InvalidSceneFileNamesKeyAndLine",
     Input::bad_scene,
     {{"build @scene.toml -o @out.decals",
       kInput,
       {"scene.toml:5: layer[0].widht: unknown key"},
       {}}}},
    {"BadOptionValueIsAUsageError",
     Input::shapefile,
     {{"build @roads.shp --corner sharp -o @out.decals --kind line",
       kUsage,
       {"round|miter|bevel"},
       {},
       false},
      {"build @roads.shp --grid 500 -o @out.decals --kind line", kUsage, {}, {}}}},
};

class BadInput : public ::testing::TestWithParam<Case> {};

TEST_P(BadInput, FailsWithTheDocumentedCodeAndAMessageNamingTheCause) {
  const Case& c = GetParam();
  TempDir dir;
  write_input(c.input, dir);
  for (const Step& run : c.steps) {
    SCOPED_TRACE(run.args);
    const auto r = run_tool(expand(run.args, dir), dir);
    EXPECT_EQ(r.rc, run.rc) << r.output;
    for (const std::string& s : run.output_has)
      EXPECT_NE(r.output.find(s), std::string::npos) << s << "\n" << r.output;
    if (!run.report_has.empty()) {
      const std::string report = read_text(dir.file("r.json"));
      for (const std::string& s : run.report_has)
        EXPECT_NE(report.find(s), std::string::npos) << s << "\n" << report;
    }
    if (run.no_package) expect_no_output(dir);
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, BadInput, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<Case>& i) {
                           return std::string(i.param.name);
                         });

}  // namespace
