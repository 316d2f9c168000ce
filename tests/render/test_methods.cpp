// `decalprep render --method volume|texture`, the two older methods the
// thesis compares with (§5.2.2): the volume method (Schneider & Klein §4,
// stencil shadow volumes) and the texture method (Taibo et al. §4, features
// rasterised into a mipmapped texture). The oracles are the CPU evaluator
// (`render --cpu`, itself checked against GEOS and gdal_rasterize in
// tests/evaluate and test_smoke.cpp) and, for a generated polygon with a hole
// and an island inside the hole, the analytic even-odd test on the rings the
// test wrote. Frames are small (480x270, 320x320) for llvmpipe.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <sys/file.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>
#include <regex>

#include <nlohmann/json.hpp>

#include "decal/reader.hpp"
#include "prep/features.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_methods {

namespace fs = std::filesystem;
using prep::test::run_tool;
using render_test::read_raw;

namespace {

const std::string kSource = DECALPREP_SOURCE_DIR;
const std::string kDem = "/vsizip/" + kSource + "/samples/monaco/N43E007.hgt.zip/N43E007.hgt";
// Central Monaco, metres relative to the package origin (as test_smoke.cpp).
const prep::Extent kTopDown{-800, -450, 800, 450};
constexpr uint32_t kW = 480, kH = 270;

fs::path out_dir(const std::string& sub) {
  fs::path p = fs::current_path() / "render-out" / sub;
  fs::create_directories(p);
  return p;
}

using render_test::monaco_package;  // the smoke tests' package (smoke_util.hpp)

// `--extent` for `relative` (metres from the package origin), absolute.
std::string topdown_extent(const std::string& pkg, const prep::Extent& r) {
  decal::Package package;
  EXPECT_TRUE(decal::Package::open(pkg, package));
  const auto meta = nlohmann::json::parse(package.metadata_json());
  const double ox = meta.at("origin").at("x").get<double>();
  const double oy = meta.at("origin").at("y").get<double>();
  char b[200];
  std::snprintf(b, sizeof b, "--extent %.6f,%.6f,%.6f,%.6f", r.xmin + ox, r.ymin + oy, r.xmax + ox,
                r.ymax + oy);
  return b;
}

// Runs `render` and reads its static decal layer (--raw); `stats` gets the
// output. False with `why` when there is no headless GL (exit code 8).
bool render_layer(const std::string& args, const fs::path& raw, std::vector<float>& layer,
                  std::string& why, std::string* stats = nullptr) {
  const auto r = run_tool("render " + args + " --raw " + raw.string() + " -o " +
                          fs::path(raw).replace_extension(".png").string());
  if (r.rc == 8) {
    why = "no headless GL: " + r.output;
    return false;
  }
  EXPECT_EQ(r.rc, 0) << args << "\n" << r.output;
  layer = read_raw(raw.string());
  if (stats) *stats = r.output;
  return true;
}

// Two decal layers pixel by pixel (alpha and straight colour within 2/255),
// leaving out the one-pixel band: pixels whose 3x3 neighbourhood in the
// oracle is not uniform (a boundary runs through or beside them).
struct BandComparison {
  size_t considered = 0, mismatched = 0, band = 0, covered = 0;
  double ratio() const { return considered ? double(mismatched) / double(considered) : 1.0; }
};
bool same_pixel(const float* a, const float* b) {
  const float tol = 2.0f / 255.0f + 1e-6f;
  if (std::abs(a[3] - b[3]) > tol) return false;
  if (a[3] <= 0 && b[3] <= 0) return true;
  for (int c = 0; c < 3; ++c)
    if (std::abs(a[c] - b[c]) > tol) return false;
  return true;
}
BandComparison compare_outside_band(const std::vector<float>& drawn,
                                    const std::vector<float>& oracle, uint32_t w, uint32_t h) {
  BandComparison c;
  EXPECT_EQ(drawn.size(), size_t(w) * h * 4);
  EXPECT_EQ(oracle.size(), drawn.size());
  if (drawn.size() != size_t(w) * h * 4 || oracle.size() != drawn.size()) return c;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const float* o = &oracle[(size_t(y) * w + x) * 4];
      bool uniform = true;
      for (int dy = -1; dy <= 1 && uniform; ++dy)
        for (int dx = -1; dx <= 1 && uniform; ++dx) {
          const int nx = int(x) + dx, ny = int(y) + dy;
          if (nx < 0 || ny < 0 || nx >= int(w) || ny >= int(h)) continue;
          uniform = same_pixel(o, &oracle[(size_t(ny) * w + size_t(nx)) * 4]);
        }
      if (!uniform) {
        ++c.band;
        continue;
      }
      ++c.considered;
      c.covered += o[3] > 0;
      c.mismatched += !same_pixel(&drawn[(size_t(y) * w + x) * 4], o);
    }
  return c;
}

