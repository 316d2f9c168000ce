// The loader's structural validation: corrupt blobs are rejected before any
// GL call, with a message naming the blob, element and value.
#include <gtest/gtest.h>

#include "decal/gl/gl.hpp"
#include "hand_model.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"

namespace {

namespace R = prep::render;

// The loader's check of `src`, the blobs of `m` (possibly changed since).
decal::Status validate(const R::DecalSource& src, const prep::DecalModel& m) {
  std::vector<decal::gl::BlobBytes> blobs;
  for (const auto& b : src.blobs)
    blobs.push_back({b.id, b.count, {static_cast<const std::byte*>(b.data), size_t(b.bytes)}});
  const auto& g = m.grid;
  return decal::gl::validate_blobs(blobs, {g.origin_x, g.origin_y, g.cell_w, g.cell_h, g.nx, g.ny});
}
decal::Status validate(const prep::DecalModel& m) {
  return validate(R::source_of(m), m);
}

// A top-down GL render of `src` (the blobs of `m`) at w x h on flat ground.
void render_topdown(const R::DecalSource& src, const prep::DecalModel& m, uint32_t w, uint32_t h) {
  R::RenderOptions opt;
  opt.width = w;
  opt.height = h;
  opt.camera = R::topdown_camera(m.extent, 0, 0);
  R::render_gl(src, R::flat_heightfield(m.extent), opt);
}

// The hand model with the one change `corrupt` makes.
template <class Corrupt>
prep::DecalModel corrupted(Corrupt&& corrupt) {
  prep::DecalModel m = render_test::hand_model();
  corrupt(m);
  return m;
}

TEST(GlLoader, AcceptsTheHandModel) {
  auto s = validate(render_test::hand_model());
  EXPECT_TRUE(s.ok) << s.message;
}

TEST(GlLoader, RejectsOutOfRangeSegmentVertex) {
  auto s = validate(corrupted([](prep::DecalModel& m) { m.cell_segments[2][1] = 7; }));
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("cell_segments[2]"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("end = 7"), std::string::npos) << s.message;
}

TEST(GlLoader, RejectsQuadTreeChildBeforeParentSoDescentCannotLoop) {
  // An internal node pointing back at node 0.
  auto s = validate(corrupted([](prep::DecalModel& m) { m.qt_node[1] = {0, 0}; }));
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("qt_node[1]"), std::string::npos) << s.message;
}

TEST(GlLoader, RejectsBvhNodesBeyondBoxes) {
  // The last cell's tree claimed to end past the 12 boxes of the model.
  auto s = validate(corrupted([](prep::DecalModel& m) { m.cell_poly_first.back()[1] = 100; }));
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("cell_poly_first runs from (0, 0) to (8, 100)"), std::string::npos)
      << s.message;
}

TEST(GlLoader, RejectsCellTreeThatIsNotFull) {
  // Cell 2 left with 2 nodes for its 2 entries (a full tree has 3).
  auto s = validate(corrupted([](prep::DecalModel& m) { m.cell_poly_first[3][1] -= 1; }));
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("cell_poly_first[2]: 2 nodes"), std::string::npos) << s.message;
}

TEST(GlLoader, RejectsBadNodeTypeHoleRangeAndGridCount) {
  const auto message = [](auto corrupt) { return validate(corrupted(corrupt)).message; };
  EXPECT_NE(message([](prep::DecalModel& m) { m.qt_node[0][0] = 7; }).find("type = 7"),
            std::string::npos);
  EXPECT_NE(message([](prep::DecalModel& m) {
              m.cell_poly_holes[1] = 5;
            }).find("cell_poly_holes[2] = 1 is less than cell_poly_holes[1] = 5"),
            std::string::npos);
  EXPECT_NE(message([](prep::DecalModel& m) { m.grid.nx = 3; }).find("grid cells"),
            std::string::npos);
}

TEST(GlLoader, RejectsDynamicVertexOutsideItsLineRun) {
  auto m = render_test::hand_model();
  // two dynamic lines of two vertices each
  m.dyn_vertices = {{0, 0, 0, 0}, {1000, 0, 0, 0}, {0, 1000, 0, 1}, {1000, 1000, 0, 1}};
  m.dyn_prev_next = {{-1, 1}, {0, -1}, {-1, 3}, {2, -1}};
  m.dyn_line_start = {0, 2};
  m.dyn_line_props.resize(2, decal::LineProps{2.0f, 0xff0000ffu, 0, 0, 0.f, 0, 0, 0});
  EXPECT_TRUE(validate(m).ok) << validate(m).message;
  m.dyn_vertices[1][3] = 1;  // vertex 1 claims line 1 but lies in line 0's run
  auto s = validate(m);
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("dyn_vertices[1]"), std::string::npos) << s.message;
  m.dyn_vertices[1][3] = 0;
  m.dyn_line_start = {0, 0};
  EXPECT_NE(validate(m).message.find("does not increase"), std::string::npos);
}

TEST(GlLoader, RenderRejectsCorruptModelBeforeCreatingAContext) {
  // render_gl validates first: the validation message (not an EGL one) comes
  // back whether or not this machine has EGL.
  auto m = render_test::hand_model();
  m.qt_leaf_loops[0] = 999;
  try {
    render_topdown(R::source_of(m), m, 8, 8);
    FAIL() << "corrupt model rendered";
  } catch (const prep::render_error& e) {
    EXPECT_NE(std::string(e.what()).find("qt_leaf_loops[0]"), std::string::npos) << e.what();
  }
}

}  // namespace

namespace {

// Random single-word corruptions of every blob of the hand model (fixed
// seed): the loader either rejects the data, or the GL passes run to the
// end on it (no crash, no hang: every loop the shaders run is bounded by
// what validation checked).
TEST(GlLoader, SurvivesRandomCorruptionsOfEveryBlob) {
  auto base = render_test::hand_model();
  R::DecalSource src0 = R::source_of(base);
  uint32_t state = 12345u;
  auto next = [&]() {
    state = state * 1664525u + 1013904223u;
    return state;
  };
  int rejected = 0, rendered = 0;
  for (int trial = 0; trial < 120; ++trial) {
    auto m = render_test::hand_model();
    R::DecalSource src = R::source_of(m);
    const auto& blob = src.blobs[next() % src.blobs.size()];
    const size_t words = size_t(blob.bytes / 4);
    if (words == 0) continue;
    auto* w = static_cast<uint32_t*>(const_cast<void*>(blob.data)) + next() % words;
    const uint32_t kinds[] = {next(),      *w + 1,      *w - 1,
                              0xffffffffu, 0x7fffffffu, *w ^ (1u << (next() % 32))};
    *w = kinds[next() % 6];
    if (!validate(src, m)) {
      ++rejected;
      continue;
    }
    if (rendered >= 25) continue;  // keep the runtime to seconds
    try {
      render_topdown(src, m, 24, 16);
      ++rendered;
    } catch (const prep::render_error& e) {
      if (std::string(e.what()).find("EGL") != std::string::npos) GTEST_SKIP() << e.what();
      ADD_FAILURE() << "data passed validation but rendering failed: " << e.what();
    }
  }
  (void)src0;
  RecordProperty("rejected", rejected);
  RecordProperty("rendered", rendered);
  EXPECT_GT(rejected, 10);
  EXPECT_GT(rendered, 5);
}

}  // namespace
