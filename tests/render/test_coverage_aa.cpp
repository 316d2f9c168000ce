// Coverage anti-aliasing (`render --aa coverage`, formats/SPEC.md
// "Anti-aliasing") on real data: Monaco's buildings (OpenStreetMap,
// samples/monaco), whose terraced rows share edges, drawn top-down in GL in
// the sample's translucent roof colour, against GEOS (through OGR) on the
// source geometry:
//   - every pixel whose whole square the union of the buildings covers
//     shows the fill within 2/255, inside one building and on the edges two
//     buildings share: their coverages add up to the whole pixel
//     (conflation would leave 1/4 of it to the background on the edge).
//     Pixels within 0.75 px of a vertex where buildings meet are counted
//     apart: there the coverage from the distance to the nearest edge is
//     not the area of a corner (at most 0.1 off);
//   - every pixel whose centre lies farther than one pixel from every
//     building shows nothing.
// The pixels on shared edges are counted (covered by the union, by no
// building alone), so the first check cannot pass for want of them; those
// where two buildings overlap (their areas in the pixel sum to more than
// the pixel) rightly show more than the fill and are left out.
#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogr_geometry.h>
#include <ogrsf_frmts.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"
#include "smoke_util.hpp"
#include "wgs84_frame.hpp"

// The render tests share one binary (a unity build): each file keeps its
// names in a namespace of its own.
namespace render_coverage_aa {

namespace fs = std::filesystem;
using prep::test::run_tool;

namespace {

const std::string kPbf = std::string(DECALPREP_SOURCE_DIR) + "/samples/monaco/monaco.osm.pbf";
constexpr float kFill[4] = {0xd9 / 255.f, 0xa4 / 255.f, 0x8a / 255.f, 0xcc / 255.f};

fs::path out_dir() {
  fs::path p = fs::current_path() / "render-out" / "coverage_aa";
  fs::create_directories(p);
  return p;
}

// The buildings of the extract in the package's frame, relative to its
// origin; invalid ones made valid (the pipeline repairs them too).
std::vector<std::unique_ptr<OGRGeometry>> buildings(const prep::SceneFrame& frame) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(kPbf.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (!ds) throw std::runtime_error("cannot open " + kPbf);
  const std::unique_ptr<OGRCoordinateTransformation> ct = render_test::wgs84_to_frame(frame);
  struct Shift : OGRDefaultGeometryVisitor {
    double dx, dy;
    Shift(double x, double y) : dx(x), dy(y) {}
    using OGRDefaultGeometryVisitor::visit;
    void visit(OGRLineString* ls) override {
      for (int i = 0; i < ls->getNumPoints(); ++i)
        ls->setPoint(i, ls->getX(i) - dx, ls->getY(i) - dy);
    }
    void visit(OGRLinearRing* r) override { visit(static_cast<OGRLineString*>(r)); }
  } shift(frame.origin_x, frame.origin_y);
  std::vector<std::unique_ptr<OGRGeometry>> out;
  OGRLayer* layer = ds->GetLayerByName("multipolygons");
  layer->SetAttributeFilter("building IS NOT NULL");
  while (OGRFeature* f = layer->GetNextFeature()) {
    const OGRGeometry* g = f->GetGeometryRef();
    if (g && !g->IsEmpty()) {
      std::unique_ptr<OGRGeometry> p(g->clone());
      if (p->transform(ct.get()) == OGRERR_NONE) {
        p->accept(&shift);
        if (!p->IsValid()) p.reset(p->MakeValid());
        if (p && !p->IsEmpty()) out.push_back(std::move(p));
      }
    }
    OGRFeature::DestroyFeature(f);
  }
  return out;
}

struct PreparedFree {
  void operator()(OGRPreparedGeometry* p) const { OGRDestroyPreparedGeometry(p); }
};
using Prepared = std::unique_ptr<OGRPreparedGeometry, PreparedFree>;

// The distance from (cx, cy) to the nearest vertex of `near`.
double nearest_vertex(const std::vector<const OGRGeometry*>& near, double cx, double cy) {
  struct Nearest : OGRDefaultConstGeometryVisitor {
    double cx = 0, cy = 0, d = 1e300;
    using OGRDefaultConstGeometryVisitor::visit;
    void visit(const OGRLineString* ls) override {
      for (int k = 0; k < ls->getNumPoints(); ++k)
        d = std::min(d, std::hypot(ls->getX(k) - cx, ls->getY(k) - cy));
    }
    void visit(const OGRLinearRing* r) override { visit(static_cast<const OGRLineString*>(r)); }
  } v;
  v.cx = cx, v.cy = cy;
  for (const OGRGeometry* g : near) g->accept(&v);
  return v.d;
}

struct Counts {
  size_t covered = 0, inside = 0, inside_wrong = 0, shared = 0, shared_wrong = 0, overlapped = 0;
  size_t corner = 0;
  double corner_worst = 0;
  size_t empty = 0, empty_wrong = 0;
};

// One top-down window of W x H pixels of `m` metres with its lower left
// corner at (x0, y0), frame metres relative to the origin.
Counts check_window(const prep::render::DecalSource& src,
                    const std::vector<std::unique_ptr<OGRGeometry>>& all, double x0, double y0,
                    double m, uint32_t W, uint32_t H) {
  const prep::Extent e{x0, y0, x0 + m * W, y0 + m * H};
  prep::render::RenderOptions opt;
  opt.width = W, opt.height = H;
  opt.camera = prep::render::topdown_camera(e, 0, 0);
  opt.aa = prep::render::AntiAliasing::coverage;
  opt.draw_lines = opt.draw_dynamic = false;
  const prep::render::Image img =
      prep::render::render_gl(src, prep::render::flat_heightfield(e), opt);

  // The buildings that reach the window grown by two pixels, their union,
  // and the union grown by one pixel.
  OGRPolygon win;
  {
    auto* ring = new OGRLinearRing;
    const double g = 2 * m;
    ring->addPoint(e.xmin - g, e.ymin - g);
    ring->addPoint(e.xmax + g, e.ymin - g);
    ring->addPoint(e.xmax + g, e.ymax + g);
    ring->addPoint(e.xmin - g, e.ymax + g);
    ring->closeRings();
    win.addRingDirectly(ring);
  }
  std::vector<const OGRGeometry*> near;
  OGRMultiPolygon parts;
  for (const auto& b : all) {
    if (!b->Intersects(&win)) continue;
    near.push_back(b.get());
    const OGRwkbGeometryType t = wkbFlatten(b->getGeometryType());
    if (t == wkbPolygon) {
      parts.addGeometry(b.get());
    } else if (t == wkbMultiPolygon) {
      for (const OGRPolygon* p : *b->toMultiPolygon()) parts.addGeometry(p);
    } else if (t == wkbGeometryCollection) {
      for (const OGRGeometry* p : *b->toGeometryCollection())
        if (wkbFlatten(p->getGeometryType()) == wkbPolygon) parts.addGeometry(p);
    }
  }
  const std::unique_ptr<OGRGeometry> uni(parts.UnionCascaded());
  const std::unique_ptr<OGRGeometry> grown(uni->Buffer(m, 16));
  Prepared covers(OGRCreatePreparedGeometry(uni.get()));
  Prepared reach(OGRCreatePreparedGeometry(grown.get()));
  std::vector<Prepared> each;
  std::vector<OGREnvelope> envs(near.size());
  for (size_t k = 0; k < near.size(); ++k) {
    each.emplace_back(
        OGRCreatePreparedGeometry(OGRGeometry::ToHandle(const_cast<OGRGeometry*>(near[k]))));
    near[k]->getEnvelope(&envs[k]);
  }

  Counts c;
  const prep::Extent& clip = src.extent;  // the scene clips to it
  for (uint32_t j = 0; j < H; ++j)
    for (uint32_t i = 0; i < W; ++i) {
      const double x = e.xmin + m * i, y = e.ymax - m * (j + 1);
      if (x < clip.xmin + m || x + m > clip.xmax - m || y < clip.ymin + m || y + m > clip.ymax - m)
        continue;
      const float* px = &img.decals[(size_t(j) * W + i) * 4];
      OGRPoint centre(x + 0.5 * m, y + 0.5 * m);
      if (!OGRPreparedGeometryIntersects(reach.get(), OGRGeometry::ToHandle(&centre))) {
        ++c.empty;
        c.empty_wrong += px[3] > 0.5f / 255.f;
        if (px[3] > 0.5f / 255.f && std::getenv("DEBUG_COVERAGE"))
          std::printf("stray %u,%u at %.3f,%.3f: %.3f %.3f %.3f %.3f\n", i, j, x + 0.5 * m,
                      y + 0.5 * m, px[0], px[1], px[2], px[3]);
        continue;
      }
      OGRPolygon sq;
      auto* ring = new OGRLinearRing;
      ring->addPoint(x, y);
      ring->addPoint(x + m, y);
      ring->addPoint(x + m, y + m);
      ring->addPoint(x, y + m);
      ring->closeRings();
      sq.addRingDirectly(ring);
      if (!OGRPreparedGeometryContains(covers.get(), OGRGeometry::ToHandle(&sq))) continue;
      ++c.covered;
      bool ok = true;
      for (int ch = 0; ch < 4; ++ch) ok = ok && std::abs(px[ch] - kFill[ch]) <= 2.f / 255.f;
      if (!ok && std::getenv("DEBUG_COVERAGE"))
        std::printf("covered %u,%u at %.3f,%.3f: %.3f %.3f %.3f %.3f\n", i, j, x + 0.5 * m,
                    y + 0.5 * m, px[0], px[1], px[2], px[3]);
      bool alone = false;
      for (size_t k = 0; k < near.size() && !alone; ++k)
        alone = envs[k].MinX <= x && envs[k].MaxX >= x + m && envs[k].MinY <= y &&
                envs[k].MaxY >= y + m &&
                OGRPreparedGeometryContains(each[k].get(), OGRGeometry::ToHandle(&sq));
      if (alone) {
        ++c.inside;
        c.inside_wrong += !ok;
        continue;
      }
      // Buildings that overlap inside the pixel (OSM has some) give it more
      // than the fill, rightly: left out, and counted.
      double area = 0;
      for (size_t k = 0; k < near.size(); ++k) {
        if (envs[k].MaxX < x || envs[k].MinX > x + m || envs[k].MaxY < y || envs[k].MinY > y + m)
          continue;
        const std::unique_ptr<OGRGeometry> in(near[k]->Intersection(&sq));
        if (in) area += OGR_G_Area(OGRGeometry::ToHandle(in.get()));
      }
      if (area > m * m * (1 + 1e-6)) {
        ++c.overlapped;
        continue;
      }
      // Within 0.75 px of a vertex the pixel may hold a corner, where a
      // coverage from the distance to the nearest edge (the half-plane of
      // Thöny et al. section 3.5) is not the area: counted apart, with the
      // largest deviation.
      if (nearest_vertex(near, x + 0.5 * m, y + 0.5 * m) < 0.75 * m) {
        ++c.corner;
        for (int ch = 0; ch < 4; ++ch)
          c.corner_worst = std::max(c.corner_worst, double(std::abs(px[ch] - kFill[ch])));
        continue;
      }
      ++c.shared;
      c.shared_wrong += !ok;
    }
  return c;
}

}  // namespace

TEST(CoverageAa, MonacoSharedEdgesAreFullAndEmptyGroundStaysEmpty) {
  const fs::path scene = out_dir() / "buildings.toml";
  std::ofstream(scene) << "source = \"" << kPbf << "\"\n"
                       << "extent = [7.400, 43.722, 7.445, 43.755]\nextent_crs = \"EPSG:4326\"\n"
                       << "resolution = 0\n\n[[layer]]\nname = \"buildings\"\n"
                       << "layer = \"multipolygons\"\nwhere = \"building IS NOT NULL\"\n"
                       << "kind = \"polygon\"\ncolor = \"#d9a48acc\"\n";
  const std::string pkg = (out_dir() / "buildings.decals").string();
  const auto r = run_tool("build " + scene.string() + " -o " + pkg + " -q");
  ASSERT_EQ(r.rc, 0) << r.output;
  decal::Package package;
  const decal::Status st = decal::Package::open(pkg, package);
  ASSERT_TRUE(bool(st)) << st.message;
  const prep::render::DecalSource src = prep::render::source_of(package);
  const auto all = buildings(src.frame);
  ASSERT_GT(all.size(), 1000u);

  // Windows of 320 x 180 pixels of 0.37 m, placed from the lon/lat of their
  // centres: of a scan of 234 such windows over the extract, the three with
  // the most pixels on shared edges (terraced blocks of Monte-Carlo and
  // La Condamine).
  const std::unique_ptr<OGRCoordinateTransformation> ct = render_test::wgs84_to_frame(src.frame);
  struct Window {
    double lon, lat, m;
  };
  Counts sum;
  for (const Window w : {Window{7.4240, 43.7425, 0.37}, Window{7.4160, 43.7320, 0.37},
                         Window{7.4240, 43.7470, 0.37}}) {
    double x = w.lon, y = w.lat;
    ASSERT_TRUE(ct->Transform(1, &x, &y));
    x -= src.frame.origin_x, y -= src.frame.origin_y;
    Counts c;
    try {
      c = check_window(src, all, x - 160 * w.m, y - 90 * w.m, w.m, 320, 180);
    } catch (const prep::render_error& err) {
      GTEST_SKIP() << "no headless GL: " << err.what();
    }
    std::printf(
        "window %.4f,%.4f at %.2f m: %zu pixels covered by the union; %zu inside one building "
        "(%zu not the fill), %zu on shared edges (%zu not the fill), %zu at corners where "
        "buildings meet (largest deviation %.1f/255), %zu where buildings overlap; %zu pixels "
        "farther than one pixel from every building (%zu not empty)\n",
        w.lon, w.lat, w.m, c.covered, c.inside, c.inside_wrong, c.shared, c.shared_wrong, c.corner,
        c.corner_worst * 255, c.overlapped, c.empty, c.empty_wrong);
    sum.covered += c.covered, sum.inside += c.inside, sum.inside_wrong += c.inside_wrong;
    sum.shared += c.shared, sum.shared_wrong += c.shared_wrong;
    sum.corner += c.corner, sum.corner_worst = std::max(sum.corner_worst, c.corner_worst);
    sum.empty += c.empty, sum.empty_wrong += c.empty_wrong;
  }
  EXPECT_GT(sum.covered, 20000u);
  EXPECT_GT(sum.shared, 200u);  // terraced rows do share edges here
  EXPECT_GT(sum.empty, 20000u);
  EXPECT_EQ(sum.inside_wrong, 0u);
  // Corners: the half-plane estimate's error, bounded loosely.
  EXPECT_LT(sum.corner_worst, 0.1);
  EXPECT_EQ(sum.shared_wrong, 0u);
  EXPECT_EQ(sum.empty_wrong, 0u);
}

}  // namespace render_coverage_aa