// Renders `view` of `pkg` with `--method volume` (`<name>.rgba`, with
// `extra` added) and with the CPU evaluator (`<name>_cpu.rgba`), and
// compares the two outside the one-pixel band. False with `why` when there
// is no headless GL.
bool volume_against_cpu(const std::string& pkg, const std::string& view, const std::string& name,
                        uint32_t w, uint32_t h, BandComparison& c, std::string& why,
                        const std::string& extra = "", std::string* stats = nullptr) {
  const fs::path d = out_dir("methods");
  std::vector<float> vol, cpu;
  if (!render_layer(pkg + " " + view + " --method volume" + extra, d / (name + ".rgba"), vol, why,
                    stats))
    return false;
  EXPECT_TRUE(render_layer(pkg + " " + view + " --cpu", d / (name + "_cpu.rgba"), cpu, why));
  c = compare_outside_band(vol, cpu, w, h);
  return true;
}

// A Monaco view (`--dem` added) at kW x kH, polygons and lines only: the
// volume method against the CPU evaluator, a tenth of the frame covered and
// fewer than one in a thousand pixels off outside the band.
void expect_monaco_volume_matches_cpu(const std::string& pkg, const std::string& view,
                                      const std::string& name, const char* label,
                                      std::string* stats = nullptr) {
  const std::string args = "--dem " + kDem + " " + view + " --size " + std::to_string(kW) + "x" +
                           std::to_string(kH) + " --only polygons,lines";
  BandComparison c;
  std::string why;
  if (!volume_against_cpu(pkg, args, name, kW, kH, c, why, stats ? " --stats" : "", stats))
    GTEST_SKIP() << why;
  std::printf("%s: %zu of %zu pixels differ outside the band (%zu in it), %zu covered\n", label,
              c.mismatched, c.considered, c.band, c.covered);
  EXPECT_GT(c.covered, size_t(kW) * kH / 10);  // a good part of the view is covered
  EXPECT_LT(c.ratio(), 1e-3);
}

TEST(RenderMethods, VolumeTopDownOnMonacoPolygonsAndLinesMatchesCpuEvaluatorOutsideOnePixelBand) {
  std::string why;
  const std::string pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  std::string stats;
  expect_monaco_volume_matches_cpu(pkg, topdown_extent(pkg, kTopDown), "monaco_volume",
                                   "volume top-down", &stats);
  if (!IsSkipped()) {
    EXPECT_NE(stats.find("prism triangles"), std::string::npos) << stats;
  }
}

TEST(RenderMethods, VolumeObliquePerspectiveOnMonacoMatchesCpuEvaluatorOutsideOnePixelBand) {
  std::string why;
  const std::string pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  // The smoke test's oblique view: prisms over the SRTM hills, z-pass.
  expect_monaco_volume_matches_cpu(pkg, "--eye 300,-2200,900 --target 0,0,60 --fov 40",
                                   "monaco_oblique_volume", "volume oblique");
}

