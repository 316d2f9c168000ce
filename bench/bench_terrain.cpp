// Terrain matching and LOD preprocessing figures:
//  - terrain matching throughput (output vertices per second) and output
//    vertex count, fixed lmax and adaptive (--terrain-tolerance), on
//    Monaco's roads with SRTM N43E007;
//  - LOCALIS preprocessing time and attributed/original segment ratio on
//    Monaco's roads and on Liechtenstein's highways + rivers.
// Data: $DECALPREP_SHARED_DATA or ../shared/data beside the checkout.
#include <benchmark/benchmark.h>
#include <gdal/ogr_spatialref.h>
#include <gdal/ogrsf_frmts.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include "lod/lod.hpp"
#include "ogr_lines.hpp"  // tests/support
#include "terrain/terrain.hpp"

namespace {

std::string shared_data() {
  if (const char* env = std::getenv("DECALPREP_SHARED_DATA")) return env;
  return (std::filesystem::path(__FILE__).parent_path() / ".." / ".." / "shared" / "data")
      .lexically_normal()
      .string();
}

struct Scene {
  prep::SceneFrame frame;
  std::vector<prep::SceneLine> lines;
};

// Lines of an OSM file's `lines` layer matching `filter`, projected to a
// local Transverse Mercator frame at (lon0, lat0) with OGR.
Scene read_lines(const std::string& path, const char* filter, double lon0, double lat0) {
  GDALAllRegister();
  CPLPushErrorHandler(CPLQuietErrorHandler);
  Scene s;
  OGRSpatialReference tm, wgs;
  tm.SetFromUserInput(("+proj=tmerc +lat_0=" + std::to_string(lat0) + " +lon_0=" +
                       std::to_string(lon0) + " +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m +no_defs")
                          .c_str());
  wgs.importFromEPSG(4326);
  tm.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  wgs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  char* wkt = nullptr;
  tm.exportToWkt(&wkt);
  s.frame.crs_wkt = wkt;
  CPLFree(wkt);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&wgs, &tm));
  GDALDatasetUniquePtr ds(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (ds && ct) {
    OGRLayer* layer = ds->GetLayerByName("lines");
    layer->SetAttributeFilter(filter);
    prep::test::for_each_line_string(*layer, [&](OGRFeature& f, const OGRLineString& ls) {
      prep::SceneLine l;
      for (int i = 0; i < ls.getNumPoints(); ++i) {
        double x = ls.getX(i), y = ls.getY(i);
        ct->Transform(1, &x, &y);
        if (!l.points.empty() && std::hypot(x - l.points.back().x, y - l.points.back().y) < 0.01)
          continue;
        l.points.push_back({x, y});
      }
      if (l.points.size() < 2) return;
      l.fid = f.GetFID();
      l.width = 3;
      s.lines.push_back(std::move(l));
    });
  }
  CPLPopErrorHandler();
  return s;
}

const Scene& monaco() {
  static const Scene s =
      read_lines(shared_data() + "/monaco/monaco.osm.pbf", "highway IS NOT NULL", 7.42, 43.73);
  return s;
}
const Scene& liechtenstein() {
  static const Scene s =
      read_lines(shared_data() + "/liechtenstein/liechtenstein-2013-08-03.osm.pbf",
                 "highway IS NOT NULL OR waterway IN ('river','stream')", 9.55, 47.15);
  return s;
}
std::string monaco_dem() {
  return "/vsizip/" + shared_data() + "/monaco/N43E007.hgt.zip/N43E007.hgt";
}

// range(0): lmax in decimetres (0: half the DEM cell); range(1): tolerance in cm (0: fixed).
void BM_TerrainMatch(benchmark::State& state) {
  const Scene& s = monaco();
  if (s.lines.empty()) {
    state.SkipWithError("Monaco data missing");
    return;
  }
  prep::DemSampler dem(monaco_dem(), s.frame, 1.0, std::nullopt);
  double xmin = 1e300, xmax = -1e300, ymin = 1e300, ymax = -1e300;
  uint64_t in = 0;
  for (const auto& l : s.lines)
    for (const auto& p : l.points) {
      xmin = std::min(xmin, p.x), xmax = std::max(xmax, p.x), ymin = std::min(ymin, p.y),
      ymax = std::max(ymax, p.y);
      ++in;
    }
  prep::MatchOptions opt;
  opt.lmax = state.range(0) > 0
                 ? state.range(0) * 0.1
                 : 0.5 * dem.cell_size_metres({0.5 * (xmin + xmax), 0.5 * (ymin + ymax)});
  opt.tolerance = state.range(1) * 0.01;
  prep::MatchedLines m;
  for (auto _ : state) {
    m = prep::match_terrain(s.lines, &dem, opt);
    benchmark::DoNotOptimize(m.vertices.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * m.vertices_out));
  state.counters["lmax_m"] = opt.lmax;
  state.counters["tolerance_m"] = opt.tolerance;
  state.counters["vertices_in"] = static_cast<double>(in);
  state.counters["vertices_fixed"] = static_cast<double>(m.vertices_fixed);
  state.counters["vertices_out"] = static_cast<double>(m.vertices_out);
  state.counters["max_deviation_m"] = m.max_deviation;
  state.counters["out_vertices_per_s"] = benchmark::Counter(
      static_cast<double>(state.iterations() * m.vertices_out), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_TerrainMatch)
    ->Args({0, 0})
    ->Args({0, 50})
    ->Args({0, 10})
    ->Args({75, 0})
    ->Args({75, 50})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

std::vector<prep::LodInputLine> lod_input(const Scene& s) {
  std::vector<prep::LodInputLine> out;
  for (uint32_t i = 0; i < s.lines.size(); ++i) {
    prep::LodInputLine l;
    l.line = i;
    for (const auto& p : s.lines[i].points) {
      const prep::ivec2 q{static_cast<int32_t>(std::llround(p.x * 1000)),
                          static_cast<int32_t>(std::llround(p.y * 1000))};
      if (l.points.empty() || l.points.back() != q) l.points.push_back(q);
    }
    if (l.points.size() > 3 && l.points.front() == l.points.back()) {
      l.points.pop_back();
      l.closed = true;
    }
    if (l.points.size() >= 2) out.push_back(std::move(l));
  }
  return out;
}

// range(0): 0 Monaco roads, 1 Liechtenstein highways + rivers; range(1): dependees on/off.
void BM_LodBuild(benchmark::State& state) {
  const auto lines = lod_input(state.range(0) == 0 ? monaco() : liechtenstein());
  if (lines.empty()) {
    state.SkipWithError("data missing");
    return;
  }
  prep::LodOptions opt;
  opt.dependees = state.range(1) != 0;
  prep::LodSet set;
  for (auto _ : state) {
    set = prep::build_lod(lines, opt);
    benchmark::DoNotOptimize(set.points.data());
  }
  state.SetItemsProcessed(static_cast<int64_t>(state.iterations() * set.stats.original_segments));
  state.counters["lines"] = static_cast<double>(set.stats.lines);
  state.counters["segments"] = static_cast<double>(set.stats.original_segments);
  state.counters["attributed"] = static_cast<double>(set.stats.attributed_segments);
  state.counters["ratio"] =
      double(set.stats.attributed_segments) / double(set.stats.original_segments);
  state.counters["dependees"] = static_cast<double>(set.stats.dependee_edges);
  state.counters["cycles"] = static_cast<double>(set.stats.cycles);
}
BENCHMARK(BM_LodBuild)
    ->Args({0, 1})
    ->Args({0, 0})
    ->Args({1, 1})
    ->Args({1, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
