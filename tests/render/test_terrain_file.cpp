// Terrain files (formats/SPEC.md "Terrain files", `decalprep terrain`):
// the Monaco sample's file read back is render's Heightfield bit for bit;
// its vertices are the DEM's bilinear heights as GDAL reads them; hostile
// files are refused naming the field; the command's output safety.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_spatialref.h>
#include <sys/stat.h>
#include <xxhash.h>

#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;
namespace R = prep::render;
using prep::test::run_tool;
using prep::test::TempDir;

const std::string kDem =
    "/vsizip/" DECALPREP_SOURCE_DIR "/samples/monaco/N43E007.hgt.zip/N43E007.hgt";

std::vector<uint8_t> slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// The Monaco package (render-out/smoke, shared with the render tests).
std::string monaco(std::string& why) {
  return render_test::monaco_package(&why);
}

// What `render PKG --dem kDem --fit` loads (prep/pipeline.hpp's render():
// open_scene, choose_dem, load_terrain over the package extent).
R::Heightfield render_mesh(const std::string& pkg_path, R::DecalSource& src, decal::Package& pkg) {
  EXPECT_TRUE(decal::Package::open(pkg_path, pkg));
  src = R::source_of(pkg);
  prep::DemSpec dem = R::recorded_dem(std::string(pkg.metadata_json()), pkg_path);
  dem.path = kDem;
  dem.named_by_package = false;
  return R::load_heightfield(dem, src.frame, src.extent, R::kMeshSamples);
}

TEST(TerrainFile, MonacoFileIsRenderMesh) {
  std::string why;
  const std::string pkg = monaco(why);
  if (pkg.empty()) GTEST_SKIP() << why;
  TempDir dir("terrain-file");
  const std::string out = dir.file("m.terrain");
  const auto r = run_tool("terrain " + pkg + " --dem " + kDem + " -o " + out + " -q");
  ASSERT_EQ(r.rc, 0) << r.output;
  const std::vector<uint8_t> bytes = slurp(out);
  const R::TerrainFile t = R::decode_terrain(bytes, out);
  decal::Package p;
  R::DecalSource src;
  const R::Heightfield want = render_mesh(pkg, src, p);
  const R::Heightfield& got = t.mesh;
  ASSERT_EQ(got.nx, want.nx);
  ASSERT_EQ(got.ny, want.ny);
  EXPECT_EQ(got.x0, want.x0);
  EXPECT_EQ(got.y0, want.y0);
  EXPECT_EQ(got.dx, want.dx);
  EXPECT_EQ(got.dy, want.dy);
  EXPECT_EQ(got.zmin, want.zmin);
  EXPECT_EQ(got.zmax, want.zmax);
  EXPECT_EQ(std::bit_cast<uint64_t>(got.surface_error_bound),
            std::bit_cast<uint64_t>(want.surface_error_bound));
  EXPECT_EQ(t.origin_x, src.frame.origin_x);
  EXPECT_EQ(t.origin_y, src.frame.origin_y);
  ASSERT_EQ(got.z.size(), want.z.size());
  double worst = 0;
  for (size_t k = 0; k < got.z.size(); ++k) worst = std::max(worst, std::abs(got.z[k] - want.z[k]));
  EXPECT_EQ(worst, 0.0) << "the file's heights are render's bit for bit";
  std::printf("monaco: %ux%u vertices, %zu bytes, max |file - render| = %g m\n", got.nx, got.ny,
              bytes.size(), worst);
  // Without --dem: the DEM the package records is the same raster.
  const auto d = run_tool("terrain " + pkg + " -o " + dir.file("d.terrain") + " -q");
  ASSERT_EQ(d.rc, 0) << d.output;
  EXPECT_EQ(slurp(dir.file("d.terrain")), bytes);
}