// Close up (0.25 m pixels): building outlines 0.6 m inside their footprint
// and hedges 0.8 m outside parks (each closed ring clipped by itself, the
// evaluator's step 6), paths with bevel joints, streets with round ones.
TEST(RenderMethods, VolumeCloseUpOnMonacoOutlinesAndJointsMatchesCpuEvaluatorOutsideOnePixelBand) {
  std::string why;
  const std::string pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  expect_monaco_volume_matches_cpu(pkg, topdown_extent(pkg, {-60, -33.75, 60, 33.75}),
                                   "monaco_close_volume", "volume close-up");
}

// A generated polygon in UTM 32N: a wavy exterior, a round hole, and an
// island inside the hole (a polygon of its own), enough vertices that the
// quad-trees split into many leaves.
struct HoleScene {
  prep::Ring exterior, hole, island;
  double cx = 350000, cy = 4840000;
  static prep::Ring circle(double cx, double cy, double r, double wave, int n, bool cw) {
    prep::Ring ring;
    for (int k = 0; k <= n; ++k) {
      const double a = 2 * std::numbers::pi * (cw ? n - k : k) / n;
      const double rr = r + wave * std::sin(7 * a);
      ring.push_back({cx + rr * std::cos(a), cy + rr * std::sin(a)});
    }
    return ring;
  }
  HoleScene() {
    exterior = circle(cx, cy, 400, 40, 240, false);
    hole = circle(cx + 30, cy - 20, 200, 15, 160, true);
    island = circle(cx + 40, cy - 10, 90, 10, 120, false);
  }
  static bool in_ring(const prep::Ring& r, double x, double y) {
    bool in = false;
    for (size_t i = 0, j = r.size() - 1; i < r.size(); j = i++)
      if ((r[i].y > y) != (r[j].y > y) &&
          x < (r[j].x - r[i].x) * (y - r[i].y) / (r[j].y - r[i].y) + r[i].x)
        in = !in;
    return in;
  }
  bool inside(double x, double y) const {
    return (in_ring(exterior, x, y) && !in_ring(hole, x, y)) || in_ring(island, x, y);
  }
  static double distance(const prep::Ring& r, double x, double y) {
    double best = INFINITY;
    for (size_t i = 0; i + 1 < r.size(); ++i) {
      const double ex = r[i + 1].x - r[i].x, ey = r[i + 1].y - r[i].y;
      const double t =
          std::clamp(((x - r[i].x) * ex + (y - r[i].y) * ey) / (ex * ex + ey * ey), 0.0, 1.0);
      best = std::min(best, std::hypot(r[i].x + t * ex - x, r[i].y + t * ey - y));
    }
    return best;
  }
  double distance(double x, double y) const {
    return std::min({distance(exterior, x, y), distance(hole, x, y), distance(island, x, y)});
  }
  void write(const std::string& path) const {
    GDALAllRegister();
    GDALDriver* drv = GetGDALDriverManager()->GetDriverByName("GPKG");
    std::unique_ptr<GDALDataset> ds(drv->Create(path.c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    ASSERT_TRUE(ds);
    OGRSpatialReference srs;
    srs.importFromEPSG(32632);
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    OGRLayer* layer = ds->CreateLayer("shapes", &srs, wkbPolygon, nullptr);
    ASSERT_NE(layer, nullptr);
    auto ring_of = [](const prep::Ring& r) {
      auto* lr = new OGRLinearRing;
      for (const auto& p : r) lr->addPoint(p.x, p.y);
      return lr;
    };
    for (int k = 0; k < 2; ++k) {
      OGRPolygon poly;
      poly.addRingDirectly(ring_of(k == 0 ? exterior : island));
      if (k == 0) poly.addRingDirectly(ring_of(hole));
      OGRFeature f(layer->GetLayerDefn());
      f.SetGeometry(&poly);
      ASSERT_EQ(layer->CreateFeature(&f), OGRERR_NONE);
    }
  }
  // Writes the scene to DIR/NAME.gpkg and builds it (one red polygon layer,
  // a 1 km extent around the centre, no simplification, plus `options`) into
  // `out`; the tool's result.
  prep::test::ToolRun build(const fs::path& dir, const std::string& name, const std::string& out,
                            const std::string& options) const {
    const std::string gpkg = (dir / (name + ".gpkg")).string();
    fs::remove(gpkg);
    write(gpkg);
    char ext[200];
    std::snprintf(ext, sizeof ext, "%.3f,%.3f,%.3f,%.3f", cx - 500, cy - 500, cx + 500, cy + 500);
    return run_tool("build " + gpkg + " --kind polygon --color '#d04020' --crs EPSG:32632 " +
                    "--extent " + ext + " --resolution 0 " + options + " -o " + out + " -q");
  }
  // The scene built into the package dir/NAME.decals; "" (a test failure
  // naming the build's exit code and output) when the build fails.
  std::string package(const fs::path& dir, const std::string& name,
                      const std::string& options) const {
    const std::string pkg = (dir / (name + ".decals")).string();
    const prep::test::ToolRun b = build(dir, name, pkg, options);
    if (b.rc == 0) return pkg;
    ADD_FAILURE() << name << ": build exit " << b.rc << "\n" << b.output;
    return "";
  }
  // A top-down view of n x n pixels over [-half, half]² around the centre,
  // absolute coordinates.
  std::string view(double half, uint32_t n) const {
    char v[300];
    std::snprintf(v, sizeof v, "--extent %.3f,%.3f,%.3f,%.3f --size %ux%u", cx - half, cy - half,
                  cx + half, cy + half, n, n);
    return v;
  }
  // The centre of pixel (i, j) of that view.
  std::array<double, 2> pixel_centre(double half, uint32_t n, uint32_t i, uint32_t j) const {
    const double px = 2 * half / n;
    return {cx - half + (i + 0.5) * px, cy + half - (j + 0.5) * px};
  }
};

TEST(RenderMethods, VolumeDrawsAGeneratedPolygonWithAHoleAndAnIslandInsideTheHole) {
  const HoleScene s;
  const fs::path d = out_dir("methods");
  const std::string pkg = s.package(d, "hole_island", "--leaf-capacity 8");
  ASSERT_FALSE(pkg.empty());
  // Top-down over [-460, 460]² around the centre.
  constexpr uint32_t n = 320;
  const double half = 460, px = 2 * half / n;
  const std::string view = s.view(half, n);
  std::vector<float> vol, cpu;
  std::string why;
  if (!render_layer(pkg + " " + view + " --method volume", d / "hole_island_volume.rgba", vol, why))
    GTEST_SKIP() << why;
  ASSERT_TRUE(render_layer(pkg + " " + view + " --cpu", d / "hole_island_cpu.rgba", cpu, why));
  ASSERT_EQ(vol.size(), size_t(n) * n * 4);
  // Analytic: pixel centres farther than one pixel from every ring.
  size_t considered = 0, wrong = 0, inside = 0, in_hole = 0, on_island = 0;
  for (uint32_t j = 0; j < n; ++j)
    for (uint32_t i = 0; i < n; ++i) {
      const auto [x, y] = s.pixel_centre(half, n, i, j);
      if (s.distance(x, y) < px) continue;
      ++considered;
      const bool want = s.inside(x, y);
      const bool got = vol[(size_t(j) * n + i) * 4 + 3] > 0.5f;
      wrong += want != got;
      inside += want;
      in_hole += HoleScene::in_ring(s.hole, x, y) && !HoleScene::in_ring(s.island, x, y);
      on_island += HoleScene::in_ring(s.island, x, y);
    }
  std::printf("hole and island: %zu of %zu pixels wrong against the rings (%zu inside)\n", wrong,
              considered, inside);
  EXPECT_GT(in_hole, 1000u);
  EXPECT_GT(on_island, 500u);
  EXPECT_EQ(wrong, 0u);
  const BandComparison c = compare_outside_band(vol, cpu, n, n);
  EXPECT_LT(c.ratio(), 1e-3) << c.mismatched << " of " << c.considered;
}

// The same scene as a tileset of 300 m tiles: each tile's prisms are cut to
// its square, so the hole and the island, split over several tiles, still
// come out exactly.
TEST(RenderMethods, VolumeDrawsTheHoleAndIslandFromATilesetCutAtTheTileSquares) {
  const HoleScene s;
  const fs::path d = out_dir("methods");
  const std::string dir = (d / "hole_island_tiles").string();
  fs::remove_all(dir);
  auto b = s.build(d, "hole_island_tiles", dir, "--tile-size 300");
  ASSERT_EQ(b.rc, 0) << b.output;
  constexpr uint32_t n = 240;
  const double half = 460, px = 2 * half / n;
  const std::string view = s.view(half, n);
  std::vector<float> vol;
  std::string why, out;
  if (!render_layer(dir + " " + view + " --method volume", d / "hole_island_tiles.rgba", vol, why,
                    &out))
    GTEST_SKIP() << why;
  ASSERT_EQ(vol.size(), size_t(n) * n * 4);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m, std::regex(R"((\d+) of \d+ tiles meet the view)"))) << out;
  EXPECT_GE(std::stoi(m[1].str()), 9) << out;
  size_t considered = 0, wrong = 0;
  for (uint32_t j = 0; j < n; ++j)
    for (uint32_t i = 0; i < n; ++i) {
      const auto [x, y] = s.pixel_centre(half, n, i, j);
      if (s.distance(x, y) < px) continue;
      ++considered;
      wrong += s.inside(x, y) != (vol[(size_t(j) * n + i) * 4 + 3] > 0.5f);
    }
  std::printf("tileset hole and island: %zu of %zu pixels wrong against the rings\n", wrong,
              considered);
  EXPECT_GT(considered, size_t(n) * n / 2);
  EXPECT_EQ(wrong, 0u);
}

