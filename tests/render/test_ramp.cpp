// `render --ramp LAYER=value:#rrggbb,...`: a value-coloured layer restyled
// when drawing, from the values the package stores (LineProps/PolyProps
// .value), without a rebuild. One package of squares and lines, each with
// its own attribute value, rendered top-down with no ramp, then with two
// different ramps, on the CPU and in GL; at every feature's centre the decal
// colour must be the ramp's colour for that feature's value. The oracle is
// the ramp rule as docs/render.md states it (linear per channel between the two
// stops around the value, clamped outside them, the layer colour for a
// feature without a value), computed here from the values this test wrote.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "decal/reader.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_ramp {

namespace fs = std::filesystem;
using prep::test::run_tool;

namespace {

constexpr double kX0 = 500000, kY0 = 4800000;
// Squares (40 m) and lines (8 m wide) along two rows, 100 m apart; values
// inside, on and past the stops, and one feature without a value.
const std::vector<std::optional<double>> kSquareValues = {0.0, 1.0, 2.2, 3.7, 5.0, 9.0, {}};
const std::vector<std::optional<double>> kLineValues = {0.0, 2.0, 7.3, 10.0, 12.0, {}};
const std::vector<double> kDynValues = {0.0, 0.25, 0.8};

struct Stop {
  double value;
  std::array<int, 4> rgba;
};
using Ramp = std::vector<Stop>;

// The rule of docs/render.md, per channel.
std::array<int, 4> ramp_colour(const Ramp& r, std::optional<double> v, std::array<int, 4> none) {
  if (!v) return none;
  const double x = float(*v);  // stored as f32
  if (x <= r.front().value) return r.front().rgba;
  if (x >= r.back().value) return r.back().rgba;
  size_t k = 0;
  while (!(r[k].value <= x && x <= r[k + 1].value)) ++k;
  const double t = (x - r[k].value) / (r[k + 1].value - r[k].value);
  std::array<int, 4> out{};
  for (int c = 0; c < 4; ++c)
    out[c] = int(std::lround(r[k].rgba[c] + t * (r[k + 1].rgba[c] - r[k].rgba[c])));
  return out;
}

std::string value_json(std::optional<double> v) {
  return v ? std::to_string(*v) : "null";
}

std::string feature_collection(const std::vector<std::string>& features) {
  std::string s =
      R"({"type":"FeatureCollection","crs":{"type":"name","properties":{"name":"EPSG:32632"}},"features":[)";
  for (size_t i = 0; i < features.size(); ++i) s += (i ? "," : "") + features[i];
  return s + "]}";
}

std::string feature(std::optional<double> v, const std::string& geometry) {
  return R"({"type":"Feature","properties":{"v":)" + value_json(v) + R"(},"geometry":)" + geometry +
         "}";
}

std::string point(double x, double y) {
  return "[" + std::to_string(x) + "," + std::to_string(y) + "]";
}

// Writes the three layers and the scene file; returns the scene path.
std::string write_scene(const fs::path& dir) {
  std::vector<std::string> squares, lines, dyn;
  for (size_t k = 0; k < kSquareValues.size(); ++k) {
    const double x = kX0 + 100.0 * double(k), y = kY0;
    squares.push_back(feature(kSquareValues[k], R"({"type":"Polygon","coordinates":[[)" +
                                                    point(x, y) + "," + point(x + 40, y) + "," +
                                                    point(x + 40, y + 40) + "," + point(x, y + 40) +
                                                    "," + point(x, y) + "]]}"));
  }
  for (size_t k = 0; k < kLineValues.size(); ++k) {
    const double x = kX0 + 100.0 * double(k), y = kY0 + 100;
    lines.push_back(feature(kLineValues[k], R"({"type":"LineString","coordinates":[)" +
                                                point(x, y) + "," + point(x + 60, y) + "]}"));
  }
  for (size_t k = 0; k < kDynValues.size(); ++k) {
    const double x = kX0 + 100.0 * double(k), y = kY0 + 200;
    dyn.push_back(feature(kDynValues[k], R"({"type":"LineString","coordinates":[)" + point(x, y) +
                                             "," + point(x + 60, y) + "]}"));
  }
  std::ofstream(dir / "sq.geojson") << feature_collection(squares);
  std::ofstream(dir / "ln.geojson") << feature_collection(lines);
  std::ofstream(dir / "dyn.geojson") << feature_collection(dyn);
  std::ofstream(dir / "scene.toml")
      << render_test::utm_scene_toml({{"sq", "polygon",
                                       "color = \"#808080\"\ncolor_attribute = \"v\"\n"
                                       "color_ramp = [[0, \"#000000\"], [5, \"#ffffff\"]]\n"},
                                      {"ln", "line",
                                       "width = 8\ncolor = \"#a0a0a0\"\ncolor_attribute = \"v\"\n"
                                       "color_ramp = [[0, \"#ff0000\"], [10, \"#00ff00\"]]\n"},
                                      {"dyn", "line",
                                       "dynamic = true\nwidth = 4\ncolor_attribute = \"v\"\n"
                                       "color_ramp = [[0, \"#0000ff\"], [1, \"#ffff00\"]]\n"}});
  return (dir / "scene.toml").string();
}

std::vector<char> bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

class RenderRamp : public ::testing::Test {
 protected:
  // Each test builds its own package in its own folder (ctest runs the
  // tests of this file in parallel processes).
  void SetUp() override {
    dir_ = fs::current_path() / "render-out" / "ramp" /
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    pkg_ = (dir_ / "ramp.decals").string();
    const auto b = run_tool("build " + write_scene(dir_) + " -o " + pkg_ + " -q");
    ASSERT_EQ(b.rc, 0) << b.output;
  }

