// The render smoke test: Monaco (building, landuse, water and
// highway polygons and lines, dynamic highway lines) over N43E007 at 640x360
// on llvmpipe, top-down orthographic and oblique perspective, against the
// CPU evaluator (--cpu) and gdal_rasterize; plus a synthetic scene that
// exercises every decal type and style. PNGs go to render-out/smoke/.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <memory>

#include <nlohmann/json.hpp>

#include "decal/reader.hpp"
#include "prep/pipeline.hpp"
#include "prep/read.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_smoke {

namespace fs = std::filesystem;
using prep::test::run_tool;
using render_test::agreement;
using render_test::read_raw;
using render_test::read_world_file;
using render_test::WorldFile;

namespace {

const std::string kSource = DECALPREP_SOURCE_DIR;
const std::string kDem = "/vsizip/" + kSource + "/samples/monaco/N43E007.hgt.zip/N43E007.hgt";
// Central Monaco: metres relative to the package origin (local TM on the
// data); --extent takes them absolute (topdown_extent below).
const prep::Extent kTopDown{-800, -450, 800, 450};

fs::path out_dir() {
  fs::path p = fs::current_path() / "render-out" / "smoke";
  fs::create_directories(p);
  return p;
}

using render_test::BuildLock;
using render_test::fresh;

// The Monaco package (smoke_util.hpp), looked up once per process.
const std::string& monaco_package(std::string* why) {
  static std::string reason;
  static const std::string path = render_test::monaco_package(&reason);
  if (why) *why = reason;
  return path;
}

// A package's frame from its metadata: origin (frame CRS) and CRS.
struct PackageFrame {
  double origin_x = 0, origin_y = 0;
  prep::Extent extent;  // relative to the origin, as the metadata stores it
  std::string crs_wkt;
  prep::Extent absolute(const prep::Extent& e) const {
    return {e.xmin + origin_x, e.ymin + origin_y, e.xmax + origin_x, e.ymax + origin_y};
  }
};
PackageFrame package_frame(const std::string& pkg) {
  decal::Package package;
  PackageFrame f;
  if (!decal::Package::open(pkg, package)) return f;
  const auto meta = nlohmann::json::parse(package.metadata_json());
  f.origin_x = meta.at("origin").at("x").get<double>();
  f.origin_y = meta.at("origin").at("y").get<double>();
  const auto& e = meta.at("extent");
  f.extent = {e.at(0).get<double>(), e.at(1).get<double>(), e.at(2).get<double>(),
              e.at(3).get<double>()};
  f.crs_wkt = meta.at("crs_wkt").get<std::string>();
  return f;
}
std::string extent_text(const prep::Extent& e, const char* format = "%.6f,%.6f,%.6f,%.6f") {
  char b[200];
  std::snprintf(b, sizeof b, format, e.xmin, e.ymin, e.xmax, e.ymax);
  return b;
}
// `--extent` for `relative` (metres from the package origin) in the absolute
// frame coordinates render takes.
std::string topdown_extent(const std::string& pkg, const prep::Extent& relative) {
  return "--extent " + extent_text(package_frame(pkg).absolute(relative));
}

// gdal_rasterize (the real program) burns 1 inside the polygons of `layer`
// of `source` on the grid -te `e` -ts w h; row 0 is the top row.
std::vector<uint8_t> gdal_burn(const std::string& source, const std::string& layer,
                               const prep::Extent& e, uint32_t w, uint32_t h, const fs::path& tif) {
  char args[400];
  std::snprintf(args, sizeof args, "-te %.9f %.9f %.9f %.9f -ts %u %u", e.xmin, e.ymin, e.xmax,
                e.ymax, w, h);
  const std::string cmd = "gdal_rasterize -q -burn 1 -init 0 -ot Byte " + std::string(args) +
                          " -l " + layer + " " + source + " " + tif.string();
  fs::remove(tif);
  std::vector<uint8_t> burn;
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ras(GDALDataset::Open(tif.c_str(), GDAL_OF_RASTER));
  EXPECT_TRUE(ras) << tif;
  if (!ras) return burn;
  burn.resize(size_t(w) * h);
  EXPECT_EQ(ras->GetRasterBand(1)->RasterIO(GF_Read, 0, 0, int(w), int(h), burn.data(), int(w),
                                            int(h), GDT_Byte, 0, 0),
            CE_None);
  return burn;
}

// Alpha > 0 of an 8-bit RGBA PNG (`render --decals`), read through GDAL.
std::vector<uint8_t> png_coverage(const fs::path& png, uint32_t w, uint32_t h) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(png.c_str(), GDAL_OF_RASTER));
  std::vector<uint8_t> alpha;
  EXPECT_TRUE(ds && ds->GetRasterCount() == 4 && ds->GetRasterXSize() == int(w) &&
              ds->GetRasterYSize() == int(h))
      << png;
  if (!ds || ds->GetRasterCount() != 4) return alpha;
  alpha.resize(size_t(w) * h);
  EXPECT_EQ(ds->GetRasterBand(4)->RasterIO(GF_Read, 0, 0, int(w), int(h), alpha.data(), int(w),
                                           int(h), GDT_Byte, 0, 0),
            CE_None);
  for (uint8_t& a : alpha) a = a > 0;
  return alpha;
}

