// Tilesets end to end with the real tool on the shipped Monaco sample
// (prep/tile.hpp, formats/SPEC.md "Tilesets"):
//  - exact: the CPU evaluator's top-down render of the tileset equals the
//    single package's on all but a few pixels, and every pixel that differs
//    has its centre within 2 mm of a boundary of the single package's
//    picture (its colour changes on a 2 mm circle around the centre); the
//    same for the GL render of the tileset against its CPU render;
//  - one frame: the GL render of the tileset (all tiles in one GL frame)
//    equals the single package's GL render, and with coverage AA the
//    per-tile renders merged, on every pixel within 1/255;
//  - accounting: the tileset's per-layer counts equal the single package's;
//  - determinism: --jobs 2 and --jobs 1 --threads 1 give the same bytes;
//  - resume: a second run keeps every tile; a deleted and a corrupted tile
//    are rebuilt, and only they;
//  - the tools take the directory (info, verify);
//  - render --gpu-budget counts the drawn tiles' blobs decoded, summed here
//    by decal::Package::open, and coarsens a tileset with levels to fit.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/files.hpp"
#include "prep/render.hpp"
#include "prep/tile.hpp"
#include "test_support.hpp"

namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using prep::test::run_tool;
using prep::test::shell_quote;

constexpr double kTileSize = 500.0;

std::vector<float> read_raw(const std::string& path, size_t floats) {
  std::vector<float> v(floats);
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(v.data()), std::streamsize(floats * sizeof(float)));
  EXPECT_EQ(size_t(in.gcount()), floats * sizeof(float)) << path;
  return v;
}

// The bytes decal::Package::open decodes from a tile: every blob's.
uint64_t decoded_bytes(const std::string& dir, const prep::TileEntry& t) {
  decal::Package p;
  const decal::Status s = decal::Package::open(dir + "/" + t.file, p);
  EXPECT_TRUE(s) << s.message;
  uint64_t n = 0;
  for (const decal::BlobView& b : p.blobs()) n += b.bytes.size();
  return n;
}

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

class Tileset : public ::testing::Test {
 protected:
  // The three builds are shared by every test (and, through the ctest
  // fixture tileset_outputs, by every test process): TILESET_WORK_DIR holds
  // them once tileset_fixture.sh has run; without it they are made here.
  static void SetUpTestSuite() {
    dir_ = new prep::test::TempDir("tileset");
    const char* work = std::getenv("TILESET_WORK_DIR");
    if (work && fs::exists(fs::path(work) / "done")) {
      for (const char* name :
           {"single.decals", "single.decals.json", "tiles", "tiles.json", "tiles1", "tiles1.json"})
        fs::copy(fs::path(work) / name, dir_->path() / name, fs::copy_options::recursive);
      return;
    }
    const std::string scene = shell_quote(prep::test::monaco_sample("scene.toml"));
    auto build = [&](const std::string& out, const std::string& extra) {
      const auto r =
          run_tool("build " + scene + " -o " + shell_quote(dir_->file(out)) + " --report " +
                       shell_quote(dir_->file(out + ".json")) + " -q " + extra,
                   *dir_);
      ASSERT_EQ(r.rc, 0) << r.output;
    };
    build("single.decals", "");
    build("tiles", "--tile-size 500 --jobs 2");
    build("tiles1", "--tile-size 500 --jobs 1 --threads 1");
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::string file(const std::string& name) { return dir_->file(name); }
  // The sample as a 500 m tileset with overview levels 1 and 2, read only:
  // the fixture's (not copied: 70 MB), else built here once.
  static std::string levels() {
    const char* work = std::getenv("TILESET_WORK_DIR");
    if (work && fs::exists(fs::path(work) / "done")) return (fs::path(work) / "levels").string();
    if (!fs::exists(dir_->path() / "levels")) {
      const auto r =
          run_tool("build " + shell_quote(prep::test::monaco_sample("scene.toml")) + " -o " +
                       shell_quote(file("levels")) + " -q --tile-size 500 --levels 2 --jobs 2",
                   *dir_);
      EXPECT_EQ(r.rc, 0) << r.output;
    }
    return file("levels");
  }
  static json read_json(const std::string& name) {
    return json::parse(prep::test::read_text(file(name)));
  }
  static prep::test::TempDir* dir_;
};
prep::test::TempDir* Tileset::dir_ = nullptr;

// A 1.6 km x 1.5 km window inside Monaco at 2 m pixels, its edges off the
// tile borders, so that it spans 4 x 4 tiles.
struct View {
  prep::Extent abs;
  uint32_t w = 800, h = 750;
};

View monaco_view(const prep::TilesetIndex& ix) {
  const double cx = std::floor(0.5 * (ix.extent.xmin + ix.extent.xmax) / kTileSize) * kTileSize;
  const double cy = std::floor(0.5 * (ix.extent.ymin + ix.extent.ymax) / kTileSize) * kTileSize;
  View v;
  v.abs = {cx - 777.0, cy - 733.0, cx - 777.0 + 2.0 * v.w, cy - 733.0 + 2.0 * v.h};
  return v;
}

std::string extent_arg(const prep::Extent& e) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%.3f,%.3f,%.3f,%.3f", e.xmin, e.ymin, e.xmax, e.ymax);
  return buf;
}

