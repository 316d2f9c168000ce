// One terrain surface (prep/dem.hpp): the heights `decalprep build` stores
// for dynamic-line vertices and the terrain mesh `decalprep render` draws
// under them are the same surface, on a generated GeoTIFF with a no-data
// strip, a band scale and offset and heights in feet, in a projected CRS.
// The oracle is the analytic surface of the generated cells (and the
// documented no-data rule), never the code under test.
#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogr_spatialref.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "decal/reader.hpp"
#include "dem_tiff.hpp"
#include "epsg_wkt.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

namespace fs = std::filesystem;
namespace R = prep::render;
using prep::test::run_tool;

namespace {

// The DEM: 28 x 24 cells of 5 m, north-up, EPSG:32632, Int16 raw values,
// feet = raw * 0.01 + 900, unit "ft"; built with z_scale 1.5.
constexpr int kW = 28, kH = 24;
constexpr double kCell = 5, kX0 = 600000, kY0 = 5001000;
constexpr double kScale = 0.01, kOffset = 900, kFoot = 0.3048, kZScale = 1.5;
constexpr double kNoData = -32768;
// No-data: row 12, columns 5..22 (one row thick, so every such cell has
// valid neighbours; prep/dem.hpp: it takes the first of them in row-major
// order, which is (i - 1, j - 1)).
constexpr int kStripRow = 12, kStripFirst = 5, kStripLast = 22;

bool in_strip(int i, int j) {
  return j == kStripRow && i >= kStripFirst && i <= kStripLast;
}
// feet(i, j) = 1000 + 0.25 i - 0.2 j + 0.02 i j at cell (i, j); raw is an integer.
double raw_of(int i, int j) {
  return 10000 + 25 * i - 20 * j + 2 * i * j;
}
double feet_of(double i, double j) {
  return 1000 + 0.25 * i - 0.2 * j + 0.02 * i * j;
}

// Height in metres of cell (i, j) after the documented fill.
double cell_metres(int i, int j) {
  i = std::clamp(i, 0, kW - 1);
  j = std::clamp(j, 0, kH - 1);
  if (in_strip(i, j)) {
    --i;
    --j;
  }
  return kZScale * kFoot * feet_of(i, j);
}

// The analytic surface at absolute EPSG:32632 (x, y): bilinear between cell
// centres, the edge cell beyond the outermost ones. Away from the strip it
// is the polynomial itself (bilinear interpolation reproduces 1, i, j, i j).
double surface(double x, double y, bool* near_strip = nullptr) {
  const double u = (x - kX0) / kCell - 0.5, v = (kY0 - y) / kCell - 0.5;
  const int i = int(std::floor(u)), j = int(std::floor(v));
  const double tx = u - i, ty = v - j;
  if (near_strip) {
    *near_strip = false;
    for (int dj = 0; dj < 2; ++dj)
      for (int di = 0; di < 2; ++di)
        *near_strip =
            *near_strip || in_strip(std::clamp(i + di, 0, kW - 1), std::clamp(j + dj, 0, kH - 1));
    if (!*near_strip && u >= 0 && v >= 0 && u <= kW - 1 && v <= kH - 1) {
      const double poly = kZScale * kFoot * feet_of(u, v);
      const double bil = (1 - ty) * ((1 - tx) * cell_metres(i, j) + tx * cell_metres(i + 1, j)) +
                         ty * ((1 - tx) * cell_metres(i, j + 1) + tx * cell_metres(i + 1, j + 1));
      EXPECT_NEAR(bil, poly, 1e-9);  // the oracle's own consistency
    }
  }
  return (1 - ty) * ((1 - tx) * cell_metres(i, j) + tx * cell_metres(i + 1, j)) +
         ty * ((1 - tx) * cell_metres(i, j + 1) + tx * cell_metres(i + 1, j + 1));
}

// The DEM through GDAL's GTiff driver; without a CRS when `with_crs` is false.
void write_dem(const std::string& path, bool with_crs) {
  GDALDatasetUniquePtr ds = create_dem_tiff(path, kW, kH, GDT_Int16, kX0, kY0, kCell,
                                            with_crs ? epsg_wkt(32632) : std::string());
  ASSERT_TRUE(ds);
  GDALRasterBand* b = ds->GetRasterBand(1);
  b->SetNoDataValue(kNoData);
  b->SetScale(kScale);
  b->SetOffset(kOffset);
  b->SetUnitType("ft");
  std::vector<double> raw(size_t(kW) * kH);
  for (int j = 0; j < kH; ++j)
    for (int i = 0; i < kW; ++i) raw[size_t(j) * kW + i] = in_strip(i, j) ? kNoData : raw_of(i, j);
  ASSERT_EQ(b->RasterIO(GF_Write, 0, 0, kW, kH, raw.data(), kW, kH, GDT_Float64, 0, 0, nullptr),
            CE_None);
}

// Three trails over the DEM (EPSG:32632): across the strip diagonally,
// north-south through it, and a zigzag around its west end.
void write_trails(const std::string& path) {
  GDALAllRegister();
  GDALDriver* gpkg = GetGDALDriverManager()->GetDriverByName("GPKG");
  ASSERT_NE(gpkg, nullptr);
  fs::remove(path);
  GDALDatasetUniquePtr ds(gpkg->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
  ASSERT_TRUE(ds);
  OGRSpatialReference srs;
  srs.importFromEPSG(32632);
  OGRLayer* layer = ds->CreateLayer("trails", &srs, wkbLineString, nullptr);
  ASSERT_NE(layer, nullptr);
  const std::vector<std::vector<std::array<double, 2>>> lines = {
      {{600010, 5000990}, {600130, 5000895}},
      {{600070, 5000995}, {600071.3, 5000885}},
      {{600012, 5000950},
       {600031, 5000925},
       {600049, 5000946.5},
       {600083, 5000931},
       {600126, 5000941}}};
  for (const auto& l : lines) {
    OGRFeature f(layer->GetLayerDefn());
    OGRLineString ls;
    for (const auto& p : l) ls.addPoint(p[0], p[1]);
    f.SetGeometry(&ls);
    ASSERT_EQ(layer->CreateFeature(&f), OGRERR_NONE);
  }
}

// One folder per test: ctest runs the tests of this file side by side, and
// two of them write a trails.gpkg of their own.
fs::path work_dir() {
  const char* test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
  fs::path d = fs::current_path() / "render-out" / "terrain_surface" / test;
  fs::create_directories(d);
  return d;
}

void write_scene(const fs::path& path, const std::string& dem, const std::string& extra = "") {
  std::ofstream out(path);
  out << "# One terrain surface: a dynamic trail layer over a generated DEM.\n"
      << "crs = \"EPSG:32632\"\n"
      << "dem = \"" << dem << "\"\n"
      << extra << "\n[build]\nz_scale = " << kZScale << "\n\n"
      << "[[layer]]\nname = \"trails\"\nsource = \"trails.gpkg\"\nkind = \"line\"\ndynamic = "
         "true\n";
}

struct SurfaceCheck {
  size_t vertices = 0, near_strip = 0;
  double stored_vs_mesh = 0, stored_vs_oracle = 0, mesh_vs_oracle = 0, mesh_bound = 0;
};

// For every stored dynamic-line vertex: the stored height, the height of the
// mesh render draws there (the package's recorded DEM through the same call
// as `decalprep render`) and the analytic surface.
SurfaceCheck check_package(const std::string& pkg_path) {
  SurfaceCheck c;
  decal::Package pkg;
  const decal::Status st = decal::Package::open(pkg_path, pkg);
  EXPECT_TRUE(st) << st.message;
  if (!st) return c;
  const R::DecalSource src = R::source_of(pkg);
  const prep::DemSpec dem = R::recorded_dem(std::string(pkg.metadata_json()), pkg_path);
  EXPECT_DOUBLE_EQ(dem.z_scale, kZScale);
  EXPECT_FALSE(dem.nodata_fill);
  const R::Heightfield mesh = R::load_heightfield(dem, src.frame, src.extent, R::kMeshSamples);
  c.mesh_bound = mesh.surface_error_bound;
  const decal::BlobView* v = pkg.find(decal::BlobId::dyn_vertices);
  EXPECT_NE(v, nullptr);
  if (!v) return c;
  const auto* q = reinterpret_cast<const int32_t*>(v->bytes.data());
  for (uint64_t k = 0; k < v->count; ++k) {
    const double x = q[4 * k] * 1e-3, y = q[4 * k + 1] * 1e-3, z = q[4 * k + 2] * 1e-3;
    bool near = false;
    const double oracle = surface(x + src.frame.origin_x, y + src.frame.origin_y, &near);
    const double drawn = mesh.height_at(x, y);
    EXPECT_FALSE(std::isnan(drawn)) << "vertex " << k << " outside the terrain mesh";
    c.stored_vs_mesh = std::max(c.stored_vs_mesh, std::abs(z - drawn));
    c.stored_vs_oracle = std::max(c.stored_vs_oracle, std::abs(z - oracle));
    c.mesh_vs_oracle = std::max(c.mesh_vs_oracle, std::abs(drawn - oracle));
    EXPECT_NEAR(drawn, z, 1e-3) << "vertex " << k << " at (" << x << ", " << y << ")";
    EXPECT_NEAR(z, oracle, 1e-3) << "vertex " << k << " at (" << x << ", " << y << ")";
    c.near_strip += near;
    ++c.vertices;
  }
  return c;
}

void report(const SurfaceCheck& c, const char* what) {
  std::printf(
      "%s: %zu vertices (%zu next to the no-data strip); max |stored - drawn| %.4f mm, "
      "|stored - analytic| %.4f mm, |drawn - analytic| %.4f mm; mesh bound %.4f mm\n",
      what, c.vertices, c.near_strip, c.stored_vs_mesh * 1e3, c.stored_vs_oracle * 1e3,
      c.mesh_vs_oracle * 1e3, c.mesh_bound * 1e3);
  ::testing::Test::RecordProperty("max_stored_vs_drawn_mm", std::to_string(c.stored_vs_mesh * 1e3));
}

TEST(TerrainSurface, DynamicLineVerticesLieOnTheTerrainRenderDraws) {
  const fs::path d = work_dir();
  write_dem((d / "dem.tif").string(), true);
  write_trails((d / "trails.gpkg").string());
  write_scene(d / "scene.toml", "dem.tif");
  const std::string pkg = (d / "trails.decals").string();
  auto b = run_tool("build " + (d / "scene.toml").string() + " -o " + pkg + " -q");
  ASSERT_EQ(b.rc, 0) << b.output;

  const SurfaceCheck c = check_package(pkg);
  report(c, "dem.tif");
  EXPECT_GT(c.vertices, 100u);
  EXPECT_GT(c.near_strip, 5u);  // the no-data fill is exercised
  EXPECT_LE(c.mesh_bound, R::kMeshTolerance);

  // The tool draws that mesh: from the package's build DEM, within the bound.
  auto r =
      run_tool("render " + pkg + " --cpu --size 64x48 --stats -o " + (d / "trails.png").string());
  ASSERT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("terrain from the package's build DEM"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" mm of the DEM surface"), std::string::npos) << r.output;
}

TEST(TerrainSurface, DemWithoutCrsIsAnErrorUnlessAssumeCrsIsGiven) {
  const fs::path d = work_dir();
  const std::string nocrs = (d / "nocrs.tif").string();
  write_dem(nocrs, false);
  write_trails((d / "trails.gpkg").string());
  write_scene(d / "nocrs.toml", "nocrs.tif");
  const std::string pkg = (d / "nocrs.decals").string();
  fs::remove(pkg);

  // build: an input error (exit 3) naming the file and the way out.
  auto b = run_tool("build " + (d / "nocrs.toml").string() + " -o " + pkg + " -q");
  EXPECT_EQ(b.rc, 3) << b.output;
  EXPECT_NE(b.output.find(nocrs), std::string::npos) << b.output;
  EXPECT_NE(b.output.find("--assume-crs"), std::string::npos) << b.output;
  EXPECT_FALSE(fs::exists(pkg));

  // --assume-crs on the command line, then assume_crs in the scene file: the
  // stored heights and the drawn terrain are the analytic surface again.
  for (const bool in_scene : {false, true}) {
    fs::remove(pkg);
    std::string args = "build " + (d / "nocrs.toml").string() + " -o " + pkg + " -q";
    if (in_scene) {
      write_scene(d / "assumed.toml", "nocrs.tif", "assume_crs = \"EPSG:32632\"");
      args = "build " + (d / "assumed.toml").string() + " -o " + pkg + " -q";
    } else {
      args += " --assume-crs EPSG:32632";
    }
    auto ok = run_tool(args);
    ASSERT_EQ(ok.rc, 0) << ok.output;
    const SurfaceCheck c = check_package(pkg);
    report(c, in_scene ? "nocrs.tif, assume_crs in the scene" : "nocrs.tif, --assume-crs");
    EXPECT_GT(c.vertices, 100u);
  }

  // render: a package without a DEM drawn over the CRS-less DEM.
  const std::string plain = (d / "plain.decals").string();
  auto p = run_tool("build " + (d / "trails.gpkg").string() + " -o " + plain +
                    " --kind line --dynamic --crs EPSG:32632 -q");
  ASSERT_EQ(p.rc, 0) << p.output;
  auto r = run_tool("render " + plain + " --dem " + nocrs + " --cpu --size 32x24 -o " +
                    (d / "plain.png").string());
  EXPECT_EQ(r.rc, 3) << r.output;
  EXPECT_NE(r.output.find(nocrs), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--assume-crs"), std::string::npos) << r.output;
  auto ra =
      run_tool("render " + plain + " --dem " + nocrs +
               " --assume-crs EPSG:32632 --cpu --size 32x24 -o " + (d / "plain.png").string());
  EXPECT_EQ(ra.rc, 0) << ra.output;
}

// A DEM in another CRS than the frame: the mesh samples the surface off its
// lattice, and --stats says so in words, with the reason, not as a distance.
TEST(TerrainSurface, StatsSayWhyAMeshOffTheDemLatticeHasNoBound) {
  const fs::path d = work_dir();
  write_dem((d / "dem.tif").string(), true);
  write_trails((d / "trails.gpkg").string());
  const std::string pkg = (d / "laea.decals").string();
  auto b = run_tool("build " + (d / "trails.gpkg").string() + " -o " + pkg +
                    " --kind line --dynamic --crs EPSG:3035 -q");
  ASSERT_EQ(b.rc, 0) << b.output;
  auto r = run_tool("render " + pkg + " --dem " + (d / "dem.tif").string() +
                    " --cpu --size 32x24 --stats -o " + (d / "laea.png").string());
  ASSERT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("vertices on the DEM surface, no bound between them (the mesh is not "
                          "on the DEM's cell lattice: the DEM is in another CRS than the frame"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("unbounded"), std::string::npos) << r.output;
}

// The mesh itself on the analytic DEM, away from any package: at its
// vertices it is the surface, and between them within its bound.
TEST(TerrainSurface, MeshVerticesAreSurfaceHeightsAndTheMeshKeepsItsBound) {
  const fs::path d = work_dir();
  const std::string dem = (d / "mesh.tif").string();
  write_dem(dem, true);
  prep::SceneFrame frame;
  frame.crs_wkt = epsg_wkt(32632);
  frame.origin_x = 600070;
  frame.origin_y = 5000940;
  const prep::Extent e{-60, -50, 60, 50};
  const R::Heightfield h =
      R::load_heightfield({dem, "", kZScale, std::nullopt}, frame, e, R::kMeshSamples);
  ASSERT_LE(h.x0, e.xmin);
  ASSERT_GE(h.x0 + h.dx * (h.nx - 1), e.xmax);
  double at_vertices = 0, between = 0;
  for (uint32_t j = 0; j < h.ny; ++j)
    for (uint32_t i = 0; i < h.nx; ++i) {
      const double x = h.x0 + i * h.dx, y = h.y0 + j * h.dy;
      at_vertices = std::max(
          at_vertices,
          std::abs(h.z[i + size_t(h.nx) * j] - surface(x + frame.origin_x, y + frame.origin_y)));
      if (i + 1 < h.nx && j + 1 < h.ny)
        for (const double f : {0.25, 0.5, 0.75}) {
          const double xm = x + f * h.dx, ym = y + (1 - f) * h.dy;
          between = std::max(between, std::abs(h.height_at(xm, ym) -
                                               surface(xm + frame.origin_x, ym + frame.origin_y)));
        }
    }
  std::printf(
      "mesh %ux%u: max |vertex - analytic| %.6f mm, between vertices %.4f mm (bound %.4f mm)\n",
      h.nx, h.ny, at_vertices * 1e3, between * 1e3, h.surface_error_bound * 1e3);
  EXPECT_LE(at_vertices, 1e-6);
  EXPECT_LE(between, h.surface_error_bound + 1e-9);
  EXPECT_LE(h.surface_error_bound, R::kMeshTolerance);
}

}  // namespace