// Every ring of every polygon in `layer` of `source` (absolute coordinates).
std::vector<prep::Ring> rings_of(const std::string& source, const std::string& layer_name) {
  GDALAllRegister();
  std::vector<prep::Ring> rings;
  std::unique_ptr<GDALDataset> ds(GDALDataset::Open(source.c_str(), GDAL_OF_VECTOR));
  OGRLayer* layer = ds ? ds->GetLayerByName(layer_name.c_str()) : nullptr;
  EXPECT_NE(layer, nullptr) << source << " " << layer_name;
  if (!layer) return rings;
  auto add_polygon = [&](const OGRPolygon& p) {
    for (const OGRLinearRing* r : p) {
      prep::Ring ring;
      for (int k = 0; k < r->getNumPoints(); ++k) ring.push_back({r->getX(k), r->getY(k)});
      rings.push_back(std::move(ring));
    }
  };
  for (auto& f : *layer) {
    const OGRGeometry* g = f->GetGeometryRef();
    if (!g) continue;
    if (wkbFlatten(g->getGeometryType()) == wkbPolygon) add_polygon(*g->toPolygon());
    if (wkbFlatten(g->getGeometryType()) == wkbMultiPolygon)
      for (const OGRPolygon* p : *g->toMultiPolygon()) add_polygon(*p);
  }
  return rings;
}

double distance_to_rings(const std::vector<prep::Ring>& rings, double x, double y);

// Drawn against burnt coverage, pixel by pixel, on the grid of extent `e`
// (absolute), leaving out pixels whose centre lies within `band` of a ring.
struct CoverageComparison {
  size_t considered = 0, mismatched = 0, in_band = 0, burnt = 0, drawn = 0;
  double mismatch() const { return considered ? double(mismatched) / double(considered) : 1.0; }
};
CoverageComparison compare_coverage(const std::vector<uint8_t>& drawn,
                                    const std::vector<uint8_t>& burnt, const prep::Extent& e,
                                    uint32_t w, uint32_t h, const std::vector<prep::Ring>& rings,
                                    double band) {
  CoverageComparison c;
  if (drawn.size() != size_t(w) * h || burnt.size() != drawn.size()) {
    ADD_FAILURE() << "coverage sizes " << drawn.size() << " and " << burnt.size() << " for " << w
                  << "x" << h;
    return c;
  }
  for (uint32_t j = 0; j < h; ++j)
    for (uint32_t i = 0; i < w; ++i) {
      const size_t k = i + size_t(w) * j;
      const bool a = drawn[k] != 0, b = burnt[k] != 0;
      c.burnt += b;
      c.drawn += a;
      if (a != b) {
        const double x = e.xmin + (i + 0.5) * (e.xmax - e.xmin) / w,
                     y = e.ymax - (j + 0.5) * (e.ymax - e.ymin) / h;
        if (distance_to_rings(rings, x, y) <= band) {
          ++c.in_band;
          continue;
        }
        ++c.mismatched;
      }
      ++c.considered;
    }
  return c;
}

// GL and CPU renders of the same view; returns false (with a skip reason)
// when there is no EGL display.
bool render_pair(const std::string& pkg, const std::string& name, const std::string& view_args,
                 std::vector<float>& gl, std::vector<float>& cpu, std::string& why) {
  const fs::path d = out_dir();
  auto g =
      run_tool("render " + pkg + " " + view_args + " --size 640x360 --aa none --raw " +
               (d / (name + "_gl.rgba")).string() + " -o " + (d / (name + "_gl.png")).string());
  if (g.rc == 8) {
    why = "no headless GL: " + g.output;
    return false;
  }
  EXPECT_EQ(g.rc, 0) << g.output;
  auto c =
      run_tool("render " + pkg + " " + view_args + " --size 640x360 --cpu --raw " +
               (d / (name + "_cpu.rgba")).string() + " -o " + (d / (name + "_cpu.png")).string());
  EXPECT_EQ(c.rc, 0) << c.output;
  gl = read_raw((d / (name + "_gl.rgba")).string());
  cpu = read_raw((d / (name + "_cpu.rgba")).string());
  EXPECT_EQ(gl.size(), 640u * 360u * 4u);
  EXPECT_EQ(cpu.size(), gl.size());
  return true;
}

// GL against the CPU evaluator on one view (render_pair): at least
// `min_considered` pixels compared and >= 99.9 % of them agreeing; `label`
// names the view in the printed line; `gl_image` receives the GL layer.
// False (with a skip reason) when there is no EGL display.
bool expect_gl_agrees_with_cpu(const std::string& pkg, const std::string& name,
                               const std::string& view_args, const char* label,
                               size_t min_considered, std::string& why,
                               std::vector<float>* gl_image = nullptr) {
  SCOPED_TRACE(name);
  std::vector<float> gl, cpu;
  if (!render_pair(pkg, name, view_args, gl, cpu, why)) return false;
  if (gl_image) *gl_image = gl;
  auto a = agreement(gl, cpu);
  ::testing::Test::RecordProperty("agreement",
                                  std::to_string(a.agree) + "/" + std::to_string(a.considered));
  std::printf("%s agreement %zu / %zu = %.5f\n", label, a.agree, a.considered, a.ratio());
  EXPECT_GT(a.considered, min_considered);
  EXPECT_GE(a.ratio(), 0.999);
  return true;
}

TEST(RenderSmoke, MonacoTopDownDecalLayerAgreesWithCpuEvaluator) {
  std::string why;
  const std::string& pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  if (!expect_gl_agrees_with_cpu(pkg, "monaco_topdown",
                                 "--dem " + kDem + " " + topdown_extent(pkg, kTopDown), "top-down",
                                 50000, why))
    GTEST_SKIP() << why;
}