// Pixels whose RGBA differ by more than 1/512 in any channel.
std::vector<size_t> differing(const std::vector<float>& a, const std::vector<float>& b) {
  std::vector<size_t> out;
  for (size_t k = 0; k * 4 < a.size(); ++k)
    for (int c = 0; c < 4; ++c)
      if (std::fabs(a[4 * k + c] - b[4 * k + c]) > 1.0f / 512) {
        out.push_back(k);
        break;
      }
  return out;
}

// Whether the single package's picture changes within 2 mm of (x, y)
// (metres relative to its origin): 16 points on the 2 mm circle.
bool near_boundary(const prep::StaticView& view, double x, double y) {
  const prep::EvalSample c = prep::evaluate(view, x, y);
  for (int k = 0; k < 16; ++k) {
    const double t = k * M_PI / 8;
    const prep::EvalSample s =
        prep::evaluate(view, x + 0.002 * std::cos(t), y + 0.002 * std::sin(t));
    for (int i = 0; i < 4; ++i)
      if (std::fabs(s.rgba[i] - c.rgba[i]) > 1e-6f) return true;
  }
  return false;
}

// How many of the pixels `diff` of view `v` have their centre farther than
// 2 mm from every boundary of the picture of the package at `reference`;
// the first five are reported as failures.
size_t far_from_boundaries(const std::vector<size_t>& diff, const View& v,
                           const std::string& reference) {
  decal::Package pkg;
  EXPECT_TRUE(decal::Package::open(reference, pkg));
  const prep::render::DecalSource src = prep::render::source_of(pkg);
  size_t far = 0;
  for (size_t k : diff) {
    const size_t col = k % v.w, row = k / v.w;  // pixel k of a row-major image
    const double x = v.abs.xmin + (double(col) + 0.5) * 2.0 - src.frame.origin_x;
    const double y = v.abs.ymax - (double(row) + 0.5) * 2.0 - src.frame.origin_y;
    if (!near_boundary(src.view, x, y) && ++far <= 5)
      ADD_FAILURE() << "pixel " << col << "," << row << " differs 2 mm from any boundary";
  }
  return far;
}

TEST_F(Tileset, CpuRenderOfTheTilesetEqualsTheSinglePackage) {
  const prep::TilesetIndex ix = prep::read_tileset_index(file("tiles"));
  const View v = monaco_view(ix);
  const auto in_view = prep::tiles_in(ix, v.abs);
  ASSERT_GE(in_view.size(), 9u) << "the view must span at least 9 tiles";
  const std::string common = " --cpu --flat --extent " + extent_arg(v.abs) + " --size " +
                             std::to_string(v.w) + "x" + std::to_string(v.h);
  auto r =
      run_tool("render " + shell_quote(file("single.decals")) + common + " -o " +
                   shell_quote(file("single.png")) + " --raw " + shell_quote(file("single.raw")),
               *dir_);
  ASSERT_EQ(r.rc, 0) << r.output;
  r = run_tool("render " + shell_quote(file("tiles")) + common + " -o " +
                   shell_quote(file("tiles.png")) + " --raw " + shell_quote(file("tiles.raw")),
               *dir_);
  ASSERT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find(std::to_string(in_view.size()) + " of " +
                          std::to_string(ix.tiles.size()) + " tiles meet the view"),
            std::string::npos)
      << r.output;
  const size_t n = size_t(v.w) * v.h;
  const std::vector<float> a = read_raw(file("single.raw"), 4 * n);
  const std::vector<float> b = read_raw(file("tiles.raw"), 4 * n);
  size_t covered = 0;
  for (size_t k = 0; k < n; ++k) covered += a[4 * k + 3] > 0 ? 1 : 0;
  ASSERT_GT(covered, n / 4) << "the view must show the city";

  const std::vector<size_t> diff = differing(a, b);
  const size_t far = far_from_boundaries(diff, v, file("single.decals"));
  std::printf(
      "[ measured ] %zu tiles in view; %zu of %zu pixels differ (%zu covered), %zu of them "
      "farther than 2 mm from a boundary\n",
      in_view.size(), diff.size(), n, covered, far);
  EXPECT_LE(double(diff.size()), 1e-4 * double(n));
  EXPECT_EQ(far, 0u);
}

