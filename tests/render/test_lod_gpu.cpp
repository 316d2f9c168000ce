// LOCALIS LOD chosen on the GPU (formats/gl/shaders/lod_select.comp.glsl,
// render --lod on) on Liechtenstein's roads built as dynamic lines with
// `lod = true`, at near, middle and far zoom, top-down and in perspective:
// - the segments the GPU selects (the compacted indices read back) are the
//   ones decal::visible_segments selects for the same camera and threshold
//   (prep::render::lod_view), exactly;
// - per line they form one polyline from its first to its last point
//   (tests/model/lod/lod_chain.hpp), which for a constant threshold and a
//   LOD set without dependees is the Douglas-Peucker result at that
//   threshold, point for point, against a recursive DP written here
//   (LOCALIS §3.1-3.2); with the package's dependees, the DP result at the
//   line's largest threshold or finer;
// - no two lines cross where their full-detail lines do not (GEOS);
// - the GL image with LOD agrees with the CPU path (render --cpu), which
//   draws the same selection.
// The data lives in the shared data folder only; the tests skip, naming the
// path, when it is missing.
#include <geos_c.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

#include "decal/reader.hpp"
#include "dp_oracle.hpp"
#include "lod/lod.hpp"
#include "lod_chain.hpp"
#include "prep/error.hpp"
#include "prep/evaluate.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_lod_gpu {

namespace fs = std::filesystem;
namespace R = prep::render;

