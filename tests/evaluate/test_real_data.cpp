// Real data: Monaco (the sample scene: landuse, green,
// water, buildings; inset building outlines, offset green outlines, normal
// water outlines; bevel paths, round streets, miter main roads) and
// Liechtenstein (buildings, landuse, offset building outlines, highways) through
// read -> project -> clean, then build; the evaluator must agree with GEOS on
// the cleaned geometry (polygons: contains with holes; lines: the buffer
// oracle of test_line_accuracy) outside the 2 mm band.
// Skips when the shared data is missing.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <mutex>

#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "prep/pipeline.hpp"
#include "prep/read.hpp"
#include "synthetic.hpp"
#include "test_support.hpp"

namespace {

using synth::G;

// 2x10^5 by default to keep ctest short (about 10 s per dataset on 2
// cores); DECALPREP_SAMPLES=1000000 for the full-size run.
size_t sample_count() {
  const char* e = std::getenv("DECALPREP_SAMPLES");
  return e ? size_t(std::atoll(e)) : size_t(200'000);
}

struct Oracle {
  std::vector<G> area, bound;
  std::vector<const GEOSPreparedGeometry*> parea, pbound;
  std::vector<bool> is_line;
  GEOSSTRtree* tree = nullptr;
  GEOSContextHandle_t h;
  explicit Oracle(GEOSContextHandle_t hh, const prep::SceneFeatures& s) : h(hh) {
    for (const auto& p : s.polygons) {
      area.push_back(synth::polygon(h, p.shell, p.holes));
      is_line.push_back(false);
    }
    for (const auto& l : s.lines) {
      area.push_back(synth::oracle(h, l, s.layers[l.layer]));
      is_line.push_back(true);
    }
    tree = GEOSSTRtree_create_r(h, 10);
    for (size_t i = 0; i < area.size(); ++i) {
      bound.push_back(G(h, GEOSBoundary_r(h, area[i].g)));
      parea.push_back(GEOSPrepare_r(h, area[i].g));
      pbound.push_back(GEOSPrepare_r(h, bound[i].g));
      GEOSSTRtree_insert_r(h, tree, area[i].g, reinterpret_cast<void*>(i));
    }
  }
  ~Oracle() {
    for (auto* p : parea) GEOSPreparedGeom_destroy_r(h, p);
    for (auto* p : pbound) GEOSPreparedGeom_destroy_r(h, p);
    GEOSSTRtree_destroy_r(h, tree);
  }
};

struct Outcome {
  uint64_t tested = 0, excluded = 0, polygon = 0, line = 0, wrong = 0;
  uint64_t wrong_inset_offset = 0;  // of `wrong`: only an inset/offset outline disagrees
};

// DECALPREP_THESIS_OUTLINES=1 clears the clipped-outline bits (SPEC
// "Clipped outlines") before sampling, to measure the thesis's one-sided
// inset/offset rule (Fig. 4.8 leaks) on the same data; the test then fails.
void maybe_unclip(prep::DecalModel& m) {
  const char* e = std::getenv("DECALPREP_THESIS_OUTLINES");
  if (!e || std::string(e) != "1") return;
  for (auto& p : m.line_props) {
    p.style &= ~(decal::kStyleClipBit | decal::kStyleClipInsideBit);
    p.clip_node = 0;
  }
}

// `m` is the full model (lines are evaluated first, so its line flag is
// exact); `polys` is the model of the polygons alone, whose polygon flag an
// opaque line above cannot hide (front-to-back early exit).
Outcome check(const prep::SceneFeatures& s, const prep::DecalModel& m,
              const prep::DecalModel& polys, size_t n) {
  const prep::StaticView view = prep::view_of(m), poly_view = prep::view_of(polys);
  const double q = decal::kQuantumMetres;
  const double x0 = m.grid.origin_x * q, y0 = m.grid.origin_y * q;
  const double w = double(m.grid.cell_w) * m.grid.nx * q,
               hgt = double(m.grid.cell_h) * m.grid.ny * q;
  // Vertices to sample near.
  std::vector<prep::Point2> anchors;
  for (const auto& p : s.polygons) {
    anchors.insert(anchors.end(), p.shell.begin(), p.shell.end());
    for (const auto& r : p.holes) anchors.insert(anchors.end(), r.begin(), r.end());
  }
  for (const auto& l : s.lines) anchors.insert(anchors.end(), l.points.begin(), l.points.end());
  const size_t chunks = 4;
  std::atomic<uint64_t> tested{0}, excluded{0}, polygon{0}, line{0}, wrong{0}, wrong_io{0};
  std::mutex log_mutex;
  int logged = 0;
  tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
    synth::Geos geos;
    Oracle o(geos.h, s);
    auto h = geos.h;
    std::mt19937_64 rng(555 + c);
    std::uniform_real_distribution<double> U(0, 1);
    Outcome my;
    const size_t count = n / chunks + (c < n % chunks ? 1 : 0);
    for (size_t k = 0; k < count; ++k) {
      double x, y;
      if (k % 2 == 0) {
        x = x0 + w * U(rng);
        y = y0 + hgt * U(rng);
      } else {
        const auto& a = anchors[size_t(U(rng) * anchors.size()) % anchors.size()];
        const double r = 8 * U(rng) * U(rng), t = 2 * M_PI * U(rng);
        x = a.x + r * std::cos(t);
        y = a.y + r * std::sin(t);
      }
      G pt = synth::point(h, x, y);
      struct Q {
        Oracle* o;
        const GEOSGeometry* pt;
        bool poly = false, line = false, skip = false;
        size_t line_index = 0;
      } qd{&o, pt.g};
      // Query with the 2 mm box around the point: a boundary within 2 mm may
      // belong to a geometry whose envelope misses the point itself.
      G probe = synth::box(h, x - 0.002, y - 0.002, x + 0.002, y + 0.002);
      GEOSSTRtree_query_r(
          h, o.tree, probe.g,
          [](void* item, void* ud) {
            auto* qq = static_cast<Q*>(ud);
            const size_t i = reinterpret_cast<size_t>(item);
            auto hh = qq->o->h;
            if (GEOSPreparedDistanceWithin_r(hh, qq->o->pbound[i], qq->pt, 0.002)) qq->skip = true;
            if (GEOSPreparedContains_r(hh, qq->o->parea[i], qq->pt)) {
              (qq->o->is_line[i] ? qq->line : qq->poly) = true;
              if (qq->o->is_line[i]) qq->line_index = i;
            }
          },
          &qd);
      if (qd.skip) {
        ++my.excluded;
        continue;
      }
      ++my.tested;
      my.polygon += qd.poly;
      my.line += qd.line;
      prep::EvalSample got = prep::evaluate(view, x, y);
      got.polygon_covered = prep::evaluate(poly_view, x, y).polygon_covered;
      if (got.polygon_covered != qd.poly || got.line_covered != qd.line) {
        ++my.wrong;
        // Counted apart: only an inset/offset outline disagrees. The thesis's
        // one-sided rule (§3.6) leaks past other edges of narrow rings
        // (Fig. 4.8); the package clips those rings by themselves, so this
        // must be 0 like the rest (the breakdown stays for diagnosis).
        auto io_layer = [&](uint32_t layer) {
          return s.layers[layer].style.outline != decal::OutlineMode::normal;
        };
        const bool inset_offset =
            got.polygon_covered == qd.poly &&
            ((got.top_line >= 0 && io_layer(m.line_props[size_t(got.top_line)].layer)) ||
             (qd.line && io_layer(s.lines[qd.line_index - s.polygons.size()].layer)));
        if (inset_offset) ++my.wrong_inset_offset;
        std::lock_guard<std::mutex> lock(log_mutex);
        if (std::getenv("DECALPREP_DEBUG_THIN") && got.top_line >= 0) {
          // Which outline, and how thin is its ring? (2 * area / perimeter)
          const prep::SceneLine& l = s.lines[size_t(got.top_line)];
          G ring = synth::polygon(h, l.points);
          const double a = prep::test::area(ring), per = prep::test::length(ring);
          double dist = 0;
          GEOSDistance_r(h, ring.g, pt.g, &dist);
          std::printf(
              "  outline fid %lld: %zu vertices, 2A/P = %.3f m, half width %.2f m, point %.3f m "
              "outside its ring\n",
              (long long)l.fid, l.points.size(), 2 * a / per,
              m.line_props[size_t(got.top_line)].half_width, dist);
        }
        if (std::getenv("DECALPREP_DEBUG_THIN") && !inset_offset) {
          const prep::EvalSample ps = prep::evaluate(poly_view, x, y);
          if (ps.top_polygon >= 0) {
            const auto& pp = polys.poly_props[size_t(ps.top_polygon)];
            for (const auto& sp : s.polygons)
              if (uint32_t(sp.fid) == pp.feature && sp.layer == pp.layer) {
                G shell = synth::polygon(h, sp.shell);
                std::printf(
                    "  polygon fid %lld layer %u: shell %zu vertices contains %d valid %d; holes "
                    "%zu:",
                    (long long)sp.fid, sp.layer, sp.shell.size(), GEOSContains_r(h, shell.g, pt.g),
                    GEOSisValid_r(h, shell.g), sp.holes.size());
                for (const auto& hr : sp.holes) {
                  G hole = synth::polygon(h, hr);
                  std::printf(" %d", GEOSContains_r(h, hole.g, pt.g));
                }
                std::printf("\n");
                const uint32_t pi = uint32_t(ps.top_polygon);
                const auto& rb = polys.qt_node_box[polys.poly_root_node[pi]];
                std::printf(
                    "    root covers %d; root box %d %d %d %d type %d; point q %.3f %.3f; ring:",
                    prep::polygon_ring_covers(poly_view, pi, x, y), rb[0], rb[1], rb[2], rb[3],
                    polys.qt_node[polys.poly_root_node[pi]][0], x / 0.001, y / 0.001);
                for (const auto& v : sp.shell) std::printf(" (%.4f %.4f)", v.x, v.y);
                std::printf("\n");
              }
          }
        }
        if (logged++ < 10)
          ADD_FAILURE()
              << std::fixed << "misclassified (" << x << ", " << y << "): GEOS polygon " << qd.poly
              << " line " << qd.line << ", evaluator polygon " << got.polygon_covered << " line "
              << got.line_covered << " (oracle line layer "
              << (qd.line ? s.layers[s.lines[qd.line_index - s.polygons.size()].layer].name : "-")
              << ", top line " << got.top_line << " layer "
              << (got.top_line >= 0 ? s.layers[m.line_props[size_t(got.top_line)].layer].name : "-")
              << ")";
      }
    }
    tested += my.tested;
    excluded += my.excluded;
    polygon += my.polygon;
    line += my.line;
    wrong += my.wrong;
    wrong_io += my.wrong_inset_offset;
  });
  return {tested.load(), excluded.load(), polygon.load(),
          line.load(),   wrong.load(),    wrong_io.load()};
}