// A tileset without overview levels: --level auto and --level 0 draw the
// level-0 tiles in view, and --stats counts their package bytes as
// tileset.json lists them and their blobs decoded as Package::open decodes
// them; --gpu-budget counts the latter: a budget below them exits 6
// naming both figures, even one that holds the package bytes.
TEST_F(Tileset, RenderBudgetAndLevelOptionsOnATilesetWithoutLevels) {
  const prep::TilesetIndex ix = prep::read_tileset_index(file("tiles"));
  const View v = monaco_view(ix);
  uint64_t bytes = 0, blob = 0;
  size_t tiles = 0;
  for (const prep::TileEntry& t : ix.tiles)
    if (t.square.xmin < v.abs.xmax && v.abs.xmin < t.square.xmax && t.square.ymin < v.abs.ymax &&
        v.abs.ymin < t.square.ymax) {
      bytes += t.bytes;
      blob += decoded_bytes(file("tiles"), t);
      ++tiles;
    }
  ASSERT_GT(blob, 2 * bytes);
  const std::string common = "render " + shell_quote(file("tiles")) +
                             " --cpu --flat --size 80x75 --extent " + extent_arg(v.abs) + " -o " +
                             shell_quote(file("budget.png"));
  for (const char* level : {"auto", "0"}) {
    const auto r = run_tool(common + " --stats --level " + level, *dir_);
    ASSERT_EQ(r.rc, 0) << r.output;
    EXPECT_NE(r.output.find("tiles: " + std::to_string(tiles) +
                            " drawn (level 0: " + std::to_string(tiles) + ")"),
              std::string::npos)
        << r.output;
    EXPECT_NE(
        r.output.find("bytes: " + std::to_string(bytes) +
                      " package bytes loaded, 100.00% of the full-detail " + std::to_string(bytes) +
                      " of this view; " + std::to_string(blob) + " blob bytes uploaded"),
        std::string::npos)
        << r.output;
  }
  auto r = run_tool(common + " --stats --gpu-budget " + std::to_string(blob), *dir_);
  EXPECT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("gpu budget: " + std::to_string(blob) +
                          " bytes of decoded blobs (GPU memory, not package bytes), " +
                          std::to_string(blob) + " used, 0 tile groups coarsened to fit"),
            std::string::npos)
      << r.output;
  for (uint64_t budget : {blob - 1, bytes}) {
    r = run_tool(common + " --gpu-budget " + std::to_string(budget), *dir_);
    EXPECT_EQ(r.rc, int(prep::ExitCode::resource)) << r.output;
    EXPECT_NE(r.output.find("--gpu-budget " + std::to_string(budget) + " bytes"), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("need " + std::to_string(blob) + " bytes"), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("(" + std::to_string(bytes) + " package bytes)"), std::string::npos)
        << r.output;
  }
  r = run_tool(common + " --level 1", *dir_);
  EXPECT_EQ(r.rc, int(prep::ExitCode::usage)) << r.output;
  r = run_tool(common + " --gpu-budget 2X", *dir_);
  EXPECT_EQ(r.rc, int(prep::ExitCode::usage)) << r.output;
}

// A tile the budget reads that is not a package: render fails naming it.
TEST_F(Tileset, RenderWithABudgetNamesATileThatIsNotAPackage) {
  const prep::TilesetIndex ix = prep::read_tileset_index(file("tiles"));
  const View v = monaco_view(ix);
  const std::string copy = file("budget_hostile");
  fs::copy(file("tiles"), copy, fs::copy_options::recursive);
  const prep::TileEntry* hit = nullptr;
  for (const prep::TileEntry& t : ix.tiles)
    if (!hit && t.square.xmin < v.abs.xmax && v.abs.xmin < t.square.xmax &&
        t.square.ymin < v.abs.ymax && v.abs.ymin < t.square.ymax)
      hit = &t;
  ASSERT_NE(hit, nullptr);
  fs::resize_file(copy + "/" + hit->file, 50);  // a truncated header
  const auto r = run_tool("render " + shell_quote(copy) + " --cpu --flat --size 80x75 --extent " +
                              extent_arg(v.abs) + " -o " + shell_quote(file("hostile.png")) +
                              " --gpu-budget 1G",
                          *dir_);
  EXPECT_EQ(r.rc, int(prep::ExitCode::verify_failed)) << r.output;
  EXPECT_NE(r.output.find(copy + "/" + hit->file), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("truncated package"), std::string::npos) << r.output;
  fs::remove_all(copy);
}

