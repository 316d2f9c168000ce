// The shipped Monaco sample end to end: the real
// decalprep binary (DECALPREP_TOOL) builds samples/monaco/scene.toml, whose
// static lines use all three corner styles and whose outlines use all three
// outline modes, `decalprep verify` accepts the package, and the package's
// line properties carry every style and mode the scene asks for, with every
// closed inset/offset ring clipped by its own ring (SPEC "Clipped outlines").
#include <gtest/gtest.h>

#include <array>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "decal/reader.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;

using prep::test::run_tool;
using prep::test::ToolRun;

TEST(MonacoSample, BuildsWithEveryCornerStyleAndOutlineModeAndVerifies) {
  const fs::path scene = fs::path(DECALPREP_SOURCE_DIR) / "samples/monaco/scene.toml";
  if (!fs::exists(scene.parent_path() / "monaco.osm.pbf"))
    GTEST_SKIP() << "Monaco sample data missing: " << scene.parent_path() / "monaco.osm.pbf";
  const prep::test::TempDir tmp("decalprep_monaco_sample");
  const fs::path& dir = tmp.path();
  const fs::path pkg = dir / "monaco.decals";

  const ToolRun build = run_tool("build '" + scene.string() + "' -o '" + pkg.string() +
                                     "' --report '" + (dir / "report.json").string() + "' -q",
                                 dir);
  ASSERT_EQ(build.rc, 0) << build.output;
  const ToolRun verify = run_tool("verify '" + pkg.string() + "'", dir);
  EXPECT_EQ(verify.rc, 0) << verify.output;

  decal::Package p;
  const decal::Status s = decal::Package::open(pkg.string(), p);
  ASSERT_TRUE(s) << s.message;
  const auto props = p.array<decal::BlobId::line_props>();
  const uint64_t nodes = p.find(decal::BlobId::qt_node) ? p.find(decal::BlobId::qt_node)->count : 0;
  // The layer table (metadata `layers`, indexed by LineProps::layer) tells
  // outlines from lines.
  const auto meta = nlohmann::json::parse(p.metadata_json());
  const auto& layers = meta.at("layers");
  std::array<size_t, 3> corners{}, outline_modes{};
  size_t clipped = 0, closed_inset_offset = 0;
  for (const decal::LineProps& l : props) {
    const uint32_t corner = l.style & decal::kStyleCornerMask;
    const uint32_t mode = (l.style & decal::kStyleOutlineMask) >> decal::kStyleOutlineShift;
    ASSERT_LT(corner, 3u);
    ASSERT_LT(mode, 3u);
    ASSERT_LT(l.layer, layers.size());
    const bool outline = layers[l.layer].at("kind") == "outline";
    if (outline) {
      ++outline_modes[mode];
      EXPECT_EQ(mode, layers[l.layer].at("outline_mode").get<uint32_t>())
          << layers[l.layer].at("name");
    } else {
      ++corners[corner];
      EXPECT_EQ(mode, 0u);
    }
    if (mode != 0) {
      // Thesis §3.6: inset/offset need the miter corner style.
      EXPECT_EQ(corner, uint32_t(decal::CornerStyle::miter));
      if (l.style & decal::kStyleClosedBit) ++closed_inset_offset;
    }
    if (l.style & decal::kStyleClipBit) {
      ++clipped;
      EXPECT_NE(mode, 0u);
      EXPECT_LT(l.clip_node, nodes);
    }
  }
  std::printf(
      "[Monaco sample] %zu static lines; lines: round %zu, miter %zu, bevel %zu; outlines: normal "
      "%zu, "
      "inset %zu, offset %zu; %zu clipped of %zu closed inset/offset rings; package %ju bytes\n",
      props.size(), corners[0], corners[1], corners[2], outline_modes[0], outline_modes[1],
      outline_modes[2], clipped, closed_inset_offset, std::uintmax_t(fs::file_size(pkg)));
  for (int k = 0; k < 3; ++k) {
    EXPECT_GT(corners[size_t(k)], 0u) << "no line with corner style " << k;
    EXPECT_GT(outline_modes[size_t(k)], 0u) << "no outline with outline mode " << k;
  }
  EXPECT_GT(clipped, 0u);
  // Every closed inset/offset ring is clipped (zero-area rings would not be;
  // Monaco has none at 1 mm).
  EXPECT_EQ(clipped, closed_inset_offset);
}

}  // namespace