// Independent oracle: each vertex (frame metres + origin) transformed with
// OGR to the DEM's CRS, placed with GDAL's geotransform, and the bilinear
// value of the four cells GDAL reads around it (cell centres at +0.5).
TEST(TerrainFile, MonacoVerticesAreGdalBilinearHeights) {
  std::string why;
  const std::string pkg = monaco(why);
  if (pkg.empty()) GTEST_SKIP() << why;
  decal::Package p;
  R::DecalSource src;
  const R::Heightfield h = render_mesh(pkg, src, p);
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(kDem.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  GDALRasterBand* band = ds->GetRasterBand(1);
  const int W = ds->GetRasterXSize(), H = ds->GetRasterYSize();
  std::vector<int16_t> cells(size_t(W) * H);
  ASSERT_EQ(band->RasterIO(GF_Read, 0, 0, W, H, cells.data(), W, H, GDT_Int16, 0, 0), CE_None);
  OGRSpatialReference frame, demsrs;
  frame.importFromWkt(src.frame.crs_wkt.c_str());
  demsrs.importFromWkt(ds->GetProjectionRef());
  frame.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  demsrs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  OGRCoordinateTransformation* ct = OGRCreateCoordinateTransformation(&frame, &demsrs);
  ASSERT_NE(ct, nullptr);
  // Bilinear between cell centres (GDAL's kernel), edge cells beyond.
  auto cell = [&](int i, int j) {
    i = std::clamp(i, 0, W - 1);
    j = std::clamp(j, 0, H - 1);
    return double(cells[size_t(i) + size_t(W) * j]);
  };
  auto bilinear = [&](double px, double py) {
    const double fx = px - 0.5, fy = py - 0.5;
    const int i = int(std::floor(fx)), j = int(std::floor(fy));
    const double u = fx - i, v = fy - j;
    return (1 - u) * (1 - v) * cell(i, j) + u * (1 - v) * cell(i + 1, j) +
           (1 - u) * v * cell(i, j + 1) + u * v * cell(i + 1, j + 1);
  };
  double worst = 0;
  size_t n = 0;
  for (uint32_t j = 0; j < h.ny; j += 5)
    for (uint32_t i = 0; i < h.nx; i += 5) {
      double x = h.x0 + i * h.dx + src.frame.origin_x, y = h.y0 + j * h.dy + src.frame.origin_y;
      ASSERT_TRUE(ct->Transform(1, &x, &y));
      const double px = (x - gt[0]) / gt[1], py = (y - gt[3]) / gt[5];
      const double mine = bilinear(px, py);
      worst = std::max(worst, std::abs(mine - h.z[i + size_t(h.nx) * j]));
      ++n;
    }
  OCTDestroyCoordinateTransformation(ct);
  GDALClose(ds);
  std::printf("monaco: %zu vertices, max |mesh - bilinear of GDAL's cells| = %.3g m\n", n, worst);
  // The mesh's stated tolerance at its vertices: they are surface heights
  // (prep/render.hpp load_heightfield), up to the transform's rounding.
  EXPECT_LT(worst, 1e-6);
}

// A header field overwritten and every checksum made right again, so the
// field's own check must refuse it.
std::vector<uint8_t> forge(std::vector<uint8_t> b, size_t at, const void* v, size_t n) {
  std::memcpy(b.data() + at, v, n);
  const uint32_t header = 144;
  const uint64_t heights = XXH64(b.data() + header, b.size() - header, 0);
  std::memcpy(b.data() + 128, &heights, 8);
  const uint64_t sum = XXH64(b.data(), 136, 0);
  std::memcpy(b.data() + 136, &sum, 8);
  return b;
}

std::string refusal(const std::vector<uint8_t>& b) {
  try {
    R::decode_terrain(b, "t");
  } catch (const prep::format_error& e) {
    return e.what();
  }
  return "";
}

R::TerrainFile small_mesh() {
  R::TerrainFile t;
  t.mesh.nx = 3;
  t.mesh.ny = 2;
  t.mesh.x0 = -10;
  t.mesh.y0 = 5;
  t.mesh.dx = 2.5;
  t.mesh.dy = 4;
  t.mesh.z = {1, 2.25, -3, 4, 5.125, 0};
  t.mesh.zmin = -3;
  t.mesh.zmax = 5.125;
  t.mesh.surface_error_bound = std::numeric_limits<double>::infinity();
  t.origin_x = 1000;
  t.origin_y = -2000;
  return t;
}

TEST(TerrainFile, HostileFilesAreRefusedNamingTheField) {
  const std::string s = R::encode_terrain(small_mesh());
  const std::vector<uint8_t> good(s.begin(), s.end());
  const R::TerrainFile back = R::decode_terrain(good, "t");
  EXPECT_EQ(back.mesh.z, small_mesh().mesh.z);
  EXPECT_EQ(back.origin_y, -2000);
  // Truncated at every header field and inside the heights.
  for (size_t n : {0, 4, 8, 10, 12, 16, 20, 24, 28, 32, 40, 88, 120, 136, 143, 144, 150})
    if (n < good.size()) {
      EXPECT_NE(refusal({good.begin(), good.begin() + long(n)}), "") << "truncated at " << n;
    }
  // Every bit of every byte flipped.
  for (size_t k = 0; k < good.size(); ++k)
    for (int bit = 0; bit < 8; ++bit) {
      std::vector<uint8_t> b = good;
      b[k] ^= uint8_t(1u << bit);
      EXPECT_NE(refusal(b), "") << "byte " << k << " bit " << bit;
    }
  struct Case {
    size_t at;
    std::vector<uint8_t> value;
    const char* field;
  };
  auto u32 = [](uint32_t v) { return std::vector<uint8_t>((uint8_t*)&v, (uint8_t*)&v + 4); };
  auto two = [](uint32_t a, uint32_t b) {
    const uint32_t v[2] = {a, b};
    return std::vector<uint8_t>((const uint8_t*)v, (const uint8_t*)v + 8);
  };
  auto f64 = [](double v) { return std::vector<uint8_t>((uint8_t*)&v, (uint8_t*)&v + 8); };
  const Case cases[] = {{8, {2, 0}, "version_major"}, {16, u32(1), "flags"},
                        {20, u32(7), "codec"},        {24, u32(1), "nx"},
                        {28, u32(20000), "ny"},       {24, two(16384, 2048), "nx * ny"},
                        {40, f64(NAN), "x0"},         {56, f64(0), "dx"},
                        {64, f64(-1), "dy"},          {72, f64(-4), "zmin"},
                        {80, f64(INFINITY), "zmax"},  {88, f64(NAN), "surface_error_bound"},
                        {96, f64(1e300), "origin_x"}, {120, f64(0), "heights_size"}};
  for (const Case& c : cases) {
    const std::string m = refusal(forge(good, c.at, c.value.data(), c.value.size()));
    EXPECT_NE(m.find(std::string(c.field) + ":"), std::string::npos) << c.field << ": " << m;
  }
  // A NaN height, stored uncompressed (codec none) with right checksums.
  std::vector<uint8_t> raw(144 + 6 * 8);
  std::memcpy(raw.data(), good.data(), 144);
  const R::TerrainFile m = small_mesh();
  for (size_t v = 0; v < 6; ++v) {
    const uint64_t bits = std::bit_cast<uint64_t>(v == 4 ? NAN : m.mesh.z[v]);
    for (size_t k = 0; k < 8; ++k) raw[144 + k * 6 + v] = uint8_t(bits >> (8 * k));
  }
  const uint64_t size = raw.size(), hs = 48;
  std::memcpy(raw.data() + 32, &size, 8);
  std::memcpy(raw.data() + 120, &hs, 8);
  const uint32_t none = 0;
  const std::string nan = refusal(forge(raw, 20, &none, 4));
  EXPECT_NE(nan.find("heights: vertex 4"), std::string::npos) << nan;
  // Encoding refuses what decoding would.
  R::TerrainFile bad = small_mesh();
  bad.mesh.z[2] = NAN;
  EXPECT_THROW(R::encode_terrain(bad), prep::usage_error);
}

TEST(TerrainFile, CommandOutputSafety) {
  std::string why;
  const std::string pkg = monaco(why);
  if (pkg.empty()) GTEST_SKIP() << why;
  TempDir dir("terrain-safety");
  const std::string copy = dir.file("m.decals"), beside = dir.file("m.terrain");
  fs::copy_file(pkg, copy);
  // A file beside the package that is not a terrain file: left as it is.
  std::ofstream(beside) << "not mine";
  auto r = run_tool("terrain " + copy + " --dem " + kDem + " -q");
  EXPECT_EQ(r.rc, 7) << r.output;
  EXPECT_NE(r.output.find("not a terrain file"), std::string::npos) << r.output;
  EXPECT_EQ(slurp(beside), std::vector<uint8_t>({'n', 'o', 't', ' ', 'm', 'i', 'n', 'e'}));
  // Named with -o it is replaced; a terrain file there is replaced too.
  r = run_tool("terrain " + copy + " --dem " + kDem + " -o " + beside + " -q");
  EXPECT_EQ(r.rc, 0) << r.output;
  EXPECT_NO_THROW(R::decode_terrain(slurp(beside), beside));
  r = run_tool("terrain " + copy + " --dem " + kDem + " -q");
  EXPECT_EQ(r.rc, 0) << r.output;
  // A FIFO as output: refused without blocking; the package as output too.
  const std::string fifo = dir.file("fifo.terrain");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
  const auto start = std::chrono::steady_clock::now();
  r = run_tool("terrain " + copy + " --dem " + kDem + " -o " + fifo + " -q");
  EXPECT_EQ(r.rc, 7) << r.output;
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(20));
  r = run_tool("terrain " + copy + " --dem " + kDem + " -o " + copy + " -q");
  EXPECT_EQ(r.rc, 7) << r.output;
  // No DEM: a package that records none, without --dem.
  std::ofstream(dir.file("a.geojson"))
      << R"({"type":"FeatureCollection","features":[{"type":"Feature","properties":{},)"
         R"("geometry":{"type":"Polygon","coordinates":[[[7.42,43.73],[7.421,43.73],)"
         R"([7.421,43.731],[7.42,43.73]]]}}]})";
  const std::string flat = render_test::build_utm_scene(
      dir.path(), "flat.decals", {{"a", "polygon", "color = \"#ff0000\"\n"}}, why);
  ASSERT_FALSE(flat.empty()) << why;
  r = run_tool("terrain " + flat + " -q");
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("records no DEM"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.file("flat.terrain")));
}