// --gpu-budget is GPU memory: the drawn tiles' blobs decoded, not their
// (about ten times smaller) package bytes. A top-down view of one level-2
// tile's square at pixels between the resolutions of levels 1 and 2 draws
// its level-1 children; a budget that holds their package bytes but not
// their blobs draws the level-2 tile instead (one group coarsened), where
// the budget on package bytes drew the children. The blob bytes --stats
// reports are the sums decal::Package::open decodes from the tiles this
// test picks from tileset.json.
TEST_F(Tileset, GpuBudgetCountsDecodedBlobBytesAndCoarsensTheView) {
  const std::string ts = levels();
  const prep::TilesetIndex ix = prep::read_tileset_index(ts);
  ASSERT_EQ(ix.levels.size(), 2u);
  auto meets = [](const prep::Extent& a, const prep::Extent& b) {
    return a.xmin < b.xmax && b.xmin < a.xmax && a.ymin < b.ymax && b.ymin < a.ymax;
  };
  // Of the level-2 tiles with at least two children, whose blobs are
  // smaller than their children's and larger than the children's package
  // bytes, the one with the most level-1 blob bytes under it. (The sample's
  // min_width_px streets make the coarsest level's cells hold them farther
  // out, formats/SPEC.md "Minimum widths", so not every parent qualifies.)
  struct Pick {
    const prep::TileEntry* parent = nullptr;
    prep::Extent view;
    size_t children = 0;
    uint64_t package = 0, blob = 0;  // the children's
    uint64_t parent_blob = 0;
  } pick;
  for (const prep::TileEntry& p : ix.levels[1].tiles) {
    Pick c;
    c.parent = &p;
    c.view = {p.square.xmin + 1, p.square.ymin + 1, p.square.xmax - 1, p.square.ymax - 1};
    for (const prep::TileEntry& t : ix.levels[0].tiles)
      if (meets(t.square, c.view)) {
        ++c.children;
        c.package += t.bytes;
        c.blob += decoded_bytes(ts, t);
      }
    c.parent_blob = decoded_bytes(ts, p);
    if (c.children >= 2 && c.package < c.parent_blob && c.parent_blob < c.blob &&
        c.blob > pick.blob)
      pick = c;
  }
  ASSERT_NE(pick.parent, nullptr) << "no level-2 tile makes the case";
  const uint64_t parent_blob = pick.parent_blob;
  const uint64_t parent_package = pick.parent->bytes;
  std::printf(
      "[ measured ] level-2 tile %s: %llu package bytes, %llu blob bytes; its %zu level-1 "
      "children: %llu package bytes, %llu blob bytes\n",
      prep::tile_name(pick.parent->key).c_str(), static_cast<unsigned long long>(parent_package),
      static_cast<unsigned long long>(parent_blob), pick.children,
      static_cast<unsigned long long>(pick.package), static_cast<unsigned long long>(pick.blob));
  ASSERT_GE(pick.children, 2u);
  ASSERT_LT(pick.package, parent_blob) << "the case needs the children's package bytes to fit";
  ASSERT_LT(parent_blob, pick.blob) << "the case needs the parent's blobs to be the smaller";

  // Pixels halfway between r_1 and r_2: level 1 where there is data.
  const double pixel = 0.5 * (ix.levels[0].resolution + ix.levels[1].resolution);
  const auto side = uint32_t(std::ceil((pick.view.xmax - pick.view.xmin) / pixel));
  const std::string common = "render " + shell_quote(ts) + " --cpu --flat --only dynamic --size " +
                             std::to_string(side) + "x" + std::to_string(side) + " --extent " +
                             extent_arg(pick.view) + " --stats -o " +
                             shell_quote(file("levels.png"));
  const std::string children = "tiles: " + std::to_string(pick.children) +
                               " drawn (level 0: 0, level 1: " + std::to_string(pick.children) +
                               ", level 2: 0)";
  const std::string parent = "tiles: 1 drawn (level 0: 0, level 1: 0, level 2: 1)";
  auto bytes_line = [](uint64_t package) {
    return "bytes: " + std::to_string(package) + " package bytes loaded, ";
  };
  auto blob_line = [](uint64_t blob) {
    return "; " + std::to_string(blob) + " blob bytes uploaded";
  };
  // No budget, and a budget that holds the children's blobs exactly.
  for (const std::string& budget : {std::string(), " --gpu-budget " + std::to_string(pick.blob)}) {
    const auto r = run_tool(common + budget, *dir_);
    ASSERT_EQ(r.rc, 0) << r.output;
    EXPECT_NE(r.output.find(children), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(bytes_line(pick.package)), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(blob_line(pick.blob)), std::string::npos) << r.output;
  }
  // Budgets above the children's package bytes but below their blobs.
  for (uint64_t budget : {pick.blob - 1, parent_blob}) {
    const auto r = run_tool(common + " --gpu-budget " + std::to_string(budget), *dir_);
    ASSERT_EQ(r.rc, 0) << r.output;
    EXPECT_NE(r.output.find(parent), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(bytes_line(parent_package)), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(blob_line(parent_blob)), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("gpu budget: " + std::to_string(budget) +
                            " bytes of decoded blobs (GPU memory, not package bytes), " +
                            std::to_string(parent_blob) + " used, 1 tile groups coarsened to fit"),
              std::string::npos)
        << r.output;
    EXPECT_LE(parent_blob, budget);
  }
  // Below the level-2 tile's blobs: nothing coarser to draw.
  const auto r = run_tool(common + " --gpu-budget " + std::to_string(parent_blob - 1), *dir_);
  EXPECT_EQ(r.rc, int(prep::ExitCode::resource)) << r.output;
  EXPECT_NE(r.output.find("need " + std::to_string(parent_blob) + " bytes"), std::string::npos)
      << r.output;
}

TEST_F(Tileset, GlRenderOfTheTilesetEqualsItsCpuRender) {
  const prep::TilesetIndex ix = prep::read_tileset_index(file("tiles"));
  const View v = monaco_view(ix);
  const std::string common = " --flat --aa none --extent " + extent_arg(v.abs) + " --size " +
                             std::to_string(v.w) + "x" + std::to_string(v.h) +
                             " --only polygons,lines";
  auto r = run_tool("render " + shell_quote(file("tiles")) + common + " --cpu -o " +
                        shell_quote(file("cpu.png")) + " --raw " + shell_quote(file("cpu.raw")),
                    *dir_);
  ASSERT_EQ(r.rc, 0) << r.output;
  r = run_tool("render " + shell_quote(file("tiles")) + common + " -o " +
                   shell_quote(file("gl.png")) + " --raw " + shell_quote(file("gl.raw")),
               *dir_);
  ASSERT_EQ(r.rc, 0) << r.output;
  const size_t n = size_t(v.w) * v.h;
  const std::vector<float> a = read_raw(file("cpu.raw"), 4 * n);
  const std::vector<float> b = read_raw(file("gl.raw"), 4 * n);
  const std::vector<size_t> diff = differing(a, b);
  const size_t far = far_from_boundaries(diff, v, file("single.decals"));
  std::printf(
      "[ measured ] GL vs CPU on the tileset: %zu of %zu pixels differ, %zu farther than "
      "2 mm from a boundary\n",
      diff.size(), n, far);
  EXPECT_LE(double(diff.size()), 1e-4 * double(n));
  EXPECT_EQ(far, 0u);
}