  // Renders the package top-down (1 m pixels over both rows) with `extra`
  // and returns the decal layer (straight alpha); nullopt with `why` when
  // there is no headless GL.
  std::optional<std::vector<float>> render(const std::string& name, const std::string& extra,
                                           std::string& why) {
    const fs::path raw = dir_ / (name + ".rgba");
    char extent[200];
    std::snprintf(extent, sizeof extent, "--extent %.0f,%.0f,%.0f,%.0f --size %dx%d", kX0 - 20,
                  kY0 - 20, kX0 + 720, kY0 + 220, 740, 240);
    const auto r = run_tool("render " + pkg_ + " " + extent + " --flat --raw " + raw.string() +
                            " -o " + (dir_ / (name + ".png")).string() + " " + extra);
    if (r.rc == 8) {
      why = "no headless GL: " + r.output;
      return std::nullopt;
    }
    EXPECT_EQ(r.rc, 0) << extra << "\n" << r.output;
    return render_test::read_raw(raw.string());
  }

  // The decal colour (0..255, straight alpha) at absolute (x, y).
  static std::array<double, 4> at(const std::vector<float>& img, double x, double y) {
    const size_t i = size_t(x - (kX0 - 20)), j = size_t((kY0 + 220) - y);
    const float* p = &img[(j * 740 + i) * 4];
    return {p[0] * 255.0, p[1] * 255.0, p[2] * 255.0, p[3] * 255.0};
  }

  // Every square's and line's centre shows the expected colour.
  static void expect_colours(const std::vector<float>& img, const Ramp& squares, const Ramp& lines,
                             const std::string& what) {
    ASSERT_EQ(img.size(), size_t(740) * 240 * 4) << what;
    auto check = [&](const std::array<double, 4>& got, const std::array<int, 4>& want,
                     const std::string& where) {
      for (int c = 0; c < 4; ++c)
        EXPECT_NEAR(got[c], want[c], 1.01) << what << ", " << where << ", channel " << c;
    };
    for (size_t k = 0; k < kSquareValues.size(); ++k)
      check(at(img, kX0 + 100.0 * double(k) + 20, kY0 + 20),
            ramp_colour(squares, kSquareValues[k], {0x80, 0x80, 0x80, 255}),
            "square " + std::to_string(k));
    for (size_t k = 0; k < kLineValues.size(); ++k)
      check(at(img, kX0 + 100.0 * double(k) + 30, kY0 + 100),
            ramp_colour(lines, kLineValues[k], {0xa0, 0xa0, 0xa0, 255}),
            "line " + std::to_string(k));
  }

