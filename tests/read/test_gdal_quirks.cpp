// GDAL quirks the user never has to know (docs/build.md "GDAL configuration
// options decalprep sets"): OSM XML as Overpass API writes it, and GeoJSON
// objects over GDAL's default size limit. End to end through `decalprep
// build`; the read counts are checked against ogrinfo run with the option
// that makes GDAL read the file (the independent oracle).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fixtures.hpp"

namespace {

using prep::test::read_text;
using prep::test::run_command;
using prep::test::run_tool;
using prep::test::shell_quote;
using prep::test::TempDir;
using prep::test::write_big_polygon;
using prep::test::write_text;

// OSM XML in the shape Overpass API gives it (`out qt`: quadtile order), so
// node ids decrease through the file; every node still comes before the ways
// that use it. Five buildings (closed ways), three highways, and a
// multipolygon relation (landuse=grass) with an outer and an inner way.
std::string overpass_xml() {
  struct Way {
    long long id;
    std::vector<long long> nodes;
    std::string tags;
  };
  std::string nodes_xml;
  std::vector<Way> ways;
  long long next_node = 100000, next_way = 50000;
  char b[160];
  auto node = [&](double lon, double lat) {
    --next_node;
    std::snprintf(b, sizeof b, "  <node id=\"%lld\" lat=\"%.7f\" lon=\"%.7f\"/>\n", next_node, lat,
                  lon);
    nodes_xml += b;
    return next_node;
  };
  auto square = [&](double lon, double lat, double side) {
    std::vector<long long> r{node(lon, lat), node(lon + side, lat), node(lon + side, lat + side),
                             node(lon, lat + side)};
    r.push_back(r.front());
    return r;
  };
  for (int k = 0; k < 5; ++k)
    ways.push_back(
        {--next_way, square(7.42 + k * 0.001, 43.73, 0.0005), "<tag k=\"building\" v=\"yes\"/>"});
  for (int k = 0; k < 3; ++k)
    ways.push_back({--next_way,
                    {node(7.42 + k * 0.001, 43.735), node(7.4205 + k * 0.001, 43.7355),
                     node(7.421 + k * 0.001, 43.735)},
                    "<tag k=\"highway\" v=\"residential\"/>"});
  const long long outer = --next_way, inner = --next_way;
  ways.push_back({outer, square(7.43, 43.74, 0.002), ""});
  ways.push_back({inner, square(7.4305, 43.7405, 0.0005), ""});
  std::string xml =
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<osm version=\"0.6\" generator=\"Overpass "
      "API\">\n";
  xml += nodes_xml;
  for (const Way& w : ways) {
    xml += "  <way id=\"" + std::to_string(w.id) + "\">";
    for (long long n : w.nodes) xml += "<nd ref=\"" + std::to_string(n) + "\"/>";
    xml += w.tags + "</way>\n";
  }
  xml += "  <relation id=\"900\"><member type=\"way\" ref=\"" + std::to_string(outer) +
         "\" role=\"outer\"/><member type=\"way\" ref=\"" + std::to_string(inner) +
         "\" role=\"inner\"/><tag k=\"type\" v=\"multipolygon\"/><tag k=\"landuse\" "
         "v=\"grass\"/></relation>\n";
  return xml + "</osm>\n";
}

struct OsmLayer {
  const char* name;
  const char* layer;  // OGR layer, or "" with sql
  const char* where;
  const char* sql;
  const char* kind;
  const char* count_sql;  // the oracle's question
};

// Whole layers (one shared pass over the file), a `where` layer and an
// `sql` layer (each read on its own).
const OsmLayer kOsmLayers[] = {
    {"areas", "multipolygons", "", "", "polygon", "SELECT COUNT(*) FROM multipolygons"},
    {"roads", "lines", "", "", "line", "SELECT COUNT(*) FROM lines"},
    {"buildings", "multipolygons", "building IS NOT NULL", "", "polygon",
     "SELECT COUNT(*) FROM multipolygons WHERE building IS NOT NULL"},
    {"grass", "", "", "SELECT * FROM multipolygons WHERE landuse = 'grass'", "polygon",
     "SELECT COUNT(*) FROM multipolygons WHERE landuse = 'grass'"},
};

std::string osm_scene(const std::string& source) {
  std::string toml = "source = \"" + source + "\"\n";
  for (const OsmLayer& l : kOsmLayers) {
    toml += std::string("[[layer]]\nname = \"") + l.name + "\"\nkind = \"" + l.kind + "\"\n";
    if (l.layer[0]) toml += std::string("layer = \"") + l.layer + "\"\n";
    if (l.where[0]) toml += std::string("where = \"") + l.where + "\"\n";
    if (l.sql[0]) toml += std::string("sql = \"") + l.sql + "\"\n";
    if (std::string(l.kind) == "line") toml += "width = 3\n";
  }
  return toml;
}

// The file name does not matter: GDAL's OSM driver takes `.osm`, `.xml`, or
// Overpass's own download name.
class OverpassOsm : public ::testing::TestWithParam<const char*> {};

TEST_P(OverpassOsm, BuildsWithOgrinfosCountsUnderThePlainNodeIndex) {
  TempDir dir;
  const std::string osm = dir.file(GetParam());
  write_text(osm, overpass_xml());
  write_text(dir.file("scene.toml"), osm_scene(osm));
  const std::string report = dir.file("report.json");
  // No GDAL option in the build's environment.
  auto r =
      run_command("env -u OSM_USE_CUSTOM_INDEXING " + shell_quote(DECALPREP_TOOL) + " build " +
                      shell_quote(dir.file("scene.toml")) + " -o " +
                      shell_quote(dir.file("o.decals")) + " -q --report " + shell_quote(report),
                  dir);
  ASSERT_EQ(r.rc, 0) << r.output;
  const auto rep = nlohmann::json::parse(read_text(report));
  const auto& counts = rep.at("manifest").at("layers");
  ASSERT_EQ(counts.size(), std::size(kOsmLayers));
  long long total = 0;
  for (size_t i = 0; i < std::size(kOsmLayers); ++i) {
    const OsmLayer& l = kOsmLayers[i];
    SCOPED_TRACE(l.name);
    const long long oracle =
        prep::test::ogrinfo_count_sql(osm, l.count_sql, "", dir, "OSM_USE_CUSTOM_INDEXING=NO");
    ASSERT_GE(oracle, 0) << "ogrinfo gave no count";
    EXPECT_EQ(counts[i].at("read").get<long long>(), oracle);
    EXPECT_EQ(counts[i].at("kept").get<long long>(), oracle);
    total += oracle;
  }
  EXPECT_EQ(total, 6 + 3 + 5 + 1);  // what the generator wrote
  // GDAL's default index stops at the first decreasing id: this file needs it.
  EXPECT_EQ(prep::test::ogrinfo_count_sql(osm, "SELECT COUNT(*) FROM lines", "", dir,
                                          "OSM_USE_CUSTOM_INDEXING=YES"),
            0);
  std::string notes;
  for (const auto& n : rep.at("manifest").at("notes")) notes += n.get<std::string>() + "\n";
  EXPECT_NE(notes.find("OSM_USE_CUSTOM_INDEXING=NO"), std::string::npos) << notes;
}

std::string file_kind(const ::testing::TestParamInfo<const char*>& p) {
  return p.index == 0 ? "osm" : p.index == 1 ? "xml" : "no_extension";
}
INSTANTIATE_TEST_SUITE_P(FileName, OverpassOsm,
                         ::testing::Values("overpass.osm", "export.xml", "interpreter"), file_kind);

// Overpass's `out; >; out skel qt;` lists the ways first and their nodes
// after them. GDAL (with either node index) then assembles no way at all and
// says nothing; the build must stop and say how to reorder the file.
TEST(OverpassOsmXml, NodesListedAfterTheirWaysStopTheBuildWithWhatToDo) {
  TempDir dir;
  std::string xml = overpass_xml();
  // Move every <node> line behind the relation.
  std::string nodes, rest;
  size_t at = 0;
  while (at < xml.size()) {
    const size_t end = xml.find('\n', at) + 1;
    const std::string line = xml.substr(at, end - at);
    (line.find("<node ") != std::string::npos ? nodes : rest) += line;
    at = end;
  }
  rest.insert(rest.rfind("</osm>"), nodes);
  const std::string osm = dir.file("ways_first.osm");
  write_text(osm, rest);
  // The oracle: GDAL itself reads no way from it, whatever the index.
  for (const char* index : {"YES", "NO"})
    EXPECT_EQ(prep::test::ogrinfo_count_sql(osm, "SELECT COUNT(*) FROM lines", "", dir,
                                            std::string("OSM_USE_CUSTOM_INDEXING=") + index),
              0);
  auto r = run_tool("build " + shell_quote(osm) + " --layer lines --kind line -o " +
                        shell_quote(dir.file("w.decals")),
                    dir);
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("ways_first.osm"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("lists node"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("osmium sort"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("out body;"), std::string::npos) << r.output;
  EXPECT_FALSE(prep::test::exists(dir.file("w.decals")));
}

// A limit the user sets on purpose is kept (only an unset option is lifted).
TEST(GeoJsonObjectLimit, AUserSetLimitIsKept) {
  TempDir dir;
  const std::string path = dir.file("polygon.geojson");
  write_big_polygon(path, 100000, 0);  // GDAL estimates about 17 MB
  auto limited = run_tool(
      "build " + shell_quote(path) + " --kind polygon -o " + shell_quote(dir.file("l.decals")),
      dir);
  ASSERT_EQ(limited.rc, 0) << limited.output;
  auto r =
      run_command("env OGR_GEOJSON_MAX_OBJ_SIZE=10 " + shell_quote(DECALPREP_TOOL) + " build " +
                      shell_quote(path) + " --kind polygon -o " + shell_quote(dir.file("p.decals")),
                  dir);
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find("OGR_GEOJSON_MAX_OBJ_SIZE"), std::string::npos) << r.output;
}

}  // namespace