#ifdef PREP_RENDER_WITH_GL
// Channels (of 4 per pixel) that differ by more than 1/255: 8-bit images
// by more than 1, float layers by more than 1/255.
size_t pixels_off(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  size_t n = 0;
  for (size_t k = 0; 4 * k < a.size(); ++k)
    for (int c = 0; c < 4; ++c)
      if (std::abs(int(a[4 * k + c]) - int(b[4 * k + c])) > 1) {
        ++n;
        break;
      }
  return n;
}
size_t pixels_off(const std::vector<float>& a, const std::vector<float>& b) {
  size_t n = 0;
  for (size_t k = 0; 4 * k < a.size(); ++k)
    for (int c = 0; c < 4; ++c)
      if (std::fabs(a[4 * k + c] - b[4 * k + c]) > 1.0f / 255) {
        ++n;
        break;
      }
  return n;
}

// The GL render of the tileset (every tile in one frame and one context:
// render_gl.cpp) against the GL render of the single package built from
// the same scene, static polygons and lines and dynamic lines: a top-down
// view over 4 x 4 tiles and an oblique perspective view of every tile (the
// dynamic lines, motorways, are in the north), with and without coverage
// AA (and MSAA top-down), over the build's DEM. A tile drawn at a wrong offset, or a
// tile's layer overwriting another's, moves its decals by metres and shows
// as whole features off.
TEST_F(Tileset, GlRenderOfTheTilesetEqualsTheSinglePackagesGlRender) {
  namespace R = prep::render;
  const prep::TilesetIndex ix = prep::read_tileset_index(file("tiles"));
  decal::Package single;
  ASSERT_TRUE(decal::Package::open(file("single.decals"), single));
  const R::DecalSource one = R::source_of(single);
  std::vector<decal::Package> packages(ix.tiles.size());
  std::vector<R::TileSource> tiles;
  const double ox = ix.frame.origin_x, oy = ix.frame.origin_y;
  for (size_t k = 0; k < ix.tiles.size(); ++k) {
    const prep::TileEntry& t = ix.tiles[k];
    ASSERT_TRUE(decal::Package::open(file("tiles/" + t.file), packages[k]));
    tiles.push_back(
        {R::source_of(packages[k]),
         {t.square.xmin - ox, t.square.ymin - oy, t.square.xmax - ox, t.square.ymax - oy},
         t.origin_x - ox,
         t.origin_y - oy});
  }
  const View v = monaco_view(ix);
  const auto in_view = prep::tiles_in(ix, v.abs);
  ASSERT_GE(in_view.size(), 4u);
  std::vector<R::TileSource> shown;
  for (const R::TileSource& t : tiles)
    for (const prep::TileEntry* e : in_view)
      if (t.square.xmin == e->square.xmin - ox && t.square.ymin == e->square.ymin - oy)
        shown.push_back(t);
  ASSERT_EQ(shown.size(), in_view.size());

  // Camera and terrain in a frame: the tileset's (index) or the package's.
  auto shift = [](const prep::Extent& e, double x, double y) {
    return prep::Extent{e.xmin - x, e.ymin - y, e.xmax - x, e.ymax - y};
  };
  // The build's DEM (dynamic lines lie on it), in the tileset's frame and
  // moved into the package's.
  const prep::Extent ground{ix.extent.xmin - 3000, ix.extent.ymin - 3000, ix.extent.xmax + 3000,
                            ix.extent.ymax + 3000};
  // The package records its DEM relative to the folder it was built in; the
  // fixture may have copied it elsewhere, so the sample's DEM is named here.
  prep::DemSpec dem = R::recorded_dem(std::string(single.metadata_json()));
  dem.path = "/vsizip/" + prep::test::monaco_sample("N43E007.hgt.zip") + "/N43E007.hgt";
  const R::Heightfield terrain =
      R::load_heightfield(dem, ix.frame, shift(ground, ox, oy), R::kMeshSamples);
  R::Heightfield one_terrain = terrain;
  one_terrain.x0 += ox - one.frame.origin_x;
  one_terrain.y0 += oy - one.frame.origin_y;
  struct Case {
    const char* name;
    bool oblique;
    R::AntiAliasing aa;
  };
  for (const Case& c : {Case{"top-down, aa none", false, R::AntiAliasing::none},
                        Case{"top-down, aa coverage", false, R::AntiAliasing::coverage},
                        Case{"top-down, aa msaa4", false, R::AntiAliasing::msaa4},
                        Case{"oblique, aa none", true, R::AntiAliasing::none},
                        Case{"oblique, aa coverage", true, R::AntiAliasing::coverage}}) {
    SCOPED_TRACE(c.name);
    auto options = [&](double x, double y) {
      R::RenderOptions o;
      o.width = c.oblique ? 640 : v.w;
      o.height = c.oblique ? 400 : v.h;
      o.aa = c.aa;
      const prep::Extent e = shift(c.oblique ? ix.extent : v.abs, x, y);
      o.camera = c.oblique ? R::fit_camera(e, terrain.zmin, terrain.zmax, o.width, o.height,
                                           R::Projection::perspective, 35)
                           : R::topdown_camera(e, terrain.zmin, terrain.zmax);
      return o;
    };
    const std::vector<R::TileSource>& drawn = c.oblique ? tiles : shown;
    R::Image a, b;
    try {
      a = R::render_gl(one, one_terrain, options(one.frame.origin_x, one.frame.origin_y));
    } catch (const prep::render_error& e) {
      GTEST_SKIP() << "no headless GL here: " << e.what();
    }
    const size_t n = size_t(a.width) * a.height;
    size_t decals = 0, lines = 0;
    for (size_t k = 0; k < n; ++k) {
      decals += a.decals[4 * k + 3] > 0 ? 1 : 0;
      lines += a.dynamic[4 * k + 3] > 0 ? 1 : 0;
    }
    ASSERT_GT(decals, n / 10) << "the view must show the city";
    if (c.oblique) {
      ASSERT_GT(lines, 0u) << "the view must show dynamic lines";
    }
    b = R::render_gl(drawn, terrain, options(ox, oy));
    ASSERT_EQ(b.rgba.size(), a.rgba.size());
    // With coverage AA a tileset's edge pixels differ from the single
    // package's already per tile (the tiles' data is cut at the squares),
    // so the oracle is each tile rendered on its own as one package, in
    // its frame and clipped to its square, each pixel from the tile with
    // the most alpha there.
    if (c.aa == R::AntiAliasing::coverage) {
      const size_t single_off = pixels_off(a.decals, b.decals);
      R::Image merged;
      for (const R::TileSource& t : drawn) {
        R::RenderOptions o = options(ox + t.dx, oy + t.dy);
        o.clip = shift(t.square, t.dx, t.dy);
        R::Heightfield h = terrain;
        h.x0 -= t.dx;
        h.y0 -= t.dy;
        R::Image img = R::render_gl(t.source, h, o);
        if (merged.rgba.empty()) {
          merged = std::move(img);
          continue;
        }
        for (size_t k = 0; k < n; ++k)
          if (img.decals[4 * k + 3] + img.dynamic[4 * k + 3] >
              merged.decals[4 * k + 3] + merged.dynamic[4 * k + 3])
            for (int ch = 0; ch < 4; ++ch) {
              merged.rgba[4 * k + ch] = img.rgba[4 * k + ch];
              merged.decals[4 * k + ch] = img.decals[4 * k + ch];
              merged.dynamic[4 * k + ch] = img.dynamic[4 * k + ch];
            }
      }
      std::printf(
          "[ measured ] %s: the tileset differs from the single package's on %zu "
          "of %zu pixels (static layer)\n",
          c.name, single_off, n);
      a = std::move(merged);
    }
    const size_t off_rgba = pixels_off(a.rgba, b.rgba), off_decals = pixels_off(a.decals, b.decals),
                 off_dyn = pixels_off(a.dynamic, b.dynamic);
    // The one-frame path: one pass-table row per pass, naming its tiles.
    bool per_pass = false;
    for (const R::PassTime& t : b.times) per_pass |= t.pass.find(" tiles]") != std::string::npos;
    EXPECT_TRUE(per_pass) << "the tileset was not drawn in one frame";
    std::printf(
        "[ measured ] %s, %zu tiles: %zu of %zu pixels differ by more than 1/255 (image), %zu "
        "(static layer, %zu covered), %zu (dynamic layer, %zu covered)\n",
        c.name, drawn.size(), off_rgba, n, off_decals, decals, off_dyn, lines);
    EXPECT_LE(double(off_rgba), 1e-4 * double(n));
    EXPECT_LE(double(off_decals), 1e-4 * double(n));
    EXPECT_LE(double(off_dyn), 1e-4 * double(n));
  }
}
#endif  // PREP_RENDER_WITH_GL