TEST(TerrainFile, TilesetGetsOnePerTile) {
  std::string why;
  if (monaco(why).empty()) GTEST_SKIP() << why;
  TempDir dir("terrain-tiles");
  const std::string tiles = dir.file("t");
  auto r = run_tool("build " DECALPREP_SOURCE_DIR "/samples/monaco/scene.toml -o " + tiles +
                    " --tile-size 2000 -q");
  ASSERT_EQ(r.rc, 0) << r.output;
  r = run_tool("terrain " + tiles + " --progress none --json");
  ASSERT_EQ(r.rc, 0) << r.output;
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(tiles + "/tiles")) {
    if (e.path().extension() != ".decals") continue;
    ++n;
    const std::string t = fs::path(e.path()).replace_extension(".terrain").string();
    ASSERT_TRUE(fs::exists(t)) << t;
    // The tile's file is the one the command writes for that package alone.
    const std::string alone = dir.file("alone.terrain");
    ASSERT_EQ(run_tool("terrain " + e.path().string() + " -o " + alone + " -q").rc, 0);
    EXPECT_EQ(slurp(t), slurp(alone)) << t;
  }
  EXPECT_GT(n, 1u);
  EXPECT_NO_THROW(R::decode_terrain(slurp(tiles + "/tileset.terrain"), "tileset.terrain"));
  EXPECT_EQ(run_tool("terrain " + tiles + " -o x.terrain -q").rc, 2);
}

}  // namespace