namespace {

using lodtest::Pt;
using prep::ivec2;

// ---- oracle: plain recursive Douglas-Peucker (dp_oracle.hpp) ----
using lodtest::oracle_dp;

template <class T>
std::vector<T> blob(const R::DecalSource& s, decal::BlobId id) {
  for (const auto& b : s.blobs)
    if (b.id == id) {
      std::vector<T> v(b.bytes / sizeof(T));
      std::memcpy(v.data(), b.data, v.size() * sizeof(T));
      return v;
    }
  return {};
}

// The package's LOD set, with each line's points (first, count).
prep::LodSet package_set(const R::DecalSource& src) {
  prep::LodSet s;
  s.points = blob<decal::LodPoint>(src, decal::BlobId::lod_points);
  s.segments = blob<decal::LodSegment>(src, decal::BlobId::lod_segments);
  s.line_range = blob<prep::uvec2>(src, decal::BlobId::lod_line_range);
  for (const auto& r : s.line_range) {
    uint32_t first = UINT32_MAX, last = 0;
    for (uint32_t k = r[0]; k < r[0] + r[1]; ++k) {
      first = std::min(first, s.segments[k].a);
      last = std::max(last, s.segments[k].b);
    }
    s.line_points.push_back({first, last - first + 1});
  }
  return s;
}

std::vector<ivec2> line_points(const prep::LodSet& s, size_t line) {
  std::vector<ivec2> pts;
  const auto lp = s.line_points[line];
  for (uint32_t p = lp[0]; p < lp[0] + lp[1]; ++p) pts.push_back({s.points[p].x, s.points[p].y});
  return pts;
}

// The same lines' LOD set without dependees (prep::build_lod), whose
// selection at a constant threshold is exactly Douglas-Peucker (formats/SPEC.md).
prep::LodSet without_dependees(const prep::LodSet& pkg) {
  std::vector<prep::LodInputLine> in;
  for (size_t i = 0; i < pkg.line_points.size(); ++i) {
    prep::LodInputLine l;
    l.points = line_points(pkg, i);
    l.line = pkg.points[pkg.line_points[i][0]].line;
    // A closed ring repeats its first point; build_lod repeats it again.
    if (l.points.size() > 3 && l.points.front() == l.points.back()) {
      l.points.pop_back();
      l.closed = true;
    }
    in.push_back(std::move(l));
  }
  prep::LodOptions opt;
  opt.dependees = false;
  return prep::build_lod(in, opt);
}

// `src` with its LOD blobs replaced by `set`'s (which must outlive it).
R::DecalSource with_lod(const R::DecalSource& src, const prep::LodSet& set) {
  R::DecalSource out = src;
  out.validated = false;
  for (auto& b : out.blobs) {
    if (b.id == decal::BlobId::lod_points)
      b = {b.id, set.points.size(), set.points.data(), set.points.size() * sizeof(decal::LodPoint)};
    else if (b.id == decal::BlobId::lod_segments)
      b = {b.id, set.segments.size(), set.segments.data(),
           set.segments.size() * sizeof(decal::LodSegment)};
    else if (b.id == decal::BlobId::lod_line_range)
      b = {b.id, set.line_range.size(), set.line_range.data(),
           set.line_range.size() * sizeof(prep::uvec2)};
  }
  return out;
}

std::string roads_package(std::string& why) {
  const std::string data =
      prep::test::shared_data("liechtenstein/liechtenstein-2013-08-03.osm.pbf");
  if (!fs::exists(data)) {
    why = "Liechtenstein data missing: " + data;
    return "";
  }
  const fs::path dir = render_test::process_dir("lod_gpu");
  const fs::path toml = dir / "roads.toml";
  std::FILE* f = std::fopen(toml.c_str(), "w");
  if (!f) {
    why = "cannot write " + toml.string();
    return "";
  }
  std::fprintf(f,
               "source = \"%s\"\nextent = [9.47, 47.04, 9.64, 47.27]\nextent_crs = \"EPSG:4326\"\n"
               "resolution = 0\n[[layer]]\nname = \"roads\"\nlayer = \"lines\"\n"
               "where = \"highway IS NOT NULL\"\nkind = \"line\"\ndynamic = true\nlod = true\n"
               "width = 3\ncolor = \"#c03020d0\"\n",
               data.c_str());
  std::fclose(f);
  const std::string pkg = (dir / "roads.decals").string();
  const auto r = prep::test::run_tool("build " + toml.string() + " -o " + pkg + " -q");
  if (r.rc != 0) {
    why = "build failed: " + r.output;
    return "";
  }
  return pkg;
}

R::Camera look(const R::Vec3& eye, const R::Vec3& target, double fov) {
  R::Camera c;
  c.eye = eye;
  c.target = target;
  c.fov_y_deg = fov;
  const double dist = std::hypot(eye[0] - target[0], eye[1] - target[1], eye[2] - target[2]);
  c.near = std::max(0.1, dist * 1e-3);
  c.depth_range = 4 * dist;
  return c;
}

R::Camera topdown(double cx, double cy, double height_m, uint32_t W, uint32_t H) {
  const double w = height_m * W / H;
  return R::topdown_camera({cx - w / 2, cy - height_m / 2, cx + w / 2, cy + height_m / 2}, 0, 0);
}

GEOSGeometry* linestring(GEOSContextHandle_t ctx, const std::vector<ivec2>& pts) {
  GEOSCoordSequence* seq = GEOSCoordSeq_create_r(ctx, static_cast<unsigned>(pts.size()), 2);
  for (unsigned i = 0; i < pts.size(); ++i) {
    GEOSCoordSeq_setX_r(ctx, seq, i, pts[i][0] * 1e-3);
    GEOSCoordSeq_setY_r(ctx, seq, i, pts[i][1] * 1e-3);
  }
  return GEOSGeom_createLineString_r(ctx, seq);
}

class LodGpu : public ::testing::Test {
 protected:
  static constexpr uint32_t W = 480, H = 270;

  void SetUp() override {
    std::string why;
    path_ = roads_package(why);
    if (path_.empty() && why.rfind("Liechtenstein data missing", 0) == 0) GTEST_SKIP() << why;
    ASSERT_FALSE(path_.empty()) << why;
    ASSERT_TRUE(decal::Package::open(path_, pkg_));
    src_ = R::source_of(pkg_);
    terrain_ = R::flat_heightfield(src_.extent);
    set_ = package_set(src_);
    ASSERT_GT(set_.line_points.size(), 1000u);
    ctx_ = GEOS_init_r();
  }
  void TearDown() override {
    if (ctx_) GEOS_finish_r(ctx_);
  }
  static void TearDownTestSuite() {
    render_test::remove_process_dir(render_test::process_dir("lod_gpu"));
  }

  // The GPU's selection (sorted), or nullopt without headless GL.
  std::optional<std::vector<uint32_t>> gpu_selection(const R::DecalSource& src,
                                                     const R::Camera& cam, double tolerance_px) {
    R::RenderOptions opt;
    opt.width = W;
    opt.height = H;
    opt.camera = cam;
    opt.draw_polygons = opt.draw_lines = false;
    opt.lod_tolerance_px = tolerance_px;
    opt.lod_read_selection = true;
    R::Image img;
    try {
      img = R::render_gl(src, terrain_, opt);
    } catch (const prep::render_error& e) {
      std::printf("no headless GL: %s\n", e.what());
      return std::nullopt;
    }
    EXPECT_EQ(img.lod_selected, img.lod_selection.size());
    EXPECT_EQ(img.lod_lines, set_.line_points.size()) << "every LOD line drawn from its segments";
    std::sort(img.lod_selection.begin(), img.lod_selection.end());
    return img.lod_selection;
  }