TEST_F(Tileset, PerLayerCountsEqualTheSinglePackages) {
  const json single = read_json("single.decals.json");
  const prep::TilesetIndex ix = prep::read_tileset_index(file("tiles"));
  const json& layers = single.at("manifest").at("layers");
  ASSERT_EQ(layers.size(), ix.manifest.layers.size());
  for (size_t i = 0; i < layers.size(); ++i) {
    const prep::LayerCounts& t = ix.manifest.layers[i];
    SCOPED_TRACE(t.layer);
    EXPECT_EQ(layers[i].at("layer").get<std::string>(), t.layer);
    EXPECT_EQ(layers[i].at("read").get<uint64_t>(), t.read);
    EXPECT_EQ(layers[i].at("kept").get<uint64_t>(), t.kept);
    EXPECT_EQ(layers[i].at("repaired").get<uint64_t>(), t.repaired);
    EXPECT_EQ(layers[i].at("clipped_away").get<uint64_t>(), t.clipped_away);
    EXPECT_EQ(layers[i].at("dropped").get<uint64_t>(), t.dropped);
    EXPECT_EQ(t.read, t.kept + t.clipped_away + t.dropped);
    // Each kept feature has a part in at least one tile, and in no more
    // tiles than there are.
    uint64_t in_tiles = 0;
    for (const prep::TileEntry& e : ix.tiles) in_tiles += e.layers.at(i).kept;
    EXPECT_GE(in_tiles, t.kept);
  }
  EXPECT_EQ(single.at("manifest").at("entry_count").get<uint64_t>(), ix.entry_count);
  // manifest.json holds the entries the index counts, and its hash.
  const auto d = prep::file_digest(file("tiles") + "/manifest.json");
  ASSERT_TRUE(d);
  EXPECT_EQ(d->xxh64, ix.manifest_xxh64);
  EXPECT_EQ(read_json("tiles/manifest.json").at("entries").size(), ix.entry_count);
}

