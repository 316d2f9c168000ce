// The decalprep info / verify / dump commands, run as the real binary
// (DECALPREP_TOOL) on packages written by the writer and on every hostile
// variant.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "fixtures.hpp"
#include "test_support.hpp"

namespace {

namespace fs = std::filesystem;

using prep::test::ToolRun;

class Tool : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = decal_test::make_temp_dir("tool");
    model_ = decal_test::small_model();
    zstd_ = dir_ + "/small_zstd.decals";
    none_ = dir_ + "/small_none.decals";
    decal_test::write_file(zstd_, decal_test::model_package_bytes(model_, {prep::Codec::zstd, 3}));
    decal_test::write_file(none_, decal_test::model_package_bytes(model_, {prep::Codec::none, 0}));
  }
  void TearDown() override { fs::remove_all(dir_); }
  ToolRun run(const std::string& args) {
    return prep::test::run_tool(args, dir_, {.split_stderr = true});
  }

  std::string dir_, zstd_, none_;
  prep::DecalModel model_;
};

// The catalogue rows a v1.3 writer writes: every id but the superseded
// v1.2 layout (formats/SPEC.md "Compact layout (v1.3)").
std::vector<decal::BlobInfo> written_catalogue() {
  std::vector<decal::BlobInfo> out;
  for (const auto& b : decal::kBlobCatalogue)
    if (!decal::is_superseded(b.id)) out.push_back(b);
  return out;
}

TEST_F(Tool, InfoJsonParsesAndListsEveryBlob) {
  const ToolRun r = run("info --json '" + zstd_ + "'");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j.at("version").at("major"), decal::kVersionMajor);
  EXPECT_EQ(j.at("file_size"), fs::file_size(zstd_));
  EXPECT_EQ(j.at("metadata").at("format"), "decals");
  const auto& blobs = j.at("blobs");
  const std::vector<decal::BlobInfo> written = written_catalogue();
  ASSERT_EQ(blobs.size(), written.size());
  for (size_t i = 0; i < blobs.size(); ++i) {
    EXPECT_EQ(blobs[i].at("name"), written[i].name);
    EXPECT_EQ(blobs[i].at("id"), static_cast<uint32_t>(written[i].id));
    EXPECT_EQ(blobs[i].at("stride"), written[i].stride);
    EXPECT_EQ(blobs[i].at("codec"), "zstd");
    EXPECT_EQ(blobs[i].at("offset").get<uint64_t>() % 256, 0u);
  }
  EXPECT_EQ(blobs[0].at("count"), model_.line_vertices.size());
}

TEST_F(Tool, InfoTextShowsVersionAndEveryBlobName) {
  const ToolRun r = run("info '" + none_ + "'");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.output.find("version   " + std::to_string(decal::kVersionMajor) + "." +
                          std::to_string(decal::kVersionMinor)),
            std::string::npos)
      << r.output;
  for (const auto& b : written_catalogue())
    EXPECT_NE(r.output.find(std::string(b.name)), std::string::npos) << b.name;
}