  fs::path dir_;
  std::string pkg_;
};

const Ramp kBuildSquares = {{0, {0, 0, 0, 255}}, {5, {255, 255, 255, 255}}};
const Ramp kBuildLines = {{0, {255, 0, 0, 255}}, {10, {0, 255, 0, 255}}};
const Ramp kSquaresA = {{0, {255, 0, 0, 255}}, {5, {0, 0, 255, 255}}};
const Ramp kLinesA = {{0, {0, 0, 0, 255}}, {10, {255, 255, 255, 128}}};
const Ramp kSquaresB = {{0, {0, 255, 0, 255}}, {2.5, {255, 255, 255, 255}}, {5, {0, 0, 0, 255}}};
const std::string kArgsA = "--ramp sq=0:#ff0000,5:#0000ff --ramp ln=0:#000000,10:#ffffff80";
const std::string kArgsB = "--ramp sq=0:#00ff00,2.5:#ffffff,5:#000000";

TEST_F(RenderRamp, TwoRampsGiveTwoColourSetsPerFeatureOnTheCpuWithoutARebuild) {
  const std::vector<char> before = bytes_of(pkg_);
  std::string why;
  const auto baked = render("cpu_baked", "--cpu", why);
  const auto a = render("cpu_a", "--cpu " + kArgsA, why);
  const auto b = render("cpu_b", "--cpu " + kArgsB, why);
  ASSERT_TRUE(baked && a && b);
  expect_colours(*baked, kBuildSquares, kBuildLines, "no --ramp (the build's ramp)");
  expect_colours(*a, kSquaresA, kLinesA, "ramp A");
  expect_colours(*b, kSquaresB, kBuildLines, "ramp B (lines keep the build's)");
  EXPECT_EQ(bytes_of(pkg_), before) << "rendering with a ramp changed the package";
}

TEST_F(RenderRamp, TwoRampsGiveTwoColourSetsPerFeatureInGlForEveryMethod) {
  std::string why;
  for (const char* method : {"decal", "volume", "texture"}) {
    const std::string m = std::string(" --method ") + method +
                          (std::string(method) == "texture" ? " --texture-resolution 0.5" : "");
    const auto a = render(std::string("gl_a_") + method, kArgsA + m, why);
    if (!a) GTEST_SKIP() << why;
    const auto b = render(std::string("gl_b_") + method, kArgsB + m, why);
    ASSERT_TRUE(b) << why;
    expect_colours(*a, kSquaresA, kLinesA, std::string("ramp A, ") + method);
    expect_colours(*b, kSquaresB, kBuildLines, std::string("ramp B, ") + method);
  }
}

// Dynamic lines have no CPU renderer; the props the GL pass uploads are
// checked instead: restyle() recolours the dynamic layer's copy and leaves
// the package's own blob as it was.
TEST_F(RenderRamp, RestyleRecoloursDynamicLinePropsAndLeavesThePackageBlob) {
  decal::Package pkg;
  ASSERT_TRUE(decal::Package::open(pkg_, pkg));
  prep::render::DecalSource src = prep::render::source_of(pkg);
  const std::vector<std::string> names =
      prep::render::layer_names(std::string(pkg.metadata_json()));
  ASSERT_EQ(names, (std::vector<std::string>{"sq", "ln", "dyn"}));
  prep::render::LayerRamps ramps(names.size());
  ramps[2] = {{0, 0xff00ff00u}, {1, 0x80ff0000u}};  // green to half-transparent blue
  const Ramp oracle = {{0, {0, 255, 0, 255}}, {1, {0, 0, 255, 128}}};
  prep::render::RestyledProps held;
  prep::render::restyle(src, ramps, held);
  ASSERT_EQ(held.dyn.size(), kDynValues.size());
  const decal::BlobView* original = pkg.find(decal::BlobId::dyn_line_props);
  ASSERT_NE(original, nullptr);
  for (size_t k = 0; k < held.dyn.size(); ++k) {
    const auto want = ramp_colour(oracle, double(held.dyn[k].value), {});
    const uint32_t got = held.dyn[k].rgba;
    for (int c = 0; c < 4; ++c) EXPECT_EQ(int((got >> (8 * c)) & 0xffu), want[c]) << k;
    decal::LineProps stored;
    std::memcpy(&stored, original->bytes.data() + k * sizeof stored, sizeof stored);
    const auto baked =
        ramp_colour({{0, {0, 0, 255, 255}}, {1, {255, 255, 0, 255}}}, double(stored.value), {});
    for (int c = 0; c < 4; ++c)
      EXPECT_EQ(int((stored.rgba >> (8 * c)) & 0xffu), baked[c]) << "package blob, line " << k;
  }
  EXPECT_EQ(held.recoloured, kDynValues.size());
}

TEST_F(RenderRamp, AnUnknownLayerOrDecreasingStopsAreUsageErrorsThatSayWhy) {
  auto r = run_tool("render " + pkg_ + " --cpu -o " + (dir_ / "x.png").string() +
                    " --ramp roads=0:#ffffff");
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("no layer 'roads' (its layers: sq, ln, dyn)"), std::string::npos)
      << r.output;
  r = run_tool("render " + pkg_ + " --cpu -o " + (dir_ / "x.png").string() +
               " --ramp sq=5:#ffffff,1:#000000");
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("stop values must increase"), std::string::npos) << r.output;
  r = run_tool("render " + pkg_ + " --cpu -o " + (dir_ / "x.png").string() + " --ramp sq=1:#fffff");
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("#rrggbb"), std::string::npos) << r.output;
}

// A layer built without color_attribute stores no values: a ramp for it
// is refused naming the layer and the key, not counted as recolouring.
TEST(RenderRampPlain, ARampOnALayerWithoutColorAttributeIsAUsageErrorNamingIt) {
  const fs::path dir = fs::current_path() / "render-out" / "ramp" / "plain";
  fs::remove_all(dir);
  fs::create_directories(dir);
  write_scene(dir);  // the geojson files
  std::string why;
  const std::string pkg = render_test::build_utm_scene(
      dir, "plain.decals", {{"sq", "polygon", "color = \"#808080\"\n"}}, why);
  ASSERT_FALSE(pkg.empty()) << why;
  const auto r = run_tool("render " + pkg + " --cpu --stats -o " + (dir / "x.png").string() +
                          " --ramp sq=0:#000000,5:#ffffff");
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("layer 'sq' was built without color_attribute"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir / "x.png"));
}

}  // namespace

}  // namespace render_ramp