TEST_F(Tileset, BytesDoNotDependOnJobsOrThreads) {
  EXPECT_EQ(file_bytes(file("tiles/tileset.json")), file_bytes(file("tiles1/tileset.json")));
  const prep::TilesetIndex ix = prep::read_tileset_index(file("tiles"));
  ASSERT_GT(ix.tiles.size(), 9u);
  for (const prep::TileEntry& t : ix.tiles) {
    const std::string a = file_bytes(file("tiles/" + t.file));
    EXPECT_EQ(a.size(), t.bytes) << t.file;
    EXPECT_TRUE(a == file_bytes(file("tiles1/" + t.file))) << t.file;
  }
}

TEST_F(Tileset, ARunAgainRebuildsOnlyMissingOrDamagedTiles) {
  // Built here, not copied from the fixture's: a tile records its DEM
  // relative to its own folder (formats/SPEC.md "Metadata"), so a tileset
  // moved elsewhere is rebuilt, not kept. A copy of this first build is the
  // reference the resumed builds must equal.
  const std::string copy = file("resume");
  const std::string scene = shell_quote(prep::test::monaco_sample("scene.toml"));
  const std::string cmd = "build " + scene + " -o " + shell_quote(copy) +
                          " --tile-size 500 --jobs 2 --report " + shell_quote(file("resume.json")) +
                          " -q";
  auto r = run_tool(cmd, *dir_);
  ASSERT_EQ(r.rc, 0) << r.output;
  const std::string reference = file("resume_reference");
  fs::copy(copy, reference, fs::copy_options::recursive);
  const prep::TilesetIndex ix = prep::read_tileset_index(copy);
  ASSERT_GE(ix.tiles.size(), 3u);
  r = run_tool(cmd, *dir_);
  ASSERT_EQ(r.rc, 0) << r.output;
  json rep = read_json("resume.json");
  EXPECT_EQ(rep.at("tileset").at("built").get<size_t>(), 0u);
  EXPECT_EQ(rep.at("tileset").at("reused").get<size_t>(), ix.tiles.size());

  fs::remove(copy + "/" + ix.tiles[0].file);
  {
    std::fstream f(copy + "/" + ix.tiles[1].file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(ix.tiles[1].bytes / 2));
    char c = 0;
    f.read(&c, 1);
    f.seekp(std::streamoff(ix.tiles[1].bytes / 2));
    c = char(c ^ 0x5a);
    f.write(&c, 1);
  }
  // What a tile write killed on a file system without O_TMPFILE leaves
  // (AtomicFile's named temp file) goes at finalize; a file of the user's
  // beside the tiles stays.
  const fs::path tile0 = fs::path(copy) / ix.tiles[0].file;
  const fs::path leftover =
      tile0.parent_path() / ("." + tile0.filename().string() + ".tmp-99999-0");
  const fs::path users = tile0.parent_path() / ".notes.tmp-1";
  for (const fs::path& p : {leftover, users}) std::ofstream(p) << "partial";
  r = run_tool(cmd, *dir_);
  ASSERT_EQ(r.rc, 0) << r.output;
  rep = read_json("resume.json");
  EXPECT_EQ(rep.at("tileset").at("built").get<size_t>(), 2u);
  EXPECT_EQ(rep.at("tileset").at("reused").get<size_t>(), ix.tiles.size() - 2);
  EXPECT_FALSE(fs::exists(leftover));
  EXPECT_TRUE(fs::exists(users));
  EXPECT_EQ(file_bytes(copy + "/tileset.json"), file_bytes(reference + "/tileset.json"));
  for (const prep::TileEntry& t : ix.tiles)
    EXPECT_TRUE(file_bytes(copy + "/" + t.file) == file_bytes(reference + "/" + t.file)) << t.file;
}

TEST_F(Tileset, VerifyAndInfoTakeTheDirectory) {
  auto r = run_tool("verify " + shell_quote(file("tiles")), *dir_);
  EXPECT_EQ(r.rc, 0) << r.output;
  r = run_tool("info " + shell_quote(file("tiles")), *dir_);
  EXPECT_EQ(r.rc, 0) << r.output;
  EXPECT_NE(r.output.find("tiles"), std::string::npos) << r.output;
  // One flipped byte in one tile: verify names it and fails.
  const std::string copy = file("damaged");
  fs::copy(file("tiles"), copy, fs::copy_options::recursive);
  const prep::TilesetIndex ix = prep::read_tileset_index(copy);
  {
    std::fstream f(copy + "/" + ix.tiles[2].file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(ix.tiles[2].bytes - 9));
    f.put('\x7f');
  }
  r = run_tool("verify " + shell_quote(copy), *dir_);
  EXPECT_EQ(r.rc, 5) << r.output;
  EXPECT_NE(r.output.find(ix.tiles[2].file), std::string::npos) << r.output;
}

}  // namespace