  std::vector<uint32_t> cpu_selection(const prep::LodSet& set, const R::Camera& cam,
                                      double tolerance_px) const {
    const R::LodView v = R::lod_view(cam, H, terrain_.zmin, terrain_.zmax, tolerance_px);
    return decal::visible_segments(set.points, set.segments, decal::LodCamera{v.cx, v.cy, v.cz},
                                   decal::LinearThreshold{v.base, v.slope});
  }

  // Pairs of lines whose full-detail lines do not meet but whose boxes do.
  void find_disjoint_pairs() {
    std::vector<GEOSGeometry*> g;
    struct Box {
      int64_t x0, y0, x1, y1;
    };
    std::vector<Box> box;
    for (size_t i = 0; i < set_.line_points.size(); ++i) {
      const auto pts = line_points(set_, i);
      g.push_back(linestring(ctx_, pts));
      Box b{pts[0][0], pts[0][1], pts[0][0], pts[0][1]};
      for (const auto& p : pts)
        b = {std::min<int64_t>(b.x0, p[0]), std::min<int64_t>(b.y0, p[1]),
             std::max<int64_t>(b.x1, p[0]), std::max<int64_t>(b.y1, p[1])};
      box.push_back(b);
    }
    for (uint32_t i = 0; i < g.size(); ++i)
      for (uint32_t j = i + 1; j < g.size(); ++j) {
        if (box[i].x1 < box[j].x0 || box[j].x1 < box[i].x0 || box[i].y1 < box[j].y0 ||
            box[j].y1 < box[i].y0)
          continue;
        if (GEOSIntersects_r(ctx_, g[i], g[j]) == 0) disjoint_.emplace_back(i, j);
      }
    for (auto* x : g) GEOSGeom_destroy_r(ctx_, x);
  }

  // Lines of `chains` that meet where their full-detail lines do not.
  size_t new_crossings(const std::vector<std::vector<ivec2>>& chains) const {
    std::vector<GEOSGeometry*> g;
    for (const auto& c : chains) g.push_back(linestring(ctx_, c));
    size_t bad = 0;
    for (const auto& [i, j] : disjoint_) bad += GEOSIntersects_r(ctx_, g[i], g[j]) == 1;
    for (auto* x : g) GEOSGeom_destroy_r(ctx_, x);
    return bad;
  }

