// The evaluator over a package read from disk answers exactly as over the
// in-memory model; render_topdown output goes to a PNG with a world file
// that GDAL places where the extent says.
#include <gdal_priv.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "prep/write.hpp"
#include "synthetic.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace evaluate_package_view {

namespace {

prep::SceneFeatures small_scene() {
  synth::PolygonSet set = synth::polygon_set(21, 4, 50.0, -100.0, 40.0, 3, 300);
  prep::SceneFeatures s = set.scene;
  s.layers.push_back(
      synth::layer("roads", prep::DecalKind::line, 0xc000ff00u, decal::CornerStyle::bevel));
  prep::SceneLine l;
  l.layer = 1;
  l.width = 6;
  l.points = {{-100, 40}, {0, 120}, {30, 60}, {100, 240}};
  s.lines.push_back(l);
  return s;
}

std::filesystem::path temp_dir() {
  auto d = std::filesystem::temp_directory_path() /
           ("decalprep_eval_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace

TEST(PackageView, EvaluatorOnAWrittenPackageMatchesTheModel) {
  const prep::DecalModel m = prep::build_model(small_scene(), {});
  const auto path = temp_dir() / "small.decals";
  prep::write_model(path.string(), m, "{}");
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path.string(), pkg)) << "open failed";
  const prep::StaticView a = prep::view_of(m), b = prep::view_of(pkg);
  EXPECT_EQ(b.grid.nx, m.grid.nx);
  EXPECT_EQ(b.grid.cell_w, m.grid.cell_w);
  EXPECT_EQ(b.grid.origin_y, m.grid.origin_y);
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> X(-110, 110), Y(30, 250);
  int covered = 0;
  for (int i = 0; i < 20000; ++i) {
    const double x = X(rng), y = Y(rng);
    const prep::EvalSample sa = prep::evaluate(a, x, y), sb = prep::evaluate(b, x, y);
    ASSERT_EQ(sa.top_line, sb.top_line);
    ASSERT_EQ(sa.top_polygon, sb.top_polygon);
    ASSERT_EQ(std::memcmp(sa.rgba, sb.rgba, sizeof sa.rgba), 0);
    covered += sa.polygon_covered || sa.line_covered;
  }
  EXPECT_GT(covered, 1000);
  std::filesystem::remove_all(path.parent_path());
}

TEST(PackageView, PackageWithoutGridMetadataIsRejected) {
  const prep::DecalModel m = prep::build_model(small_scene(), {});
  const auto path = temp_dir() / "nogrid.decals";
  prep::write_package(path.string(), R"({"format": "decals"})", prep::model_blobs(m, true));
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(path.string(), pkg));
  EXPECT_THROW(prep::view_of(pkg), prep::format_error);
  // A grid of zero-width cells: the writer refuses to write it, and a
  // package that states one (written raw) is refused on reading.
  prep::DecalModel bad = m;
  bad.grid.cell_w = 0;
  EXPECT_THROW(prep::write_model(path.string(), bad, "{}"), prep::output_error);
  prep::write_package(path.string(),
                      R"({"format": "decals", "grid": {"origin": [0, 0], "cell": [0, 5000],)"
                      R"( "dims": [149, 149]}})",
                      prep::model_blobs(m, true));
  ASSERT_TRUE(decal::Package::open(path.string(), pkg));
  EXPECT_THROW(prep::view_of(pkg), prep::format_error);
  std::filesystem::remove_all(path.parent_path());
}

TEST(RenderTopdown, PngAndWorldFileArePlacedLikeGdalRasterize) {
  const prep::DecalModel m = prep::build_model(small_scene(), {});
  const prep::StaticView v = prep::view_of(m);
  const prep::Extent ex{-100, 40, 100, 240};
  const uint32_t W = 40, H = 20;
  const std::vector<float> img = prep::render_topdown(v, ex, W, H);
  ASSERT_EQ(img.size(), size_t(W) * H * 4);
  // Pixel (i, j) centre as gdal_rasterize -te/-ts places it.
  for (uint32_t j = 0; j < H; j += 3)
    for (uint32_t i = 0; i < W; i += 3) {
      const prep::EvalSample s = prep::evaluate(v, -100 + (i + 0.5) * 5.0, 240 - (j + 0.5) * 10.0);
      EXPECT_FLOAT_EQ(img[(j * W + i) * 4 + 3], s.rgba[3]);
    }
  const auto dir = temp_dir();
  const std::string png = (dir / "top.png").string();
  prep::write_png_rgba(png, W, H, prep::to_rgba8(img));
  prep::write_world_file(png, {1000 - 100, 2000 + 40, 1000 + 100, 2000 + 240}, W, H, "");
  GDALAllRegister();
  auto* ds = static_cast<GDALDataset*>(GDALOpen(png.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  EXPECT_DOUBLE_EQ(gt[0], 900.0);
  EXPECT_DOUBLE_EQ(gt[1], 5.0);
  EXPECT_DOUBLE_EQ(gt[3], 2240.0);
  EXPECT_DOUBLE_EQ(gt[5], -10.0);
  EXPECT_EQ(ds->GetRasterXSize(), int(W));
  EXPECT_EQ(ds->GetRasterCount(), 4);
  GDALClose(ds);
  std::filesystem::remove_all(dir);
}

// A package written by format 1.1 (tests/formats/legacy/golden_v1_1.decals:
// the golden scene, tests/tools/golden/scene.toml, built by the last 1.1
// writer) ranked lines and polygons separately and drew every line over
// every polygon; a 1.2 reader keeps that.
TEST(PackageView, FormatOneOnePackageKeepsEveryLineOverEveryPolygon) {
  const std::string path =
      std::string(DECALPREP_SOURCE_DIR) + "/tests/formats/legacy/golden_v1_1.decals";
  decal::Package p;
  const decal::Status st = decal::Package::open(path, p);
  ASSERT_TRUE(bool(st)) << st.message;
  EXPECT_EQ(p.minor(), 1u);
  const prep::StaticView v = prep::view_of(p);
  ASSERT_FALSE(v.line_props.empty());
  EXPECT_EQ(v.polygon_rank_bias, v.line_props.size());
  const std::vector<prep::DrawRun> runs = prep::draw_runs(v);
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].kind, prep::DrawRun::Kind::lines);
  EXPECT_EQ(runs[0].lo, 0u);
  EXPECT_EQ(runs[0].hi, uint32_t(v.line_props.size()));
  EXPECT_EQ(runs[1].kind, prep::DrawRun::Kind::polygons);
}

}  // namespace evaluate_package_view