namespace {

// The index is read as untrusted input: each change a writer never makes
// is refused with a format_error naming the field.
TEST_F(Tileset, TheIndexReaderRefusesWhatTheWriterNeverWrites) {
  const json good = read_json("tiles/tileset.json");
  struct Case {
    const char* what;
    std::function<void(json&)> change;
    const char* field;
  };
  const std::vector<Case> cases = {
      {"a path out of the directory", [](json& j) { j["tiles"][0]["file"] = "../x.decals"; },
       "tiles[0].file"},
      {"another tile's file", [](json& j) { j["tiles"][0]["file"] = j["tiles"][1]["file"]; },
       "tiles[0].file"},
      {"a tile listed twice",
       [](json& j) {
         j["tiles"][1]["x"] = j["tiles"][0]["x"], j["tiles"][1]["y"] = j["tiles"][0]["y"];
       },
       "tiles[1]"},
      {"a square off its key", [](json& j) { j["tiles"][0]["square"][0] = 1.5; },
       "tiles[0].square"},
      {"an origin off the centre", [](json& j) { j["tiles"][0]["origin"][1] = 0.25; },
       "tiles[0].origin"},
      {"a hash that is not hex", [](json& j) { j["tiles"][0]["xxh64"] = "zz"; }, "tiles[0].xxh64"},
      {"a negative count", [](json& j) { j["tiles"][0]["bytes"] = -1; }, "tiles[0].bytes"},
      {"another major version", [](json& j) { j["tileset_version"] = "2.0"; }, "tileset_version"},
      {"no tile size", [](json& j) { j["tiling"].erase("tile_size_m"); }, "tiling.tile_size_m"},
      {"a tile size of 0", [](json& j) { j["tiling"]["tile_size_m"] = 0; }, "tiling.tile_size_m"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const std::string dir = file(std::string("bad_") + c.what);
    fs::create_directories(dir);
    json j = good;
    c.change(j);
    prep::test::write_text(dir + "/tileset.json", j.dump());
    try {
      prep::read_tileset_index(dir);
      ADD_FAILURE() << "accepted";
    } catch (const prep::format_error& e) {
      EXPECT_NE(std::string(e.what()).find(c.field), std::string::npos) << e.what();
    }
  }
  // The unchanged index reads.
  const std::string dir = file("good_index");
  fs::create_directories(dir);
  prep::test::write_text(dir + "/tileset.json", good.dump());
  EXPECT_NO_THROW(prep::read_tileset_index(dir));
}

}  // namespace

namespace {

// Two small squares 40 degrees of longitude apart on the equator (about
// 4,450 km): too wide for one package. The build stops right after project,
// before clean starts, naming the feature; as a tileset it builds.
TEST(TilesetSpan, TooWideForOnePackageFailsBeforeCleanAndBuildsAsATileset) {
  prep::test::TempDir dir("span");
  const std::string src = dir.file("wide.geojson");
  prep::test::write_text(src,
                         R"({"type":"FeatureCollection","features":[
{"type":"Feature","id":1,"properties":{},"geometry":{"type":"Polygon","coordinates":[[[0,0],[0.01,0],[0.01,0.01],[0,0.01],[0,0]]]}},
{"type":"Feature","id":2,"properties":{},"geometry":{"type":"Polygon","coordinates":[[[40,0],[40.01,0],[40.01,0.01],[40,0.01],[40,0]]]}}]})");
  auto r = run_tool("build " + shell_quote(src) + " --kind polygon -o " +
                        shell_quote(dir.file("one.decals")) + " --progress json",
                    dir, {.split_stderr = true});
  EXPECT_EQ(r.rc, 3) << r.err;
  EXPECT_NE(r.err.find("lies more than 2147 km from the package origin"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("--tile-size"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("\"stage\":\"clean\""), std::string::npos) << "clean ran:\n" << r.err;
  EXPECT_FALSE(fs::exists(dir.file("one.decals")));

  r = run_tool("build " + shell_quote(src) + " --kind polygon -o " +
                   shell_quote(dir.file("tiles")) + " --tile-size 100000 -q",
               dir);
  ASSERT_EQ(r.rc, 0) << r.output;
  const prep::TilesetIndex ix = prep::read_tileset_index(dir.file("tiles"));
  // Each 1.1 km square lies in at most 4 tiles; nothing between them.
  EXPECT_GE(ix.tiles.size(), 2u);
  EXPECT_LE(ix.tiles.size(), 8u);
  ASSERT_EQ(ix.manifest.layers.size(), 1u);
  EXPECT_EQ(ix.manifest.layers[0].kept, 2u);
  EXPECT_GT(ix.extent.xmax - ix.extent.xmin, 4.0e6);
  r = run_tool("verify " + shell_quote(dir.file("tiles")), dir);
  EXPECT_EQ(r.rc, 0) << r.output;
}

}  // namespace