// The camera 0.3 m above the ground inside the polygon's prism (flat terrain:
// prisms from -0.5 to 0.5 m), looking along the ground towards the hole and
// the island: z-pass would count from inside a volume and invert the
// coverage, so the group must be counted z-fail (Schneider & Klein §4.2.1).
TEST(RenderMethods, VolumeWithTheCameraInsideAPrismCountsZFailAndMatchesCpuEvaluator) {
  const HoleScene s;
  const fs::path d = out_dir("methods");
  const std::string pkg = s.package(d, "hole_island_zfail", "");
  ASSERT_FALSE(pkg.empty());
  decal::Package package;
  ASSERT_TRUE(decal::Package::open(pkg, package));
  const auto meta = nlohmann::json::parse(package.metadata_json());
  const double ex = s.cx - meta.at("origin").at("x").get<double>();
  const double ey = s.cy - meta.at("origin").at("y").get<double>();
  char view[300];
  std::snprintf(view, sizeof view,
                "--flat --eye %.3f,%.3f,0.3 --target %.3f,%.3f,-4 --fov 60 --size 320x180", ex,
                ey - 300, ex, ey - 250);
  BandComparison c;
  std::string why, stats;
  if (!volume_against_cpu(pkg, view, "zfail_volume", 320, 180, c, why, " --stats", &stats))
    GTEST_SKIP() << why;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(stats, m, std::regex(R"(\((\d+) z-fail)"))) << stats;
  EXPECT_GE(std::stoi(m[1].str()), 1) << stats;
  std::printf("volume, camera inside: %zu of %zu pixels differ outside the band, %zu covered\n",
              c.mismatched, c.considered, c.covered);
  EXPECT_GT(c.covered, 320u * 180u / 8);
  EXPECT_LT(c.ratio(), 1e-3);
}