void run(const char* name, const prep::BuildSpec& spec) {
  prep::BuildRequest req;
  req.dry_run = true;
  const prep::BuildResult r = prep::run_build(spec, req);
  ASSERT_FALSE(r.scene.polygons.empty());
  ASSERT_FALSE(r.scene.lines.empty());
  prep::DecalModel m = prep::build_model(r.scene, spec.model);
  maybe_unclip(m);
  prep::SceneFeatures polygons_only = r.scene;
  polygons_only.lines.clear();
  const prep::DecalModel mp = prep::build_model(polygons_only, spec.model);
  const Outcome o = check(r.scene, m, mp, sample_count());
  std::printf(
      "[%s] %zu polygons, %zu static lines; %llu samples tested, %llu excluded (within 2 mm), "
      "%llu in polygons, %llu on lines, %llu misclassified (%llu of them only by an inset/offset "
      "outline, see the comment in check()); grid %ux%u; max representation "
      "error %.6f mm\n",
      name, r.scene.polygons.size(), r.scene.lines.size(), (unsigned long long)o.tested,
      (unsigned long long)o.excluded, (unsigned long long)o.polygon, (unsigned long long)o.line,
      (unsigned long long)o.wrong, (unsigned long long)o.wrong_inset_offset, m.grid.nx, m.grid.ny,
      m.max_representation_error * 1000);
  EXPECT_EQ(o.wrong, 0u);
  EXPECT_LE(m.max_representation_error, 0.001);
}

}  // namespace

