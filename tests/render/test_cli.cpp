// `decalprep render` end to end on a package written by prep_write: output
// files, the no-EGL exit code, and rejection of corrupt packages.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "dem_tiff.hpp"
#include "hand_model.hpp"
#include "prep/write.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

using prep::test::run_tool;
using prep::test::ToolRun;

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::current_path() / "render-out" / "cli";
    fs::create_directories(dir_);
    pkg_ = (dir_ / "hand.decals").string();
    prep::DecalModel m = render_test::hand_model();
    m.frame.crs_wkt = "";  // no CRS needed without a DEM
    // Far from 0: --extent is absolute (origin + the model's 0..100 m).
    m.frame.origin_x = kOriginX;
    m.frame.origin_y = kOriginY;
    prep::write_model(pkg_, m, "");
  }
  static constexpr double kOriginX = 500000, kOriginY = 4000000;
  // The model's 0..100 m square in absolute frame coordinates.
  static constexpr const char* kExtent = "--extent 500000,4000000,500100,4000100";
  fs::path dir_;
  std::string pkg_;
};

TEST_F(RenderCli, TopDownWritesPngWorldFileAndRawDecalLayer) {
  std::string png = (dir_ / "hand_cli.png").string(), raw = (dir_ / "hand_cli.rgba").string();
  ToolRun r = run_tool("render " + pkg_ + " " + kExtent + " --size 100x100 --stats --raw " + raw +
                       " -o " + png);
  if (r.rc == 8) GTEST_SKIP() << "no headless GL here: " << r.output;
  ASSERT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("static polygons"), std::string::npos) << r.output;  // --stats pass times
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  ASSERT_TRUE(fs::exists(png));
  // World file: 1 m pixels, upper-left pixel centre at (0.5, 99.5) from the origin.
  std::ifstream wf(dir_ / "hand_cli.pgw");
  double pixel_w, rot1, rot2, pixel_h, centre_x, centre_y;
  wf >> pixel_w >> rot1 >> rot2 >> pixel_h >> centre_x >> centre_y;
  ASSERT_TRUE(wf);
  EXPECT_EQ(pixel_w, 1.0);
  EXPECT_EQ(pixel_h, -1.0);
  EXPECT_EQ(centre_x, kOriginX + 0.5);
  EXPECT_EQ(centre_y, kOriginY + 99.5);
  ASSERT_EQ(fs::file_size(raw), 100u * 100u * 16u);
  // Pixel (70, 20): centre (70.5, 79.5) lies inside the exterior, off both lines.
  std::ifstream in(raw, std::ios::binary);
  std::vector<float> px(100 * 100 * 4);
  in.read(reinterpret_cast<char*>(px.data()), std::streamsize(px.size() * 4));
  const float* c = &px[4 * (70 + 100 * 20)];
  EXPECT_NEAR(c[3], 1.0, 1e-6);
  EXPECT_NEAR(c[0], 0xe0 / 255.0, 1e-3);
  // Pixel (5, 5) lies outside every decal.
  EXPECT_EQ(px[4 * (5 + 100 * 5) + 3], 0.0f);
}

// --aa left out: msaa4 in GL with the decal method (--stats says so), none
// with --cpu and the volume method, which would refuse any other; an
// explicit --aa with --cpu is still refused.
TEST_F(RenderCli, TheAntiAliasingDefaultIsMsaaWhereTheRendererHasIt) {
  const std::string png = (dir_ / "aa_default.png").string();
  ToolRun gl = run_tool("render " + pkg_ + " " + kExtent + " --size 64x64 --stats -o " + png);
  if (gl.rc == 8) GTEST_SKIP() << "no headless GL here: " << gl.output;
  ASSERT_EQ(gl.rc, 0) << gl.output;
  EXPECT_NE(gl.output.find("aa msaa4"), std::string::npos) << gl.output;
  ToolRun cpu = run_tool("render " + pkg_ + " " + kExtent + " --size 64x64 --cpu -o " + png);
  EXPECT_EQ(cpu.rc, 0) << cpu.output;
  ToolRun volume =
      run_tool("render " + pkg_ + " " + kExtent + " --size 64x64 --method volume -o " + png);
  EXPECT_EQ(volume.rc, 0) << volume.output;
  ToolRun refused =
      run_tool("render " + pkg_ + " " + kExtent + " --size 64x64 --cpu --aa msaa4 -o " + png);
  EXPECT_EQ(refused.rc, 2) << refused.output;
  EXPECT_NE(refused.output.find("--aa none"), std::string::npos) << refused.output;
}