  std::string path_;
  decal::Package pkg_;
  R::DecalSource src_;
  R::Heightfield terrain_;
  prep::LodSet set_;
  GEOSContextHandle_t ctx_ = nullptr;
  std::vector<std::pair<uint32_t, uint32_t>> disjoint_;
};

std::vector<Pt> metres(const std::vector<ivec2>& q) {
  std::vector<Pt> p;
  for (const auto& v : q) p.push_back({v[0] * 1e-3, v[1] * 1e-3});
  return p;
}

// Top-down views (a constant threshold: tolerance times the pixel's ground
// size) of the lines' LOD set without dependees: the GPU's selection is
// decal::visible_segments' and, per line, exactly the Douglas-Peucker result.
TEST_F(LodGpu, TopDownSelectionIsTheCpuSelectionAndExactlyDouglasPeucker) {
  const prep::LodSet plain = without_dependees(set_);
  ASSERT_EQ(plain.points.size(), set_.points.size());
  for (size_t p = 0; p < plain.points.size(); ++p)
    ASSERT_TRUE(plain.points[p].x == set_.points[p].x && plain.points[p].y == set_.points[p].y &&
                plain.points[p].line == set_.points[p].line)
        << "point " << p;
  const R::DecalSource src = with_lod(src_, plain);
  // Every distance DP compares with a threshold, to keep thresholds clear of
  // them (the LOD set stores errors as floats).
  std::vector<std::vector<Pt>> lines;
  std::vector<double> seen;
  for (size_t i = 0; i < plain.line_points.size(); ++i) {
    lines.push_back(metres(line_points(plain, i)));
    std::vector<bool> all(lines.back().size());
    oracle_dp(lines.back(), 0, lines.back().size() - 1, -1.0, all, &seen);
  }
  std::sort(seen.begin(), seen.end());
  auto clear = [&](double eps) {
    const auto it = std::lower_bound(seen.begin(), seen.end(), eps * (1 - 1e-5));
    return it == seen.end() || *it > eps * (1 + 1e-5);
  };
  struct View {
    const char* name;
    double height_m;
  } views[] = {{"near", 150}, {"middle", 2500}, {"far", 30000}};
  for (const View& v : views) {
    const R::Camera cam = topdown(0, 0, v.height_m, W, H);
    double tolerance = 0.5;
    for (int k = 1; !clear(tolerance * v.height_m / H) && k < 1000; ++k) {
      const int step = (k + 1) / 2;  // 1, 1, 2, 2, ...: alternately above and below 0.5
      tolerance = 0.5 * (1 + (k % 2 ? 1 : -1) * 1e-4 * step);
    }
    const double eps = tolerance * v.height_m / H;
    ASSERT_TRUE(clear(eps)) << v.name;
    const auto gpu = gpu_selection(src, cam, tolerance);
    if (!gpu) GTEST_SKIP() << "no headless GL";
    const auto cpu = cpu_selection(plain, cam, tolerance);
    EXPECT_EQ(*gpu, cpu) << v.name << ": GPU and CPU selections differ";
    size_t simplified = 0, kept = 0, total = 0;
    for (uint32_t i = 0; i < lines.size(); ++i) {
      std::vector<bool> keep(lines[i].size(), false);
      keep.front() = keep.back() = true;
      oracle_dp(lines[i], 0, lines[i].size() - 1, eps, keep, nullptr);
      std::vector<uint32_t> expected;
      for (uint32_t k = 0; k < keep.size(); ++k)
        if (keep[k]) expected.push_back(plain.line_points[i][0] + k);
      std::string why;
      const auto chain = lodtest::visible_chain(plain, i, *gpu, &why);
      ASSERT_TRUE(chain) << v.name << " line " << i << ": " << why;
      ASSERT_EQ(*chain, expected) << v.name << " line " << i << " eps " << eps;
      simplified += expected.size() < lines[i].size();
      kept += expected.size() - 1;
      total += lines[i].size() - 1;
    }
    std::printf("%s: eps %.4f m, %zu of %zu segments (%zu lines simplified)\n", v.name, eps, kept,
                total, simplified);
    if (std::string(v.name) == "far") {
      EXPECT_LT(kept, total / 2) << "far view hardly simplified";
    }
  }
}

// The package's own LOD set (with dependees) in perspective and top-down:
// the GPU's selection is decal::visible_segments', each line one polyline,
// the DP result at its largest threshold or finer, and no new crossings.
TEST_F(LodGpu, PerspectiveSelectionIsTheCpuSelectionConnectedAndNeverCrosses) {
  find_disjoint_pairs();
  ASSERT_GT(disjoint_.size(), 100u);
  struct View {
    const char* name;
    R::Camera cam;
  };
  const View views[] = {
      {"near", look({-150, -500, 250}, {0, 0, 0}, 40)},
      {"middle", look({500, -5000, 3000}, {0, 0, 0}, 40)},
      {"far", look({0, -26000, 16000}, {0, 0, 0}, 40)},
      {"far top-down", topdown(0, 0, 30000, W, H)},
  };
  const double tolerance = 0.5;
  for (const View& v : views) {
    const auto gpu = gpu_selection(src_, v.cam, tolerance);
    if (!gpu) GTEST_SKIP() << "no headless GL";
    const auto cpu = cpu_selection(set_, v.cam, tolerance);
    EXPECT_EQ(*gpu, cpu) << v.name << ": GPU and CPU selections differ";
    const R::LodView lv = R::lod_view(v.cam, H, terrain_.zmin, terrain_.zmax, tolerance);
    std::vector<std::vector<ivec2>> chains;
    size_t kept = 0, total = 0, coarser = 0;
    for (uint32_t i = 0; i < set_.line_points.size(); ++i) {
      std::string why;
      const auto chain = lodtest::visible_chain(set_, i, *gpu, &why);
      ASSERT_TRUE(chain) << v.name << " line " << i << ": " << why;
      std::vector<ivec2> pts;
      for (uint32_t p : *chain) pts.push_back({set_.points[p].x, set_.points[p].y});
      chains.push_back(pts);
      kept += pts.size() - 1;
      total += set_.line_points[i][1] - 1;
      // The line's largest threshold: eps at its farthest point.
      double dmax = 0;
      for (uint32_t p = set_.line_points[i][0]; p < set_.line_points[i][0] + set_.line_points[i][1];
           ++p)
        dmax = std::max(dmax, decal::lod_distance(set_.points[p], {lv.cx, lv.cy, lv.cz}));
      const double eps_hi = decal::LinearThreshold{lv.base, lv.slope}(dmax) * (1 + 1e-5);
      const auto full = metres(line_points(set_, i));
      std::vector<bool> keep(full.size(), false);
      keep.front() = keep.back() = true;
      oracle_dp(full, 0, full.size() - 1, eps_hi, keep, nullptr);
      for (uint32_t k = 0; k < keep.size(); ++k)
        if (keep[k] &&
            !std::binary_search(chain->begin(), chain->end(), set_.line_points[i][0] + k))
          ++coarser;
    }
    EXPECT_EQ(coarser, 0u) << v.name << ": points DP keeps at the line's largest threshold missing";
    const size_t bad = new_crossings(chains);
    EXPECT_EQ(bad, 0u) << v.name << ": line pairs that cross only when simplified";
    std::printf("%s: %zu of %zu segments selected, %zu disjoint pairs checked\n", v.name, kept,
                total, disjoint_.size());
    if (std::string(v.name).rfind("far", 0) == 0) {
      EXPECT_LT(kept, total * 6 / 10) << v.name << ": hardly simplified";
    }
  }
}

// With LOD on, the GL image (dynamic layer) agrees with render --cpu's,
// which draws decal::visible_segments' selection, and the counts match.
TEST_F(LodGpu, LodOnImageAgreesWithTheCpuPath) {
  const fs::path out = render_test::process_dir("lod_gpu");
  R::RenderOptions opt;
  opt.width = W;
  opt.height = H;
  opt.camera = look({500, -5000, 3000}, {0, 0, 0}, 40);
  opt.draw_polygons = opt.draw_lines = false;
  R::Image gl;
  try {
    gl = R::render_gl(src_, terrain_, opt);
  } catch (const prep::render_error& e) {
    GTEST_SKIP() << "no headless GL: " << e.what();
  }
  const R::Image cpu = R::render_cpu(src_, terrain_, opt);
  prep::write_png_rgba((out / "middle_gl.png").string(), gl.width, gl.height, gl.rgba);
  prep::write_png_rgba((out / "middle_cpu.png").string(), cpu.width, cpu.height, cpu.rgba);
  EXPECT_GT(gl.lod_lines, 0u);
  EXPECT_EQ(gl.lod_lines, cpu.lod_lines);
  EXPECT_EQ(gl.lod_selected, cpu.lod_selected);
  EXPECT_EQ(gl.lod_drawn, cpu.lod_drawn);
  EXPECT_LT(gl.lod_drawn, gl.lod_full);
  ASSERT_EQ(gl.dynamic.size(), cpu.dynamic.size());
  size_t agree = 0, covered = 0;
  const size_t pixels = size_t(W) * H;
  for (size_t k = 0; k < pixels; ++k) {
    const float* g = &gl.dynamic[4 * k];
    const float* p = &cpu.dynamic[4 * k];
    bool same = std::abs(g[3] - p[3]) <= 2.0f / 255;
    if (same && (g[3] > 0 || p[3] > 0))
      for (int ch = 0; ch < 3; ++ch) same = same && std::abs(g[ch] - p[ch]) <= 2.0f / 255;
    agree += same;
    covered += p[3] > 0;
  }
  std::printf("LOD on: %zu of %zu pixels agree, %zu covered; %llu of %llu segments drawn\n", agree,
              pixels, covered, static_cast<unsigned long long>(gl.lod_drawn),
              static_cast<unsigned long long>(gl.lod_full));
  EXPECT_GT(covered, pixels / 100);
  EXPECT_GE(double(agree) / double(pixels), 0.999);
  // Off: every line from its vertex chain, no LOD counts.
  opt.lod = false;
  const R::Image off = R::render_gl(src_, terrain_, opt);
  EXPECT_EQ(off.lod_lines, 0u);
  EXPECT_GT(off.dyn_segments, gl.dyn_segments);
}

}  // namespace

}  // namespace render_lod_gpu