TEST_F(Tool, VerifyAcceptsGoodPackages) {
  const ToolRun r = run("verify '" + zstd_ + "' '" + none_ + "'");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.output.find(zstd_ + ": ok"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(none_ + ": ok"), std::string::npos) << r.output;
  EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST_F(Tool, VerifyRejectsEachHostileCaseWithOneLineReason) {
  const auto good = decal_test::model_package_bytes(model_, {prep::Codec::zstd, 3});
  for (const auto& h : decal_test::hostile_variants(good)) {
    SCOPED_TRACE(h.name);
    const std::string path = dir_ + "/" + h.name + ".decals";
    decal_test::write_file(path, h.bytes);
    const ToolRun r = run("verify '" + path + "'");
    EXPECT_EQ(r.rc, 5);
    EXPECT_TRUE(r.output.empty()) << r.output;
    ASSERT_FALSE(r.err.empty());
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "reason is not one line: " << r.err;
    EXPECT_EQ(r.err.rfind(path + ": FAILED: ", 0), 0u) << r.err;
    EXPECT_NE(r.err.find(h.expect), std::string::npos) << r.err;
    // info refuses the structurally broken ones too (it skips blob checksums).
    if (!h.structure_valid && h.name.find("bit_flip_in_blob") == std::string::npos) {
      EXPECT_EQ(run("info --json '" + path + "'").rc, 5);
    }
  }
}

TEST_F(Tool, VerifyFailsWhenAnyOfSeveralPackagesIsBad) {
  decal_test::write_file(dir_ + "/empty.decals", {});
  const ToolRun r =
      run("verify '" + zstd_ + "' '" + dir_ + "/empty.decals' '" + dir_ + "/missing.decals'");
  EXPECT_EQ(r.rc, 5);
  EXPECT_NE(r.output.find(zstd_ + ": ok"), std::string::npos);
  EXPECT_NE(r.err.find("empty.decals: FAILED: empty file"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("missing.decals: FAILED: cannot open"), std::string::npos) << r.err;
}

TEST_F(Tool, VerifyCatchesMetadataCountsThatDisagreeWithTheBlobs) {
  const std::string path = dir_ + "/lying.decals";
  std::vector<std::array<int32_t, 4>> v = {{1, 2, 3, 4}, {5, 6, 7, 8}, {9, 10, 11, 12}};
  prep::BlobInput b{decal::BlobId::poly_bvh_box, decal::ElementType::ivec4, 16, 3,
                    std::as_bytes(std::span(v))};
  prep::write_package(path, R"({"format":"decals","counts":{"poly_bvh_box":4}})", {&b, 1});
  const ToolRun r = run("verify '" + path + "'");
  EXPECT_EQ(r.rc, 5);
  EXPECT_NE(r.err.find("counts.poly_bvh_box = 4"), std::string::npos) << r.err;
}

TEST_F(Tool, DumpTextIsTheSameForCompressedAndUncompressedPackages) {
  const ToolRun a = run("dump '" + zstd_ + "'");
  const ToolRun b = run("dump '" + none_ + "'");
  ASSERT_EQ(a.rc, 0) << a.err;
  ASSERT_EQ(b.rc, 0) << b.err;
  EXPECT_EQ(a.output, b.output);
}

TEST_F(Tool, DumpTextListsEveryElementOfTheModel) {
  const ToolRun r = run("dump '" + zstd_ + "'");
  ASSERT_EQ(r.rc, 0) << r.err;
  // Expected lines built from the model arrays, not from the reader.
  std::string expected = "blob line_vertices id=1 type=ivec2 stride=8 count=" +
                         std::to_string(model_.line_vertices.size()) + "\n";
  for (size_t i = 0; i < model_.line_vertices.size(); ++i)
    expected += "  [" + std::to_string(i) + "] " + std::to_string(model_.line_vertices[i][0]) +
                " " + std::to_string(model_.line_vertices[i][1]) + "\n";
  EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(
                "  [1] half_width=0.75 rgba=0x8000ff00 order=0 style=0x00000010 value=nan layer=1 "
                "feature=8 clip_node=0\n"),
            std::string::npos);
  for (const auto& b : written_catalogue())
    EXPECT_NE(r.output.find("blob " + std::string(b.name) + " id="), std::string::npos) << b.name;
}

TEST_F(Tool, DumpJsonGivesElementsAndPositionsInSceneMetres) {
  const ToolRun r = run("dump --json '" + zstd_ + "'");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.output);
  const auto& blobs = j.at("blobs");
  ASSERT_EQ(blobs.size(), written_catalogue().size());
  auto blob = [&](const std::string& name) -> const nlohmann::json& {
    for (const auto& b : blobs)
      if (b.at("name") == name) return b;
    throw std::runtime_error("no blob " + name);
  };
  const auto& lv = blob("line_vertices");
  ASSERT_EQ(lv.at("elements").size(), model_.line_vertices.size());
  for (size_t i = 0; i < model_.line_vertices.size(); ++i) {
    EXPECT_EQ(lv.at("elements")[i][0], model_.line_vertices[i][0]);
    EXPECT_DOUBLE_EQ(lv.at("scene_m")[i][0].get<double>(), model_.line_vertices[i][0] / 1000.0);
    EXPECT_DOUBLE_EQ(lv.at("scene_m")[i][1].get<double>(), model_.line_vertices[i][1] / 1000.0);
  }
  const auto& dv = blob("dyn_vertices");
  ASSERT_EQ(dv.at("scene_m")[0].size(), 3u);  // x, y, z; the line index is not a position
  EXPECT_DOUBLE_EQ(dv.at("scene_m")[0][2].get<double>(), 120.5);
  EXPECT_DOUBLE_EQ(blob("qt_node_box").at("scene_m")[0][2].get<double>(), 8.0);
  EXPECT_FALSE(blob("cell_segments").contains("scene_m"));
  EXPECT_EQ(blob("line_props").at("elements")[0].at("order"), 1);
  EXPECT_TRUE(blob("line_props").at("elements")[1].at("value").is_null());  // NaN
  EXPECT_EQ(blob("poly_props").at("elements")[1].at("exterior"), 0);
  EXPECT_EQ(blob("lod_segments").at("elements")[0].at("b"), 2);
}

TEST_F(Tool, DumpOfOneBlobAndOfAMissingBlob) {
  const ToolRun r = run("dump --json --blob cell_segments '" + none_ + "'");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = nlohmann::json::parse(r.output);
  ASSERT_EQ(j.at("blobs").size(), 1u);
  EXPECT_EQ(j.at("blobs")[0].at("elements"), nlohmann::json({{0, 1}, {1, 2}, {1, 2}, {3, 4}}));
  EXPECT_EQ(run("dump --blob no_such_blob '" + none_ + "'").rc, 2);
}

TEST_F(Tool, VersionAndHelpExitZero) {
  EXPECT_EQ(run("--version").rc, 0);
  const ToolRun h = run("--help");
  EXPECT_EQ(h.rc, 0);
  EXPECT_NE(h.output.find("verify"), std::string::npos);
  EXPECT_EQ(run("info").rc, 2);  // missing PACKAGE: usage error
}

}  // namespace
