// Layer order on real data: a scene of Monaco's land use, then its buildings
// (OpenStreetMap, samples/monaco). Every building standing inside a land-use
// polygon must show the building colour, in the CPU evaluator and in the GL
// render, because a later scene layer is drawn above an earlier one whatever
// the polygons' areas (formats/SPEC.md "Drawing order"). With the two layers
// swapped, the same points show the land-use colour.
//
// The oracle shares no code with the pipeline: OGR reads the same OSM
// layers, projects them into the package's frame CRS (from its metadata),
// and GEOS (through OGR, double precision) gives each building's point on
// surface, the land-use polygon that contains it, and the region
// building ∩ land use shrunk by 1 cm, inside which every test point lies.
#include <gtest/gtest.h>

#include <gdal_priv.h>
#include <ogr_api.h>
#include <ogr_geometry.h>
#include <ogrsf_frmts.h>

#include <cmath>
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
namespace render_layer_order {

namespace fs = std::filesystem;
using prep::test::run_tool;

namespace {

const std::string kSource = DECALPREP_SOURCE_DIR;
const std::string kPbf = kSource + "/samples/monaco/monaco.osm.pbf";
const std::string kLanduseWhere = "landuse IS NOT NULL";
const std::string kBuildingWhere = "building IS NOT NULL";
constexpr uint32_t kLanduseRgba = 0xff00ff00u;   // green, opaque (R in the low byte)
constexpr uint32_t kBuildingRgba = 0xff0000ffu;  // red, opaque

fs::path out_dir() {
  fs::path p = fs::current_path() / "render-out" / "layer_order";
  fs::create_directories(p);
  return p;
}

// A two-layer scene: `first` drawn lowest, `second` above it. No
// simplification, so the package keeps the OSM geometry to 1 mm.
std::string write_scene(const std::string& name, bool buildings_on_top) {
  const std::string landuse =
      "[[layer]]\nname = \"landuse\"\nlayer = \"multipolygons\"\nwhere = \"" + kLanduseWhere +
      "\"\nkind = \"polygon\"\ncolor = \"#00ff00\"\n\n";
  const std::string buildings =
      "[[layer]]\nname = \"buildings\"\nlayer = \"multipolygons\"\nwhere = \"" + kBuildingWhere +
      "\"\nkind = \"polygon\"\ncolor = \"#ff0000\"\n\n";
  const fs::path scene = out_dir() / (name + ".toml");
  std::ofstream(scene) << "source = \"" << kPbf << "\"\n"
                       << "extent = [7.400, 43.722, 7.445, 43.755]\nextent_crs = \"EPSG:4326\"\n"
                       << "resolution = 0\n\n"
                       << (buildings_on_top ? landuse + buildings : buildings + landuse);
  return scene.string();
}

// GEOS point on surface of any (multi)polygon, through OGR's C API.
std::unique_ptr<OGRPoint> point_on_surface(const OGRGeometry& g) {
  OGRGeometryH h = OGR_G_PointOnSurface(OGRGeometry::ToHandle(const_cast<OGRGeometry*>(&g)));
  OGRGeometry* p = h ? OGRGeometry::FromHandle(h) : nullptr;
  if (p && wkbFlatten(p->getGeometryType()) == wkbPoint)
    return std::unique_ptr<OGRPoint>(p->toPoint());
  delete p;
  return nullptr;
}

struct Probe {
  double x = 0, y = 0;                  // scene metres (relative to the package origin)
  std::unique_ptr<OGRGeometry> region;  // building ∩ land use, shrunk by 1 cm
};

// Buildings of the OSM extract whose point on surface lies in a land-use
// polygon, as probes in the frame of `frame`. Buildings OGR reports invalid
// are left out (the pipeline repairs them; their point on surface is not
// well defined), as are those outside `extent` (clipped by the scene).
std::vector<Probe> probes(const prep::SceneFrame& frame, const prep::Extent& extent,
                          size_t& buildings) {
  GDALAllRegister();
  std::unique_ptr<GDALDataset> ds(
      GDALDataset::Open(kPbf.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY));
  if (!ds) throw std::runtime_error("cannot open " + kPbf);
  const std::unique_ptr<OGRCoordinateTransformation> ct = render_test::wgs84_to_frame(frame);
  // Features are read into frame coordinates, then shifted to the origin.
  auto read = [&](const std::string& where) {
    std::vector<std::unique_ptr<OGRGeometry>> out;
    OGRLayer* layer = ds->GetLayerByName("multipolygons");
    layer->ResetReading();
    layer->SetAttributeFilter(where.c_str());
    while (OGRFeature* f = layer->GetNextFeature()) {
      OGRGeometry* g = f->GetGeometryRef();
      if (g && !g->IsEmpty()) {
        std::unique_ptr<OGRGeometry> p(g->clone());
        if (p->transform(ct.get()) == OGRERR_NONE) {
          // Shift by the origin (every vertex), through a generic visitor.
          struct Shift : OGRDefaultGeometryVisitor {
            double dx, dy;
            Shift(double x, double y) : dx(x), dy(y) {}
            using OGRDefaultGeometryVisitor::visit;
            void visit(OGRPoint* pt) override {
              pt->setX(pt->getX() - dx), pt->setY(pt->getY() - dy);
            }
            void visit(OGRLineString* ls) override {
              for (int i = 0; i < ls->getNumPoints(); ++i)
                ls->setPoint(i, ls->getX(i) - dx, ls->getY(i) - dy);
            }
            void visit(OGRLinearRing* r) override { visit(static_cast<OGRLineString*>(r)); }
          } shift(frame.origin_x, frame.origin_y);
          p->accept(&shift);
          out.push_back(std::move(p));
        }
      }
      OGRFeature::DestroyFeature(f);
    }
    return out;
  };
  const auto landuse = read(kLanduseWhere);
  const auto building = read(kBuildingWhere);
  buildings = building.size();
  std::vector<OGREnvelope> lenv(landuse.size());
  for (size_t i = 0; i < landuse.size(); ++i) landuse[i]->getEnvelope(&lenv[i]);
  std::vector<Probe> out;
  for (const auto& b : building) {
    if (!b->IsValid()) continue;
    std::unique_ptr<OGRPoint> pos = point_on_surface(*b);
    if (!pos || pos->IsEmpty()) continue;
    const double px = pos->getX(), py = pos->getY();
    if (px < extent.xmin + 1 || px > extent.xmax - 1 || py < extent.ymin + 1 ||
        py > extent.ymax - 1)
      continue;
    for (size_t i = 0; i < landuse.size(); ++i) {
      if (!(lenv[i].MinX <= px && px <= lenv[i].MaxX && lenv[i].MinY <= py && py <= lenv[i].MaxY))
        continue;
      if (!landuse[i]->IsValid() || !landuse[i]->Contains(pos.get())) continue;
      std::unique_ptr<OGRGeometry> both(b->Intersection(landuse[i].get()));
      if (!both) break;
      Probe pr;
      pr.region.reset(both->Buffer(-0.01));
      if (!pr.region || pr.region->IsEmpty()) break;
      // The building's point on surface when it is 1 cm clear of every edge
      // involved; else the point on surface of the shrunk region.
      if (pr.region->Contains(pos.get())) {
        pr.x = px, pr.y = py;
      } else {
        std::unique_ptr<OGRPoint> q = point_on_surface(*pr.region);
        if (!q || q->IsEmpty()) break;
        pr.x = q->getX(), pr.y = q->getY();
      }
      out.push_back(std::move(pr));
      break;
    }
  }
  return out;
}

struct Counts {
  size_t probes = 0, cpu_expected = 0;
  size_t gl_buildings = 0, gl_expected = 0, gl_pixels = 0, gl_pixels_expected = 0;
};

// Builds the scene, then checks every probe: the CPU evaluator at the probe
// point, the GL render at every pixel centre inside the probe's region.
Counts run(const std::string& name, bool buildings_on_top, bool& gl_ran, std::string& why) {
  Counts c;
  const std::string pkg = (out_dir() / (name + ".decals")).string();
  auto r = run_tool("build " + write_scene(name, buildings_on_top) + " -o " + pkg + " -q");
  EXPECT_EQ(r.rc, 0) << r.output;
  decal::Package package;
  const decal::Status st = decal::Package::open(pkg, package);
  EXPECT_TRUE(bool(st)) << st.message;
  if (!st) return c;
  const prep::render::DecalSource src = prep::render::source_of(package);
  size_t buildings = 0;
  const std::vector<Probe> pr = probes(src.frame, src.extent, buildings);
  c.probes = pr.size();
  const uint32_t want = buildings_on_top ? kBuildingRgba : kLanduseRgba;
  auto is = [](const float* rgba, uint32_t colour) {
    for (int ch = 0; ch < 4; ++ch)
      if (std::abs(rgba[ch] - float((colour >> (8 * ch)) & 0xffu) / 255.f) > 1.5f / 255.f)
        return false;
    return true;
  };
  for (const Probe& p : pr) {
    const prep::EvalSample s = prep::evaluate(src.view, p.x, p.y);
    c.cpu_expected += is(s.rgba, want);
  }

  // GL: top-down orthographic tiles at 1 m per pixel over the probes' box.
  prep::Extent box{1e300, 1e300, -1e300, -1e300};
  for (const Probe& p : pr) {
    box.xmin = std::min(box.xmin, std::floor(p.x) - 2),
    box.ymin = std::min(box.ymin, std::floor(p.y) - 2);
    box.xmax = std::max(box.xmax, std::ceil(p.x) + 2),
    box.ymax = std::max(box.ymax, std::ceil(p.y) + 2);
  }
  const uint32_t W = uint32_t(box.xmax - box.xmin), H = uint32_t(box.ymax - box.ymin);
  std::vector<float> layer(size_t(W) * H * 4, 0.f);
  constexpr uint32_t kTile = 1024;
  gl_ran = true;
  for (uint32_t ty = 0; ty < H && gl_ran; ty += kTile)
    for (uint32_t tx = 0; tx < W && gl_ran; tx += kTile) {
      const uint32_t tw = std::min(kTile, W - tx), th = std::min(kTile, H - ty);
      const prep::Extent e{box.xmin + tx, box.ymax - ty - th, box.xmin + tx + tw, box.ymax - ty};
      prep::render::RenderOptions opt;
      opt.width = tw, opt.height = th;
      opt.camera = prep::render::topdown_camera(e, 0, 0);
      opt.draw_dynamic = false;
      try {
        const prep::render::Image img =
            prep::render::render_gl(src, prep::render::flat_heightfield(e), opt);
        for (uint32_t j = 0; j < th; ++j)
          std::copy_n(&img.decals[size_t(j) * tw * 4], size_t(tw) * 4,
                      &layer[(size_t(ty + j) * W + tx) * 4]);
      } catch (const prep::render_error& err) {
        why = std::string("no headless GL: ") + err.what();
        gl_ran = false;
      }
    }
  if (!gl_ran) return c;
  for (const Probe& p : pr) {
    OGREnvelope env;
    p.region->getEnvelope(&env);
    size_t inside = 0, right = 0;
    for (int64_t j = int64_t(std::floor(box.ymax - env.MaxY));
         j <= int64_t(std::ceil(box.ymax - env.MinY)); ++j)
      for (int64_t i = int64_t(std::floor(env.MinX - box.xmin));
           i <= int64_t(std::ceil(env.MaxX - box.xmin)); ++i) {
        if (i < 0 || j < 0 || i >= int64_t(W) || j >= int64_t(H)) continue;
        OGRPoint centre(box.xmin + double(i) + 0.5, box.ymax - double(j) - 0.5);
        const double cx = centre.getX(), cy = centre.getY();
        const prep::Extent& ex = src.extent;  // the scene clips to it
        if (cx < ex.xmin + 0.01 || cx > ex.xmax - 0.01 || cy < ex.ymin + 0.01 ||
            cy > ex.ymax - 0.01)
          continue;
        if (!p.region->Contains(&centre)) continue;
        ++inside;
        const bool ok = is(&layer[(size_t(j) * W + size_t(i)) * 4], want);
        right += ok;
        if (!ok && std::getenv("DEBUG_LAYER_ORDER")) {
          const float* g = &layer[(size_t(j) * W + size_t(i)) * 4];
          const prep::EvalSample cs = prep::evaluate(src.view, centre.getX(), centre.getY());
          std::printf(
              "pixel %lld,%lld at %.3f,%.3f gl %.3f %.3f %.3f %.3f cpu %.3f %.3f %.3f %.3f\n",
              (long long)i, (long long)j, centre.getX(), centre.getY(), g[0], g[1], g[2], g[3],
              cs.rgba[0], cs.rgba[1], cs.rgba[2], cs.rgba[3]);
        }
      }
    if (inside == 0) continue;  // no pixel centre inside at 1 m
    ++c.gl_buildings;
    c.gl_pixels += inside;
    c.gl_pixels_expected += right;
    c.gl_expected += right == inside;
  }
  std::printf(
      "[%s] %zu buildings in the extract, %zu inside a land-use polygon; CPU evaluator shows the "
      "%s colour "
      "at %zu / %zu points on surface; GL (1 m pixels): %zu / %zu buildings with every pixel "
      "centre right, "
      "%zu / %zu pixels\n",
      name.c_str(), buildings, c.probes, buildings_on_top ? "building" : "land-use", c.cpu_expected,
      c.probes, c.gl_expected, c.gl_buildings, c.gl_pixels_expected, c.gl_pixels);
  return c;
}

// Builds and checks one stacking; the GL part skips where there is no EGL.
void check_stack(const std::string& name, bool buildings_on_top) {
  bool gl_ran = false;
  std::string why;
  const Counts c = run(name, buildings_on_top, gl_ran, why);
  EXPECT_GT(c.probes, 500u);  // Monaco has a few thousand such buildings
  EXPECT_EQ(c.cpu_expected, c.probes);
  if (!gl_ran) GTEST_SKIP() << "CPU evaluator checked; GL part skipped: " << why;
  EXPECT_GT(c.gl_buildings, c.probes * 9 / 10);
  EXPECT_EQ(c.gl_expected, c.gl_buildings);
  EXPECT_EQ(c.gl_pixels_expected, c.gl_pixels);
}

}  // namespace

TEST(LayerOrder, MonacoBuildingsAfterLandUseAreDrawnAboveIt) {
  check_stack("buildings_on_top", true);
}

TEST(LayerOrder, MonacoLandUseAfterBuildingsIsDrawnAboveThem) {
  check_stack("landuse_on_top", false);
}

}  // namespace render_layer_order