// Misclassified pixels: decal alpha off the oracle's by more than half.
double misclassified(const std::vector<float>& drawn, const std::vector<float>& oracle) {
  size_t wrong = 0;
  for (size_t k = 3; k < drawn.size() && k < oracle.size(); k += 4)
    wrong += std::abs(drawn[k] - oracle[k]) > 0.5f;
  return oracle.empty() ? 1.0 : 4.0 * double(wrong) / double(oracle.size());
}

TEST(RenderMethods, TextureErrorAgainstCpuEvaluatorFallsAsTextureResolutionRises) {
  std::string why;
  const std::string pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  const fs::path d = out_dir("methods");
  // 1600 m over 480 pixels: 3.3 m per pixel; textures coarser than that.
  const std::string view = "--dem " + kDem + " " + topdown_extent(pkg, kTopDown) + " --size " +
                           std::to_string(kW) + "x" + std::to_string(kH) + " --only polygons,lines";
  std::vector<float> cpu;
  ASSERT_TRUE(render_layer(pkg + " " + view + " --cpu", d / "monaco_texture_cpu.rgba", cpu, why));
  std::vector<double> errors;
  std::vector<uint64_t> bytes;
  for (const char* res : {"24", "12", "4"}) {
    std::vector<float> tex;
    std::string stats;
    if (!render_layer(
            pkg + " " + view + " --method texture --texture-resolution " + res + " --stats",
            d / (std::string("monaco_texture_") + res + ".rgba"), tex, why, &stats))
      GTEST_SKIP() << why;
    errors.push_back(misclassified(tex, cpu));
    std::smatch m;
    const std::regex bytes_re(R"(texture: \d+x\d+ texels at [0-9.]+ m, (\d+) bytes)");
    ASSERT_TRUE(std::regex_search(stats, m, bytes_re)) << stats;
    bytes.push_back(std::stoull(m[1].str()));
    std::printf("texture %s m: %.5f of the pixels misclassified, %llu texture bytes\n", res,
                errors.back(), static_cast<unsigned long long>(bytes.back()));
  }
  EXPECT_GT(errors[0], errors[1]);
  EXPECT_GT(errors[1], errors[2]);
  EXPECT_LT(errors[2], 0.1);
  EXPECT_LT(bytes[0], bytes[1]);
  EXPECT_LT(bytes[1], bytes[2]);
}

