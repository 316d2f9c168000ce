// The drawing order across layers and kinds (formats/SPEC.md "Drawing
// order"): a later scene layer is drawn above an earlier one whatever its
// size or geometry type, and older packages keep every line over every
// polygon. Expected colours are analytic: the scenes are
// axis-aligned squares and straight lines whose covered sets are known.
#include <gtest/gtest.h>

#include <cmath>

#include "prep/evaluate.hpp"
#include "prep/model.hpp"
#include "synthetic.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace evaluate_draw_order {

namespace {

constexpr uint32_t kRed = 0xff0000ffu, kGreen = 0xff00ff00u, kBlue = 0xffff0000u,
                   kGrey = 0xff808080u;

prep::ScenePolygon square(uint32_t layer, int64_t fid, double x0, double y0, double x1, double y1) {
  prep::ScenePolygon p;
  p.shell = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
  p.layer = layer;
  p.fid = fid;
  p.area = (x1 - x0) * (y1 - y0);
  return p;
}

prep::SceneLine horizontal(uint32_t layer, int64_t fid, double x0, double x1, double y,
                           double width) {
  prep::SceneLine l;
  l.layer = layer;
  l.fid = fid;
  l.width = width;
  l.points = {{x0, y}, {x1, y}};
  l.length = x1 - x0;
  return l;
}

uint32_t rgba8(const prep::EvalSample& s) {
  uint32_t v = 0;
  for (int c = 0; c < 4; ++c)
    v |= uint32_t(std::lround(std::clamp(s.rgba[c], 0.f, 1.f) * 255.f)) << (8 * c);
  return v;
}

// Layers, bottom to top: a big polygon "landuse" (0), a road line (1), a small
// polygon "building" (2) on the road, and a ring of outline (3).
prep::SceneFeatures stacked_scene(bool swap_road_and_building) {
  prep::SceneFeatures s;
  const uint32_t road = swap_road_and_building ? 2 : 1, building = swap_road_and_building ? 1 : 2;
  s.layers.resize(4);
  s.layers[0] = synth::layer("landuse", prep::DecalKind::polygon, kGreen);
  s.layers[road] = synth::layer("road", prep::DecalKind::line, kGrey);
  s.layers[road].style.width = 10;
  s.layers[building] = synth::layer("building", prep::DecalKind::polygon, kRed);
  s.layers[3] = synth::layer("outline", prep::DecalKind::outline, kBlue);
  s.layers[3].style.width = 1;
  s.polygons.push_back(square(0, 1, 0, 0, 1000, 1000));
  s.polygons.push_back(square(building, 2, 400, 480, 440, 560));
  s.lines.push_back(horizontal(road, 3, 100, 900, 500, 10));  // covers y in [495, 505]
  prep::SceneLine ring;
  ring.layer = 3;
  ring.fid = 4;
  ring.width = 1;
  ring.closed = true;
  ring.points = {{600, 600}, {700, 600}, {700, 700}, {600, 700}};
  ring.length = 400;
  s.lines.push_back(ring);
  return s;
}

}  // namespace

TEST(DrawOrder, LaterLayerIsAboveEarlierWhateverItsSizeOrKind) {
  const prep::DecalModel m = prep::build_model(stacked_scene(false), {});
  const prep::StaticView v = prep::view_of(m);
  EXPECT_EQ(rgba8(prep::evaluate(v, 200, 200)), kGreen);  // land use only
  EXPECT_EQ(rgba8(prep::evaluate(v, 200, 500)), kGrey);   // road over land use
  EXPECT_EQ(rgba8(prep::evaluate(v, 420, 500)),
            kRed);  // building (layer 2) over road (1) and land use
  EXPECT_EQ(rgba8(prep::evaluate(v, 420, 530)), kRed);   // building over land use
  EXPECT_EQ(rgba8(prep::evaluate(v, 700, 680)), kBlue);  // the top layer's ring over land use
  EXPECT_EQ(rgba8(prep::evaluate(v, 650, 650)), kGreen);
}

TEST(DrawOrder, SwappingTwoLayersSwapsWhichIsOnTop) {
  const prep::DecalModel m = prep::build_model(stacked_scene(true), {});
  const prep::StaticView v = prep::view_of(m);
  EXPECT_EQ(rgba8(prep::evaluate(v, 420, 500)), kGrey);  // road (now layer 2) over the building
  EXPECT_EQ(rgba8(prep::evaluate(v, 420, 530)), kRed);
  EXPECT_EQ(rgba8(prep::evaluate(v, 200, 500)), kGrey);
}

TEST(DrawOrder, RunsListTheStackTopFirstAndCoverEveryRank) {
  const prep::DecalModel m = prep::build_model(stacked_scene(false), {});
  const prep::StaticView v = prep::view_of(m);
  const std::vector<prep::DrawRun> runs = prep::draw_runs(v);
  // Top first: outline ring, building, road, land use.
  ASSERT_EQ(runs.size(), 4u);
  using K = prep::DrawRun::Kind;
  const K kinds[] = {K::lines, K::polygons, K::lines, K::polygons};
  uint32_t next = 0;
  for (size_t i = 0; i < runs.size(); ++i) {
    EXPECT_EQ(runs[i].kind, kinds[i]) << i;
    EXPECT_EQ(runs[i].lo, next) << i;  // one rank space: runs tile 0..N-1
    next = runs[i].hi;
  }
  EXPECT_EQ(next, 4u);
}

TEST(DrawOrder, PackagesBeforeOneRankSpaceDrawEveryLineOverEveryPolygon) {
  // A format 1.0/1.1 reader view: ranks per kind, polygons biased below lines.
  const prep::DecalModel m = prep::build_model(stacked_scene(false), {});
  prep::DecalModel legacy = m;
  std::vector<uint32_t> lines, polys;
  for (uint32_t i = 0; i < legacy.line_props.size(); ++i) lines.push_back(i);
  std::sort(lines.begin(), lines.end(), [&](uint32_t a, uint32_t b) {
    return legacy.line_props[a].order < legacy.line_props[b].order;
  });
  for (uint32_t r = 0; r < lines.size(); ++r) legacy.line_props[lines[r]].order = r;
  std::vector<std::pair<uint32_t, uint32_t>> ext;  // (order, index)
  for (uint32_t i = 0; i < legacy.poly_props.size(); ++i)
    if (legacy.poly_props[i].exterior < 0) ext.push_back({legacy.poly_props[i].order, i});
  std::sort(ext.begin(), ext.end());
  for (uint32_t r = 0; r < ext.size(); ++r) legacy.poly_props[ext[r].second].order = r;
  for (auto& p : legacy.poly_props)
    if (p.exterior >= 0) p.order = legacy.poly_props[size_t(p.exterior)].order;
  prep::StaticView v = prep::view_of(legacy);
  v.polygon_rank_bias = legacy.line_props.size();
  EXPECT_EQ(rgba8(prep::evaluate(v, 420, 500)),
            kGrey);  // the road over the building, as 1.1 drew it
  EXPECT_EQ(rgba8(prep::evaluate(v, 420, 530)), kRed);
  const std::vector<prep::DrawRun> runs = prep::draw_runs(v);
  ASSERT_EQ(runs.size(), 2u);
  EXPECT_EQ(runs[0].kind, prep::DrawRun::Kind::lines);
  EXPECT_EQ(runs[1].kind, prep::DrawRun::Kind::polygons);
}

}  // namespace evaluate_draw_order