TEST(RenderSmoke, MonacoObliquePerspectiveDecalLayerAgreesWithCpuEvaluator) {
  std::string why;
  const std::string& pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  // Looking north over the harbour from above the sea.
  if (!expect_gl_agrees_with_cpu(pkg, "monaco_oblique",
                                 "--dem " + kDem + " --eye 300,-2200,900 --target 0,0,60 --fov 40",
                                 "oblique", 20000, why))
    GTEST_SKIP() << why;
}

// Writes the cleaned polygons (holes included) to a GeoPackage in the frame
// CRS, absolute coordinates; returns every ring (absolute) for the
// edge-distance check.
std::vector<prep::Ring> write_polygons(const prep::SceneFeatures& scene, const std::string& path) {
  GDALAllRegister();
  GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
  std::unique_ptr<GDALDataset> ds(drv->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  OGRSpatialReference srs;
  srs.importFromWkt(scene.frame.crs_wkt.c_str());
  OGRLayer* layer = ds->CreateLayer("polygons", &srs, wkbPolygon, nullptr);
  std::vector<prep::Ring> rings;
  auto ring_of = [&](const prep::Ring& r) {
    OGRLinearRing lr;
    prep::Ring absolute;
    for (const auto& p : r) {
      lr.addPoint(p.x + scene.frame.origin_x, p.y + scene.frame.origin_y);
      absolute.push_back({p.x + scene.frame.origin_x, p.y + scene.frame.origin_y});
    }
    lr.closeRings();
    rings.push_back(std::move(absolute));
    return lr;
  };
  for (const auto& poly : scene.polygons) {
    OGRPolygon g;
    g.addRingDirectly(new OGRLinearRing(ring_of(poly.shell)));
    for (const auto& h : poly.holes) g.addRingDirectly(new OGRLinearRing(ring_of(h)));
    OGRFeature f(layer->GetLayerDefn());
    f.SetGeometry(&g);
    EXPECT_EQ(layer->CreateFeature(&f), OGRERR_NONE);
  }
  return rings;
}

double distance_to_rings(const std::vector<prep::Ring>& rings, double x, double y) {
  double best = 1e300;
  for (const auto& r : rings) {
    if (r.empty()) continue;
    double x0 = r[0].x, x1 = r[0].x, y0 = r[0].y, y1 = r[0].y;
    for (const auto& p : r) {
      x0 = std::min(x0, p.x), x1 = std::max(x1, p.x), y0 = std::min(y0, p.y),
      y1 = std::max(y1, p.y);
    }
    if (x < x0 - best || x > x1 + best || y < y0 - best || y > y1 + best)
      continue;  // farther than the best
    for (size_t i = 0; i < r.size(); ++i) {
      const auto& a = r[i];
      const auto& b = r[(i + 1) % r.size()];
      double dx = b.x - a.x, dy = b.y - a.y, l2 = dx * dx + dy * dy;
      double t = l2 > 0 ? std::clamp(((x - a.x) * dx + (y - a.y) * dy) / l2, 0.0, 1.0) : 0.0;
      best = std::min(best, std::hypot(a.x + t * dx - x, a.y + t * dy - y));
    }
  }
  return best;
}

TEST(RenderSmoke, MonacoTopDownPolygonCoverageMatchesGdalRasterize) {
  std::string why;
  const std::string& pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  const fs::path d = out_dir();
  // Aliased GL coverage of the polygons alone.
  auto g = run_tool("render " + pkg + " " + topdown_extent(pkg, kTopDown) +
                    " --size 640x360 --aa none --only polygons --raw " +
                    (d / "monaco_polygons_gl.rgba").string() + " -o " +
                    (d / "monaco_polygons_gl.png").string());
  if (g.rc == 8) GTEST_SKIP() << "no headless GL: " << g.output;
  ASSERT_EQ(g.rc, 0) << g.output;
  auto gl = read_raw((d / "monaco_polygons_gl.rgba").string());
  std::vector<uint8_t> drawn(640 * 360);
  for (size_t k = 0; k < drawn.size() && 4 * k + 3 < gl.size(); ++k) drawn[k] = gl[4 * k + 3] > 0;
  // The same cleaned polygons (the pipeline is deterministic), burnt by GDAL.
  prep::BuildSpec spec = prep::load_scene_file(kSource + "/samples/monaco/scene.toml");
  prep::BuildRequest req;
  req.dry_run = true;
  prep::BuildResult built = prep::run_build(spec, req);
  const std::string gpkg = (d / "monaco_polygons.gpkg").string();
  fs::remove(gpkg);
  auto rings = write_polygons(built.scene, gpkg);
  const prep::Extent view = package_frame(pkg).absolute(kTopDown);
  const auto burn = gdal_burn(gpkg, "polygons", view, 640, 360, d / "monaco_polygons.tif");
  // Only pixel centres exactly on an edge may go either way.
  const CoverageComparison c = compare_coverage(drawn, burn, view, 640, 360, rings, 1e-6);
  std::printf("gdal_rasterize agreement %zu / %zu (%zu excluded, %zu burnt)\n",
              c.considered - c.mismatched, c.considered, c.in_band, c.burnt);
  RecordProperty("agreement",
                 std::to_string(c.considered - c.mismatched) + "/" + std::to_string(c.considered));
  EXPECT_GT(c.burnt, 50000u);
  EXPECT_LE(c.mismatch(), 0.001);
}

// ---------------------------------------------------------------------------
// One coordinate convention: `render --extent` takes absolute coordinates of
// the package's frame CRS, like `build --extent` and the world file. A
// package built with --crs EPSG:32632 (absolute UTM metres) from the sample's
// buildings, rendered by the CPU evaluator, against gdal_rasterize of the
// same source layer reprojected by ogr2ogr (GDAL's programs, not ours).
// ---------------------------------------------------------------------------

const std::string kBuildingsWhere = "building IS NOT NULL";

// The UTM package and the oracle's GeoPackage (layer "buildings"); "" with
// a reason when either cannot be made.
struct UtmBuildings {
  std::string package, oracle;
};
const UtmBuildings& utm_buildings(std::string* why) {
  static UtmBuildings made;
  static std::string reason;
  static bool tried = false;
  if (!tried) {
    tried = true;
    const fs::path d = out_dir() / "utm";
    fs::create_directories(d);
    BuildLock lock(out_dir() / "utm.lock");
    const fs::path pkg = d / "buildings_utm.decals", gpkg = d / "buildings_utm.gpkg";
    const std::string pbf = kSource + "/samples/monaco/monaco.osm.pbf";
    if (!fresh(pkg) || !fs::exists(gpkg)) {
      // --resolution 0: every vertex kept, as gdal_rasterize sees them.
      auto r = run_tool("build " + pbf + " --layer multipolygons --where '" + kBuildingsWhere +
                        "' --kind polygon --crs EPSG:32632 --resolution 0 -q -o " + pkg.string());
      if (r.rc != 0)
        reason = "decalprep build failed (rc " + std::to_string(r.rc) + "): " + r.output;
      fs::remove(gpkg);
      const std::string cmd = "ogr2ogr -f GPKG -t_srs EPSG:32632 -nln buildings -where '" +
                              kBuildingsWhere + "' " + gpkg.string() + " " + pbf + " multipolygons";
      if (reason.empty() && std::system(cmd.c_str()) != 0) reason = "ogr2ogr failed: " + cmd;
    }
    if (reason.empty()) made = {pkg.string(), gpkg.string()};
  }
  if (why) *why = reason;
  return made;
}

// Renders `view_args` with the CPU evaluator (--decals PNG) and compares its
// coverage with gdal_rasterize over `oracle_extent`, outside a band of one
// pixel around the source polygons' edges.
CoverageComparison cpu_against_gdal(const UtmBuildings& b, const std::string& name,
                                    const std::string& view_args, const prep::Extent& oracle_extent,
                                    uint32_t w, uint32_t h) {
  const fs::path d = out_dir() / "utm";
  const fs::path decals = d / (name + "_decals.png");
  fs::remove(decals);
  auto r = run_tool("render " + b.package + " --cpu " + view_args + " --size " + std::to_string(w) +
                    "x" + std::to_string(h) + " --decals " + decals.string() + " -o " +
                    (d / (name + ".png")).string());
  EXPECT_EQ(r.rc, 0) << r.output;
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  const auto drawn = png_coverage(decals, w, h);
  const auto burnt =
      gdal_burn(b.oracle, "buildings", oracle_extent, w, h, d / (name + "_gdal.tif"));
  static const std::vector<prep::Ring> rings = rings_of(b.oracle, "buildings");
  const double pixel = std::max((oracle_extent.xmax - oracle_extent.xmin) / w,
                                (oracle_extent.ymax - oracle_extent.ymin) / h);
  return compare_coverage(drawn, burnt, oracle_extent, w, h, rings, pixel);
}

// Central Monaco in UTM 32N: absolute metres, off the package's 1 m origin grid.
const prep::Extent kUtmView{372000.25, 4843200.75, 373600.25, 4844200.75};

TEST(RenderExtent, CpuTopDownInAbsoluteUtmMatchesGdalRasterizeOfTheSourceLayer) {
  std::string why;
  const UtmBuildings& b = utm_buildings(&why);
  if (b.package.empty()) GTEST_SKIP() << why;
  const CoverageComparison c =
      cpu_against_gdal(b, "absolute", "--extent " + extent_text(kUtmView, "%.2f,%.2f,%.2f,%.2f"),
                       kUtmView, 800, 500);
  std::printf(
      "absolute UTM view: %zu of %zu pixels outside the one-pixel band differ (%.2e); %zu in the "
      "band, "
      "%zu burnt, %zu drawn\n",
      c.mismatched, c.considered, c.mismatch(), c.in_band, c.burnt, c.drawn);
  RecordProperty("mismatch", std::to_string(c.mismatch()));
  EXPECT_GT(c.burnt, 50000u);
  EXPECT_LT(c.mismatch(), 5e-4);
  // The world file beside the image holds the extent as given.
  const WorldFile wf = read_world_file(out_dir() / "utm" / "absolute.pgw");
  ASSERT_TRUE(wf.ok);
  EXPECT_NEAR(wf.dx, 2.0, 1e-12);
  EXPECT_NEAR(wf.dy, -2.0, 1e-12);
  EXPECT_NEAR(wf.x0, kUtmView.xmin + 1.0, 1e-6);
  EXPECT_NEAR(wf.y0, kUtmView.ymax - 1.0, 1e-6);
}

TEST(RenderExtent, AnExtentInAnotherCrsIsTransformedIntoTheFrameCrs) {
  std::string why;
  const UtmBuildings& b = utm_buildings(&why);
  if (b.package.empty()) GTEST_SKIP() << why;
  const prep::Extent lonlat{7.4155, 43.7295, 7.4305, 43.7385};
  // The oracle: gdaltransform (GDAL's program) of 21 points along each edge,
  // their bounding box in UTM 32N.
  const fs::path pts = out_dir() / "utm" / "edge_points.txt",
                 utm = out_dir() / "utm" / "edge_points_utm.txt";
  {
    std::ofstream o(pts);
    o.precision(12);
    for (int k = 0; k <= 20; ++k) {
      const double t = k / 20.0, x = lonlat.xmin + t * (lonlat.xmax - lonlat.xmin),
                   y = lonlat.ymin + t * (lonlat.ymax - lonlat.ymin);
      o << x << " " << lonlat.ymin << "\n" << x << " " << lonlat.ymax << "\n";
      o << lonlat.xmin << " " << y << "\n" << lonlat.xmax << " " << y << "\n";
    }
  }
  const std::string cmd =
      "gdaltransform -s_srs EPSG:4326 -t_srs EPSG:32632 < " + pts.string() + " > " + utm.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  prep::Extent oracle{1e300, 1e300, -1e300, -1e300};
  std::ifstream in(utm);
  double x, y, z;
  int n = 0;
  while (in >> x >> y >> z) {
    oracle = {std::min(oracle.xmin, x), std::min(oracle.ymin, y), std::max(oracle.xmax, x),
              std::max(oracle.ymax, y)};
    ++n;
  }
  ASSERT_EQ(n, 84);
  const CoverageComparison c =
      cpu_against_gdal(b, "lonlat",
                       // --stretch: gdal_rasterize's -te is the transformed box as it is
                       "--extent " + extent_text(lonlat, "%.4f,%.4f,%.4f,%.4f") +
                           " --extent-crs EPSG:4326 --stretch",
                       oracle, 600, 500);
  std::printf(
      "EPSG:4326 view: %zu of %zu pixels outside the one-pixel band differ (%.2e); %zu burnt\n",
      c.mismatched, c.considered, c.mismatch(), c.burnt);
  EXPECT_GT(c.burnt, 20000u);
  EXPECT_LT(c.mismatch(), 5e-4);
  const WorldFile wf = read_world_file(out_dir() / "utm" / "lonlat.pgw");
  ASSERT_TRUE(wf.ok);
  EXPECT_NEAR(wf.x0 - 0.5 * wf.dx, oracle.xmin, 1e-3);
  EXPECT_NEAR(wf.y0 - 0.5 * wf.dy, oracle.ymax, 1e-3);
  EXPECT_NEAR(wf.x0 - 0.5 * wf.dx + 600 * wf.dx, oracle.xmax, 1e-3);
  EXPECT_NEAR(wf.y0 - 0.5 * wf.dy + 500 * wf.dy, oracle.ymin, 1e-3);
}

TEST(RenderExtent, AViewThatMissesThePackageWarnsWithBothExtents) {
  std::string why;
  const UtmBuildings& b = utm_buildings(&why);
  if (b.package.empty()) GTEST_SKIP() << why;
  const PackageFrame f = package_frame(b.package);
  // Metres relative to the origin (the old convention) lie far off in UTM.
  auto r = run_tool("render " + b.package + " --cpu --extent 0,0,800,500 --size 80x50 -o " +
                    (out_dir() / "utm" / "miss.png").string());
  EXPECT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("warning"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("0.000,0.000,800.000,500.000"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(extent_text(f.absolute(f.extent), "%.3f,%.3f,%.3f,%.3f")),
            std::string::npos)
      << r.output;
  // --extent-crs alone, and a CRS PROJ does not know.
  EXPECT_EQ(run_tool("render " + b.package + " --cpu --extent-crs EPSG:4326 -o " +
                     (out_dir() / "utm" / "x.png").string())
                .rc,
            2);
  auto bad =
      run_tool("render " + b.package + " --cpu --extent 0,0,1,1 --extent-crs EPSG:999999 -o " +
               (out_dir() / "utm" / "x.png").string());
  EXPECT_EQ(bad.rc, 3) << bad.output;
  EXPECT_NE(bad.output.find("EPSG:999999"), std::string::npos) << bad.output;
}

// ---------------------------------------------------------------------------
// Every decal type and style: a synthetic scene written as GeoJSON and read
// through GDAL by `decalprep build` (lon/lat around 7.42 E, 43.74 N).
// ---------------------------------------------------------------------------

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

std::string feature(const std::string& geometry, const std::string& props = "{}") {
  return R"({"type":"Feature","properties":)" + props + R"(,"geometry":)" + geometry + "}";
}
std::string collection(const std::vector<std::string>& features) {
  std::string s = R"({"type":"FeatureCollection","features":[)";
  for (size_t i = 0; i < features.size(); ++i) s += (i ? "," : "") + features[i];
  return s + "]}";
}
// GeoJSON coordinates "[[x,y],...]" of `pts`, six decimals.
std::string coords(std::initializer_list<std::array<double, 2>> pts) {
  std::string s = "[";
  char b[64];
  for (const auto& [x, y] : pts) {
    std::snprintf(b, sizeof b, "%s[%.6f,%.6f]", s.size() > 1 ? "," : "", x, y);
    s += b;
  }
  return s + "]";
}
std::string ring(double x0, double y0, double x1, double y1, bool ccw = true) {
  return ccw ? coords({{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}, {x0, y0}})
             : coords({{x0, y0}, {x0, y1}, {x1, y1}, {x1, y0}, {x0, y0}});
}
// An L-shaped polygon with its lower-left corner at (x, y), about 120 m.
std::string l_shape(double x, double y) {
  return R"({"type":"Polygon","coordinates":[)" +
         coords({{x, y},
                 {x + 0.0015, y},
                 {x + 0.0015, y + 0.0005},
                 {x + 0.0006, y + 0.0005},
                 {x + 0.0006, y + 0.0011},
                 {x, y + 0.0011},
                 {x, y}}) +
         "]}";
}
// A zigzag with a sharp (< 40 degrees, round fallback) and obtuse turns.
std::string zigzag(double x, double y) {
  return R"({"type":"LineString","coordinates":)" +
         coords({{x, y},
                 {x + 0.0005, y + 0.0008},
                 {x + 0.0007, y},
                 {x + 0.0012, y + 0.0004},
                 {x + 0.0018, y + 0.0002}}) +
         "}";
}

const std::string& styles_package(std::string* why) {
  static std::string path, reason;
  static bool tried = false;
  if (!tried) {
    tried = true;
    fs::path d = out_dir() / "styles";
    fs::create_directories(d);
    BuildLock lock(out_dir() / "styles.lock");
    if (fresh(d / "styles.decals")) {
      path = (d / "styles.decals").string();
      if (why) *why = reason;
      return path;
    }
    // Polygon with a hole, and an island inside the hole (its own feature).
    write_text(d / "polys.geojson",
               collection({feature(R"({"type":"Polygon","coordinates":[)" +
                                   ring(7.4200, 43.7400, 7.4216, 43.7412) + "," +
                                   ring(7.4204, 43.7403, 7.4212, 43.7409, false) + "]}"),
                           feature(R"({"type":"Polygon","coordinates":[)" +
                                   ring(7.4206, 43.7405, 7.4210, 43.7407) + "]}")}));
    write_text(d / "l_normal.geojson", collection({feature(l_shape(7.4222, 43.7400))}));
    write_text(d / "l_inset.geojson", collection({feature(l_shape(7.4241, 43.7400))}));
    write_text(d / "l_offset.geojson", collection({feature(l_shape(7.4222, 43.7414))}));
    write_text(d / "z_round.geojson", collection({feature(zigzag(7.4200, 43.7415))}));
    write_text(d / "z_miter.geojson", collection({feature(zigzag(7.4241, 43.7414))}));
    write_text(d / "z_bevel.geojson", collection({feature(zigzag(7.4200, 43.7426))}));
    write_text(
        d / "cross.geojson",
        collection(
            {feature(R"({"type":"LineString","coordinates":[[7.4225,43.7428],[7.4255,43.7436]]})",
                     R"({"imp":1})"),
             feature(R"({"type":"LineString","coordinates":[[7.4225,43.7436],[7.4255,43.7428]]})",
                     R"({"imp":2})")}));
    write_text(d / "scene.toml", R"(
[[layer]]
name = "polys"
source = "polys.geojson"
kind = "polygon"
color = "#3060c0c0"
[[layer]]
name = "l_normal"
source = "l_normal.geojson"
kind = "outline"
corner = "miter"
width = 6
color = "#202020a0"
[[layer]]
name = "l_inset"
source = "l_inset.geojson"
kind = "outline"
corner = "miter"
outline_mode = "inset"
width = 6
color = "#802020c0"
[[layer]]
name = "l_offset"
source = "l_offset.geojson"
kind = "outline"
corner = "miter"
outline_mode = "offset"
width = 6
color = "#208020c0"
[[layer]]
name = "z_round"
source = "z_round.geojson"
kind = "line"
corner = "round"
width = 8
color = "#e0a000b0"
[[layer]]
name = "z_miter"
source = "z_miter.geojson"
kind = "line"
corner = "miter"
width = 8
color = "#a000e0b0"
[[layer]]
name = "z_bevel"
source = "z_bevel.geojson"
kind = "line"
corner = "bevel"
width = 8
color = "#00a0a0b0"
[[layer]]
name = "cross"
source = "cross.geojson"
kind = "line"
width = 10
order_attribute = "imp"
color_attribute = "imp"
color_ramp = [[1, "#ff000080"], [2, "#0000ff80"]]
)");
    std::string pkg = (d / "styles.decals").string();
    auto r = run_tool("build " + (d / "scene.toml").string() + " -o " + pkg + " -q");
    if (r.rc != 0)
      reason = "decalprep build of the styles scene failed (rc " + std::to_string(r.rc) +
               "): " + r.output;
    else
      path = pkg;
  }
  if (why) *why = reason;
  return path;
}

const std::string kStylesView = "--extent 7.4196,43.7396,7.4262,43.7440 --extent-crs EPSG:4326";

TEST(RenderSmoke, EveryDecalTypeAndStyleAgreesWithCpuEvaluatorTopDown) {
  std::string why;
  const std::string& pkg = styles_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  std::vector<float> gl;
  if (!expect_gl_agrees_with_cpu(pkg, "styles_topdown", kStylesView, "styles top-down", 10000, why,
                                 &gl))
    GTEST_SKIP() << why;

  // The crossing of the two transparent lines shows the more important one
  // (imp 2, blue) over the other (red): read the pixel at the crossing.
  // World file: pixel size and the upper-left pixel centre in the frame.
  const WorldFile wf = read_world_file(out_dir() / "styles_topdown_gl.pgw");
  ASSERT_TRUE(wf.ok) << "world file";
  const double dx = wf.dx, dy = wf.dy, x0 = wf.x0, y0 = wf.y0;
  decal::Package package;
  ASSERT_TRUE(decal::Package::open(pkg, package));
  auto meta = nlohmann::json::parse(package.metadata_json());
  OGRSpatialReference ll, frame;
  ll.importFromEPSG(4326);
  ll.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  frame.importFromWkt(meta["crs_wkt"].get<std::string>().c_str());
  frame.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> ct(OGRCreateCoordinateTransformation(&ll, &frame));
  double cx = 7.4240, cy = 43.7432;  // where the two lines cross
  ASSERT_TRUE(ct->Transform(1, &cx, &cy));
  // The world file is in absolute frame coordinates (not scene-relative),
  // and GDAL reads the same placement and CRS from the PNG's .aux.xml.
  {
    GDALAllRegister();
    GDALDatasetUniquePtr img(GDALDataset::Open(
        (out_dir() / "styles_topdown_gl.png").string().c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
    ASSERT_TRUE(img);
    double gt[6];
    ASSERT_EQ(img->GetGeoTransform(gt), CE_None);
    EXPECT_NEAR(gt[0] + 0.5 * gt[1], x0, 1e-6);
    EXPECT_NEAR(gt[3] + 0.5 * gt[5], y0, 1e-6);
    ASSERT_NE(img->GetSpatialRef(), nullptr);
    EXPECT_TRUE(img->GetSpatialRef()->IsSame(&frame));
  }
  const int i = int(std::lround((cx - x0) / dx)), j = int(std::lround((cy - y0) / dy));
  ASSERT_TRUE(i >= 0 && i < 640 && j >= 0 && j < 360);
  const float* c = &gl[4 * (size_t(i) + 640 * size_t(j))];
  const double a_top = 128 / 255.0, alpha = a_top + (1 - a_top) * a_top;
  EXPECT_NEAR(c[3], alpha, 2.0 / 255);
  EXPECT_NEAR(c[2], a_top / alpha, 2.0 / 255);                // blue on top
  EXPECT_NEAR(c[0], (1 - a_top) * a_top / alpha, 2.0 / 255);  // red below
}

TEST(RenderSmoke, EveryDecalTypeAndStyleAgreesWithCpuEvaluatorInPerspective) {
  std::string why;
  const std::string& pkg = styles_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  if (!expect_gl_agrees_with_cpu(pkg, "styles_oblique", "--fit --pitch 35", "styles oblique", 5000,
                                 why))
    GTEST_SKIP() << why;
}

// Quality of the anti-aliasing modes: mean absolute difference of the
// premultiplied decal layer from a 16x supersampled reference (4x4 box
// filter of an aliased 2560x1440 render of the same view).
TEST(RenderSmoke, AntiAliasingModesAreCloserToSupersampledReferenceThanAliased) {
  std::string why;
  const std::string& pkg = styles_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  const fs::path d = out_dir();
  auto render = [&](const std::string& aa, const std::string& size, const std::string& name) {
    auto r = run_tool("render " + pkg + " " + kStylesView + " --size " + size + " --aa " + aa +
                      " --raw " + (d / (name + ".rgba")).string() + " -o " +
                      (d / (name + ".png")).string());
    return r;
  };
  auto ref_run = render("none", "2560x1440", "aa_reference");
  if (ref_run.rc == 8) GTEST_SKIP() << "no headless GL: " << ref_run.output;
  ASSERT_EQ(ref_run.rc, 0) << ref_run.output;
  auto big = read_raw((d / "aa_reference.rgba").string());
  ASSERT_EQ(big.size(), 2560u * 1440u * 4u);
  std::vector<double> ref(640 * 360 * 4, 0.0);
  for (uint32_t j = 0; j < 1440; ++j)
    for (uint32_t i = 0; i < 2560; ++i) {
      const float* c = &big[4 * (i + 2560 * size_t(j))];
      double* o = &ref[4 * (i / 4 + 640 * size_t(j / 4))];
      for (int k = 0; k < 3; ++k) o[k] += c[k] * c[3] / 16.0;
      o[3] += c[3] / 16.0;
    }
  std::map<std::string, double> error;
  for (const std::string aa : {"none", "coverage", "msaa4"}) {
    auto r = render(aa, "640x360", "aa_" + aa);
    ASSERT_EQ(r.rc, 0) << r.output;
    auto img = read_raw((d / ("aa_" + aa + ".rgba")).string());
    ASSERT_EQ(img.size(), ref.size());
    double sum = 0;
    size_t n = 0;
    for (size_t p = 0; p < ref.size(); p += 4) {
      if (ref[p + 3] == 0 && img[p + 3] == 0) continue;
      for (int k = 0; k < 3; ++k) sum += std::abs(img[p + k] * img[p + 3] - ref[p + k]);
      sum += std::abs(img[p + 3] - ref[p + 3]);
      n += 4;
    }
    error[aa] = sum / double(n);
    std::printf("aa %-9s mean |difference| from 16x supersampling: %.5f\n", aa.c_str(), error[aa]);
    RecordProperty("mean_abs_error_" + aa, std::to_string(error[aa]));
  }
  EXPECT_LT(error["coverage"], 0.8 * error["none"]);
  EXPECT_LT(error["msaa4"], 0.8 * error["none"]);
}

// Clipped outlines (SPEC "Clipped outlines", thesis Fig. 4.8): U-shaped
// buildings whose 4 m arms are narrower than the 6 m band of a 6 m wide
// inset/offset outline. Built at (7.42 E, 43.745 N), metres converted with
// the local scale (the tests only use places far from any edge).
struct Metres {
  double lon0 = 7.4200, lat0 = 43.7450;
  double lon(double x) const { return lon0 + x / (111320.0 * std::cos(lat0 * M_PI / 180.0)); }
  double lat(double y) const { return lat0 + y / 110950.0; }
};
// The U: 14 m x 30 m, arms 4 m wide around a 6 m gap (x 4..10, y 4..30).
std::string u_shape(const Metres& m, double x0) {
  const double xy[][2] = {{0, 0}, {14, 0}, {14, 30}, {10, 30}, {10, 4},
                          {4, 4}, {4, 30}, {0, 30},  {0, 0}};
  std::string s = R"({"type":"Polygon","coordinates":[[)";
  char b[64];
  for (size_t i = 0; i < std::size(xy); ++i) {
    std::snprintf(b, sizeof b, "%s[%.8f,%.8f]", i ? "," : "", m.lon(x0 + xy[i][0]),
                  m.lat(xy[i][1]));
    s += b;
  }
  return s + "]]}";
}
// --stretch: the view is the transformed extent as it is, whatever the
// aspect of --size (the analytic pixel positions below assume it).
std::string extent_of(const Metres& m, double x0, double y0, double x1, double y1) {
  char b[170];
  std::snprintf(b, sizeof b, "--extent %.8f,%.8f,%.8f,%.8f --extent-crs EPSG:4326 --stretch",
                m.lon(x0), m.lat(y0), m.lon(x1), m.lat(y1));
  return b;
}

TEST(RenderSmoke, OutlinesOfNarrowRingsAreClippedByTheirRingOnTheGpuInBothBindings) {
  const fs::path d = out_dir() / "narrow";
  fs::create_directories(d);
  const Metres m;
  // Inset U at x 0..14, offset U at x 100..114 (their bands never meet).
  write_text(d / "inset.geojson", collection({feature(u_shape(m, 0))}));
  write_text(d / "offset.geojson", collection({feature(u_shape(m, 100))}));
  write_text(d / "scene.toml", R"(
[[layer]]
name = "inset"
source = "inset.geojson"
kind = "outline"
corner = "miter"
outline_mode = "inset"
width = 6
color = "#c02020ff"
[[layer]]
name = "offset"
source = "offset.geojson"
kind = "outline"
corner = "miter"
outline_mode = "offset"
width = 6
color = "#20a020ff"
)");
  const std::string pkg = (d / "narrow.decals").string();
  auto b = run_tool("build " + (d / "scene.toml").string() + " -o " + pkg + " -q");
  ASSERT_EQ(b.rc, 0) << b.output;
  auto render = [&](const std::string& view, const std::string& how, const std::string& name) {
    const std::string raw = (d / (name + ".rgba")).string();
    auto r = run_tool("render " + pkg + " " + view + " --size 200x120 " + how + " --raw " + raw +
                      " -o " + (d / (name + ".png")).string());
    return std::make_pair(r, read_raw(raw));
  };
  // Whole scene: GPU (both bindings) against the CPU evaluator, which the
  // evaluate tests check against GEOS (band ∩ ring, band − ring).
  const std::string all = extent_of(m, -10, -10, 124, 40);
  auto [rc_cpu, cpu] = render(all, "--cpu", "all_cpu");
  ASSERT_EQ(rc_cpu.rc, 0) << rc_cpu.output;
  for (const std::string binding : {"ssbo", "texture"}) {
    auto [r, gl] = render(all, "--aa none --binding " + binding, "all_" + binding);
    if (r.rc == 8) GTEST_SKIP() << "no headless GL: " << r.output;
    ASSERT_EQ(r.rc, 0) << r.output;
    const auto a = agreement(gl, cpu);
    std::printf("narrow rings, %s binding: agreement %zu / %zu = %.5f\n", binding.c_str(), a.agree,
                a.considered, a.ratio());
    EXPECT_GT(a.considered, 2000u);
    EXPECT_GE(a.ratio(), 0.999) << binding;
    // Analytic: inside the inset U's gap (outside the polygon, 0.5 m from
    // both arms) nothing is drawn, though the one-sided band of each arm
    // reaches 2 m into it; the offset U's gap lies within 6 m of the ring
    // outside the polygon, so all of it is drawn.
    auto [ri, gap_inset] = render(extent_of(m, 4.5, 8, 9.5, 26), "--aa none --binding " + binding,
                                  "gap_inset_" + binding);
    ASSERT_EQ(ri.rc, 0) << ri.output;
    auto [ro, gap_offset] = render(extent_of(m, 104.5, 8, 109.5, 26),
                                   "--aa none --binding " + binding, "gap_offset_" + binding);
    ASSERT_EQ(ro.rc, 0) << ro.output;
    ASSERT_EQ(gap_inset.size(), 200u * 120u * 4u);
    ASSERT_EQ(gap_offset.size(), gap_inset.size());
    size_t leaked = 0, missing = 0;
    for (size_t p = 3; p < gap_inset.size(); p += 4) {
      leaked += gap_inset[p] > 0;
      missing += gap_offset[p] < 0.99f;
    }
    EXPECT_EQ(leaked, 0u) << binding << ": inset outline drawn in the gap of its U";
    EXPECT_EQ(missing, 0u) << binding << ": offset outline missing in the gap of its U";
  }
}

}  // namespace

}  // namespace render_smoke
