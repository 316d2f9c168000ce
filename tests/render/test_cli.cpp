// `decalprep render` end to end on a package written by prep_write: output
// files, the no-EGL exit code, and rejection of corrupt packages.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "hand_model.hpp"
#include "prep/write.hpp"

namespace fs = std::filesystem;

namespace {

struct ToolRun {
  int rc = -1;
  std::string output;
};

ToolRun run_tool(const std::string& args, const std::string& env = "") {
  fs::path log = fs::temp_directory_path() / ("decalprep_render_cli_" + std::to_string(::getpid()) + ".log");
  std::string cmd = env + " " + DECALPREP_TOOL + " " + args + " > " + log.string() + " 2>&1";
  int status = std::system(cmd.c_str());
  ToolRun r;
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(log);
  r.output.assign(std::istreambuf_iterator<char>(in), {});
  fs::remove(log);
  return r;
}

class RenderCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::current_path() / "render-out" / "cli";
    fs::create_directories(dir_);
    pkg_ = (dir_ / "hand.decals").string();
    prep::DecalModel m = render_test::hand_model();
    m.frame.crs_wkt = "";  // no CRS needed without a DEM
    prep::write_model(pkg_, m, "");
  }
  fs::path dir_;
  std::string pkg_;
};

TEST_F(RenderCli, TopDownWritesPngWorldFileAndRawDecalLayer) {
  std::string png = (dir_ / "hand_cli.png").string(), raw = (dir_ / "hand_cli.rgba").string();
  ToolRun r = run_tool("render " + pkg_ + " --extent 0,0,100,100 --size 100x100 --stats --raw " + raw + " -o " + png);
  if (r.rc == 8) GTEST_SKIP() << "no headless GL here: " << r.output;
  ASSERT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("static polygons"), std::string::npos) << r.output;  // --stats pass times
  ASSERT_TRUE(fs::exists(png));
  ASSERT_TRUE(fs::exists(dir_ / "hand_cli.pgw"));
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

TEST_F(RenderCli, ExitsWithRenderCodeWhenNoEglDisplayCanBeCreated) {
  // glvnd finds no vendor library: no EGL display at all.
  ToolRun r = run_tool("render " + pkg_ + " --extent 0,0,100,100 --size 16x16 -o " + (dir_ / "none.png").string(),
              "__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent/egl_vendor.json __EGL_VENDOR_LIBRARY_DIRS=/nonexistent");
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
  ToolRun r = run_tool("render " + bad + " --extent 0,0,100,100 --size 16x16 -o " + (dir_ / "corrupt.png").string());
  EXPECT_EQ(r.rc, 5) << r.output;
  EXPECT_NE(r.output.find("decalprep:"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ / "corrupt.png"));
}

}  // namespace