// A package records the DEM it was built with (build_options.dem): render
// uses it without --dem, falls back to flat terrain with a warning when it
// is gone, and --flat ignores it. Checked on the CPU path (no GL needed).
TEST_F(RenderCli, UsesThePackagesBuildDemUnlessFlatIsAsked) {
  GDALAllRegister();
  OGRSpatialReference utm;
  utm.importFromEPSG(32632);
  char* wkt = nullptr;
  utm.exportToWkt(&wkt);
  const std::string frame_wkt = wkt;
  CPLFree(wkt);
  // A 20 x 20 DEM over the scene (origin 0), a 300 m ramp from west to east.
  const std::string dem = (dir_ / "ramp.tif").string();
  {
    GDALDatasetUniquePtr ds = create_dem_tiff(dem, 20, 20, GDT_Float32, -50, 150, 10, frame_wkt);
    ASSERT_TRUE(ds);
    std::vector<float> z(400);
    for (int j = 0; j < 20; ++j)
      for (int i = 0; i < 20; ++i) z[size_t(j * 20 + i)] = float(15 * i);
    ASSERT_EQ(
        ds->GetRasterBand(1)->RasterIO(GF_Write, 0, 0, 20, 20, z.data(), 20, 20, GDT_Float32, 0, 0),
        CE_None);
  }
  const std::string pkg = (dir_ / "hand_dem.decals").string();
  prep::DecalModel m = render_test::hand_model();
  m.frame.crs_wkt = frame_wkt;
  prep::write_model(pkg, m, R"({"build_options": {"dem": ")" + dem + R"("}})");

  const std::string with = (dir_ / "dem_pkg.png").string(), flat = (dir_ / "dem_flat.png").string();
  ToolRun r = run_tool("render " + pkg + " --cpu --size 96x64 -o " + with);
  ASSERT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("terrain from the package's build DEM " + dem), std::string::npos)
      << r.output;
  ToolRun f = run_tool("render " + pkg + " --cpu --size 96x64 --flat -o " + flat);
  ASSERT_EQ(f.rc, 0) << f.output;
  EXPECT_EQ(f.output.find("DEM"), std::string::npos) << f.output;
  auto bytes = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  // The ramp changes the camera fit and the drape: the images differ.
  EXPECT_NE(bytes(with), bytes(flat));

  // The DEM is gone: a warning that names it, flat terrain, exit 0.
  fs::remove(dem);
  ToolRun g =
      run_tool("render " + pkg + " --cpu --size 96x64 -o " + (dir_ / "dem_gone.png").string());
  ASSERT_EQ(g.rc, 0) << g.output;
  EXPECT_NE(g.output.find("cannot be read here"), std::string::npos) << g.output;
  EXPECT_EQ(bytes((dir_ / "dem_gone.png").string()), bytes(flat));

  // --flat with --dem is a usage error.
  EXPECT_EQ(
      run_tool("render " + pkg + " --cpu --flat --dem x.tif -o " + (dir_ / "x.png").string()).rc,
      2);
}

TEST_F(RenderCli, ExitsWithRenderCodeWhenNoEglDisplayCanBeCreated) {
  // glvnd finds no vendor library: no EGL display at all.
  ToolRun r = run_tool(
      "render " + pkg_ + " " + kExtent + " --size 16x16 -o " + (dir_ / "none.png").string(),
      {.env = "__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/egl_vendor.json "
              "__EGL_VENDOR_LIBRARY_DIRS=/nonexistent"});
  EXPECT_EQ(r.rc, 8) << r.output;
  EXPECT_NE(r.output.find("EGL"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "none.png"));
}

TEST_F(RenderCli, RejectsACorruptPackageWithAClearMessage) {
  // Flip one byte in the middle of the file (a blob or the table): the
  // reader's checksums or structure checks must refuse it before GL.
  std::string bad = (dir_ / "corrupt.decals").string();
  fs::copy_file(pkg_, bad, fs::copy_options::overwrite_existing);
  std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
  const auto size = fs::file_size(bad);
  f.seekg(std::streamoff(size / 2));
  char b = 0;
  f.read(&b, 1);
  b = char(b ^ 0x5a);
  f.seekp(std::streamoff(size / 2));
  f.write(&b, 1);
  f.close();
  ToolRun r = run_tool("render " + bad + " " + kExtent + " --size 16x16 -o " +
                       (dir_ / "corrupt.png").string());
  EXPECT_EQ(r.rc, 5) << r.output;
  EXPECT_NE(r.output.find("decalprep:"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "corrupt.png"));
}

}  // namespace