TEST(RealData, MonacoSampleSceneAgreesWithGeos) {
  const std::string data = prep::test::monaco_sample("monaco.osm.pbf");
  const std::string scene = std::string(DECALPREP_SOURCE_DIR) + "/samples/monaco/scene.toml";
  if (!std::filesystem::exists(data) || !std::filesystem::exists(scene))
    GTEST_SKIP() << "Monaco data missing: " << data;
  prep::BuildSpec spec = prep::load_scene_file(scene);
  for (auto& l : spec.layers) l.source = data;
  spec.dem = "/vsizip/" + prep::test::monaco_sample("N43E007.hgt.zip/N43E007.hgt");
  run("Monaco", spec);
}

TEST(RealData, LiechtensteinAgreesWithGeos) {
  const std::string data =
      prep::test::shared_data("liechtenstein/liechtenstein-2013-08-03.osm.pbf");
  if (!std::filesystem::exists(data)) GTEST_SKIP() << "Liechtenstein data missing: " << data;
  prep::BuildSpec spec = prep::parse_scene(R"(
source = ")" + data + R"("
resolution = 0.1
[[layer]]
name = "landuse"
layer = "multipolygons"
where = "landuse IS NOT NULL"
kind = "polygon"
color = "#ebe3d6"
[[layer]]
name = "buildings"
layer = "multipolygons"
where = "building IS NOT NULL"
kind = "polygon"
color = "#d9a48acc"
[[layer]]
name = "building_outlines"
layer = "multipolygons"
where = "building IS NOT NULL"
kind = "outline"
outline_mode = "offset"
corner = "miter"
width = 0.5
color = "#8c5a46"
[[layer]]
name = "roads"
layer = "lines"
where = "highway IS NOT NULL"
kind = "line"
width = 4.0
corner = "round"
color = "#fdfbf6"
)",
                                           data + ".scene.toml");
  run("Liechtenstein", spec);
}
