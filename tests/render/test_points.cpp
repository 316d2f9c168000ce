// Points (scene kind = "point", formats/SPEC.md "Points"): the amenity
// nodes of Monaco's OpenStreetMap extract as round dots, static (metres)
// and dynamic (pixels), drawn top-down:
//  - GL agrees with the CPU evaluator (static) and dynamic_cpu (dynamic) on
//    at least 99.9% of the pixels either draws;
//  - the pixel holding each node (placed from its lon/lat by OGR, not by
//    decalprep) shows the dot's colour, in GL and on the CPU.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"
#include "wgs84_frame.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_points {

namespace fs = std::filesystem;
namespace R = prep::render;
using prep::test::run_tool;

namespace {

const std::string kPbf = std::string(DECALPREP_SOURCE_DIR) + "/samples/monaco/monaco.osm.pbf";
const std::string kWhere = "other_tags LIKE '%\"amenity\"%'";
constexpr float kStatic[3] = {0xc0 / 255.f, 0x39 / 255.f, 0x2b / 255.f};
constexpr float kDynamic[3] = {0x1f / 255.f, 0x4e / 255.f, 0xc8 / 255.f};

// The amenity nodes in the frame, relative to its origin.
std::vector<std::array<double, 2>> nodes(const prep::SceneFrame& frame) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(kPbf.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (!ds) throw std::runtime_error("cannot open " + kPbf);
  const std::unique_ptr<OGRCoordinateTransformation> ct = render_test::wgs84_to_frame(frame);
  OGRLayer* layer = ds->GetLayerByName("points");
  layer->SetAttributeFilter(kWhere.c_str());
  std::vector<std::array<double, 2>> out;
  while (OGRFeature* f = layer->GetNextFeature()) {
    const OGRGeometry* g = f->GetGeometryRef();
    if (g && wkbFlatten(g->getGeometryType()) == wkbPoint) {
      double x = g->toPoint()->getX(), y = g->toPoint()->getY();
      if (ct->Transform(1, &x, &y)) out.push_back({x - frame.origin_x, y - frame.origin_y});
    }
    OGRFeature::DestroyFeature(f);
  }
  return out;
}

bool is(const float* px, const float* rgb) {
  if (px[3] < 0.99f) return false;
  for (int c = 0; c < 3; ++c)
    if (std::abs(px[c] - rgb[c]) > 2.f / 255.f) return false;
  return true;
}

}  // namespace

TEST(Points, MonacoAmenitiesAreDotsGlAgreesWithCpuAndEveryNodeShowsItsColour) {
  const fs::path dir = fs::current_path() / "render-out" / "points";
  fs::create_directories(dir);
  std::ofstream(dir / "scene.toml")
      << "source = \"" << kPbf << "\"\n"
      << "extent = [7.400, 43.722, 7.445, 43.755]\nextent_crs = \"EPSG:4326\"\n\n"
      << "[[layer]]\nname = \"dots\"\nlayer = \"points\"\nwhere = \""
      << "other_tags LIKE '%\\\"amenity\\\"%'"
      << "\"\nkind = \"point\"\nwidth = 6\ncolor = \"#c0392b\"\n\n"
      << "[[layer]]\nname = \"pins\"\nlayer = \"points\"\nwhere = \""
      << "other_tags LIKE '%\\\"amenity\\\"%'"
      << "\"\nkind = \"point\"\ndynamic = true\nwidth = 5\ncolor = \"#1f4ec8\"\n";
  const std::string pkg = (dir / "points.decals").string();
  const auto r = run_tool("build " + (dir / "scene.toml").string() + " -o " + pkg + " -q");
  ASSERT_EQ(r.rc, 0) << r.output;
  decal::Package package;
  ASSERT_TRUE(decal::Package::open(pkg, package));
  const R::DecalSource src = R::source_of(package);
  const auto at = nodes(src.frame);
  ASSERT_GT(at.size(), 200u);

  // Top-down, 960 x 540 pixels of 1 m around the nodes' median.
  std::vector<double> xs, ys;
  for (const auto& p : at) xs.push_back(p[0]), ys.push_back(p[1]);
  std::nth_element(xs.begin(), xs.begin() + long(xs.size() / 2), xs.end());
  std::nth_element(ys.begin(), ys.begin() + long(ys.size() / 2), ys.end());
  const double cx = std::round(xs[xs.size() / 2]), cy = std::round(ys[ys.size() / 2]);
  const prep::Extent e{cx - 480, cy - 270, cx + 480, cy + 270};
  R::RenderOptions opt;
  opt.width = 960, opt.height = 540;
  opt.camera = R::topdown_camera(e, 0, 0);
  const R::Image cpu = R::render_cpu(src, R::flat_heightfield(e), opt);
  std::optional<R::Image> gl;
  try {
    gl = R::render_gl(src, R::flat_heightfield(e), opt);
  } catch (const prep::render_error& err) {
    GTEST_SKIP() << "no headless GL: " << err.what();
  }
  for (bool dynamic : {false, true}) {
    SCOPED_TRACE(dynamic ? "dynamic" : "static");
    const std::vector<float>& a = dynamic ? gl->dynamic : gl->decals;
    const std::vector<float>& b = dynamic ? cpu.dynamic : cpu.decals;
    size_t drawn = 0, agree = 0;
    for (size_t k = 0; k < size_t(opt.width) * opt.height; ++k) {
      if (a[4 * k + 3] == 0 && b[4 * k + 3] == 0) continue;
      ++drawn;
      bool ok = true;
      for (int c = 0; c < 4; ++c) ok = ok && std::abs(a[4 * k + c] - b[4 * k + c]) <= 2.f / 255.f;
      agree += ok;
    }
    size_t centres = 0, gl_right = 0, cpu_right = 0;
    const float* rgb = dynamic ? kDynamic : kStatic;
    for (const auto& p : at) {
      // Nodes a pixel or more inside the view.
      if (p[0] < e.xmin + 1 || p[0] > e.xmax - 1 || p[1] < e.ymin + 1 || p[1] > e.ymax - 1)
        continue;
      const size_t i = size_t(p[0] - e.xmin), j = size_t(e.ymax - p[1]);
      const size_t k = j * opt.width + i;
      ++centres;
      gl_right += is(&a[4 * k], rgb);
      cpu_right += is(&b[4 * k], rgb);
    }
    std::printf(
        "%s dots: %zu pixels drawn, %zu agree (GL, CPU); %zu nodes in view, centre pixel "
        "in the dot colour: GL %zu, CPU %zu\n",
        dynamic ? "dynamic" : "static", drawn, agree, centres, gl_right, cpu_right);
    EXPECT_GT(centres, 50u);
    EXPECT_GE(double(agree), 0.999 * double(drawn));
    EXPECT_EQ(gl_right, centres);
    EXPECT_EQ(cpu_right, centres);
  }
}

}  // namespace render_points