// Dynamic (pixel-width) lines are drawn by the decal method's dynamic pass
// whatever --method draws the static decals: the same vertices kept, the
// same segments and the same per-pixel list nodes as with --method decal.
TEST(RenderMethods, DynamicLinesAreDrawnTheSameWithEveryMethod) {
  std::string why;
  const std::string pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  const fs::path d = out_dir("methods");
  std::map<std::string, std::string> figures;
  for (const char* method : {"decal", "volume", "texture"}) {
    const auto r =
        run_tool("render " + pkg + " --dem " + kDem + " --size 320x180 --stats --method " + method +
                 " -o " + (d / (std::string("dynamic_") + method + ".png")).string());
    if (r.rc == 8) GTEST_SKIP() << "no headless GL: " << r.output;
    ASSERT_EQ(r.rc, 0) << r.output;
    std::smatch m;
    const std::regex dyn_re(
        R"(dynamic lines: (\d+) vertices kept, (\d+) segments drawn, (\d+) list nodes)");
    ASSERT_TRUE(std::regex_search(r.output, m, dyn_re)) << method << "\n" << r.output;
    figures[method] = m[1].str() + " kept, " + m[2].str() + " segments, " + m[3].str() + " nodes";
    if (std::string(method) == "decal") {
      EXPECT_GT(std::stoul(m[2].str()), 10u) << r.output;
    }
  }
  std::printf("dynamic lines: decal %s; volume %s; texture %s\n", figures["decal"].c_str(),
              figures["volume"].c_str(), figures["texture"].c_str());
  EXPECT_EQ(figures["volume"], figures["decal"]);
  EXPECT_EQ(figures["texture"], figures["decal"]);
}

TEST(RenderMethods, CpuWithAnotherMethodIsAUsageError) {
  std::string why;
  const std::string pkg = monaco_package(&why);
  if (pkg.empty()) GTEST_SKIP() << why;
  const auto r = run_tool("render " + pkg + " --cpu --method volume -o " +
                          (out_dir("methods") / "never.png").string());
  EXPECT_EQ(r.rc, 2) << r.output;
  EXPECT_NE(r.output.find("--cpu is the decal evaluator"), std::string::npos) << r.output;
}

}  // namespace

}  // namespace render_methods
