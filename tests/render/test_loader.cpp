// The loader's structural validation: corrupt blobs are rejected before any
// GL call, with a message naming the blob, element and value.
#include <gtest/gtest.h>

#include "decal/gl/gl.hpp"
#include "hand_model.hpp"
#include "prep/error.hpp"
#include "prep/render.hpp"

namespace {

namespace R = prep::render;

decal::Status validate(const prep::DecalModel& m) {
  R::DecalSource src = R::source_of(m);
  std::vector<decal::gl::BlobBytes> blobs;
  for (const auto& b : src.blobs) blobs.push_back({b.id, b.count, {static_cast<const std::byte*>(b.data), size_t(b.bytes)}});
  const auto& g = m.grid;
  return decal::gl::validate_blobs(blobs, {g.origin_x, g.origin_y, g.cell_w, g.cell_h, g.nx, g.ny});
}

TEST(GlLoader, AcceptsTheHandModel) {
  auto s = validate(render_test::hand_model());
  EXPECT_TRUE(s.ok) << s.message;
}

TEST(GlLoader, RejectsOutOfRangeSegmentVertex) {
  auto m = render_test::hand_model();
  m.cell_segments[2][1] = 7;
  auto s = validate(m);
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("cell_segments[2]"), std::string::npos) << s.message;
  EXPECT_NE(s.message.find("end = 7"), std::string::npos) << s.message;
}

TEST(GlLoader, RejectsQuadTreeChildBeforeParentSoDescentCannotLoop) {
  auto m = render_test::hand_model();
  m.qt_node[1] = {0, 0};  // internal node pointing back at node 0
  auto s = validate(m);
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("qt_node[1]"), std::string::npos) << s.message;
}

TEST(GlLoader, RejectsBvhRangeBeyondBoxes) {
  auto m = render_test::hand_model();
  m.poly_bvh_range[3][0] = 100;
  auto s = validate(m);
  ASSERT_FALSE(s.ok);
  EXPECT_NE(s.message.find("poly_bvh_range[3]"), std::string::npos) << s.message;
}

TEST(GlLoader, RejectsBadNodeTypeHoleRangeAndGridCount) {
  {
    auto m = render_test::hand_model();
    m.qt_node[0][0] = 7;
    EXPECT_NE(validate(m).message.find("type = 7"), std::string::npos);
  }
  {
    auto m = render_test::hand_model();
    m.cell_polys[0][3] = 5;
    EXPECT_NE(validate(m).message.find("cell_polys[0]"), std::string::npos);
  }
  {
    auto m = render_test::hand_model();
    m.grid.nx = 3;
    EXPECT_NE(validate(m).message.find("grid cells"), std::string::npos);
  }
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
  m.qt_leaf_segments[0][0] = 999;
  R::DecalSource src = R::source_of(m);
  R::RenderOptions opt;
  opt.width = 8;
  opt.height = 8;
  opt.camera = R::topdown_camera(m.extent, 0, 0);
  try {
    R::render_gl(src, R::flat_heightfield(m.extent), opt);
    FAIL() << "corrupt model rendered";
  } catch (const prep::render_error& e) {
    EXPECT_NE(std::string(e.what()).find("qt_leaf_segments[0]"), std::string::npos) << e.what();
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
    const uint32_t kinds[] = {next(), *w + 1, *w - 1, 0xffffffffu, 0x7fffffffu, *w ^ (1u << (next() % 32))};
    *w = kinds[next() % 6];
    std::vector<decal::gl::BlobBytes> blobs;
    for (const auto& b : src.blobs) blobs.push_back({b.id, b.count, {static_cast<const std::byte*>(b.data), size_t(b.bytes)}});
    const auto& g = m.grid;
    if (!decal::gl::validate_blobs(blobs, {g.origin_x, g.origin_y, g.cell_w, g.cell_h, g.nx, g.ny})) {
      ++rejected;
      continue;
    }
    if (rendered >= 25) continue;  // keep the runtime to seconds
    R::RenderOptions opt;
    opt.width = 24;
    opt.height = 16;
    opt.camera = R::topdown_camera(m.extent, 0, 0);
    try {
      R::render_gl(src, R::flat_heightfield(m.extent), opt);
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
