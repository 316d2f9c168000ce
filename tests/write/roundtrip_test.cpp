// Round trip: write_package / write_model, then Package::open or
// from_memory, must give back every blob byte for byte, for every element
// type, empty and >64 MiB blobs, compressed and not, mapped and not.
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "decal/inspect.hpp"
#include "decal/layout.hpp"
#include "decal/reader.hpp"
#include "fixtures.hpp"
#include "prep/error.hpp"
#include "prep/manifest_json.hpp"
#include "prep/write.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace write_roundtrip {

namespace {

using decal::BlobId;
using decal::ElementType;
using decal_test::make_temp_dir;
using decal_test::read_file;

using decal_test::OwnedBlob;

// walk_blob (fixtures.hpp) with the blob id as a number, catalogue or not.
OwnedBlob make_blob(uint32_t id, ElementType type, uint32_t stride, uint64_t n, uint64_t seed) {
  return decal_test::walk_blob(static_cast<BlobId>(id), type, stride, n, seed);
}

// One blob of every element type: catalogue blobs for the types the
// catalogue uses, ids >= 1000 (unknown to the catalogue) for the rest.
std::vector<OwnedBlob> every_type_blobs() {
  std::vector<OwnedBlob> v;
  v.push_back(make_blob(1, ElementType::ivec2, 8, 1000, 1));  // line_vertices
  v.push_back(make_blob(2, ElementType::u32, 4, 1000, 2));    // line_vertex_line
  v.push_back(make_blob(3, ElementType::record, sizeof(decal::LineProps), 7, 3));  // line_props
  v.push_back(make_blob(5, ElementType::uvec2, 8, 0, 4));                          // empty
  v.push_back(make_blob(12, ElementType::ivec4, 16, 33, 5));                       // qt_node_box
  v.push_back(make_blob(18, ElementType::uvec4, 16, 9, 6));                        // cell_polys
  v.push_back(make_blob(1000, ElementType::u8, 1, 13, 7));
  v.push_back(make_blob(1001, ElementType::i32, 4, 100, 8));
  v.push_back(make_blob(1002, ElementType::f32, 4, 100, 9));
  v.push_back(make_blob(1003, ElementType::vec2, 8, 50, 10));
  v.push_back(make_blob(1004, ElementType::vec4, 16, 25, 11));
  v.push_back(make_blob(1005, ElementType::record, 12, 3, 12));
  v.push_back(make_blob(1006, ElementType::u8, 1, 0, 13));  // empty, unknown id
  return v;
}

using decal_test::inputs;

void expect_same_blobs(const decal::Package& p, const std::vector<OwnedBlob>& blobs) {
  ASSERT_EQ(p.blobs().size(), blobs.size());
  for (size_t i = 0; i < blobs.size(); ++i) {
    const decal::BlobView& v = p.blobs()[i];
    SCOPED_TRACE("blob id " + std::to_string(v.id));
    EXPECT_EQ(v.id, static_cast<uint32_t>(blobs[i].id));
    EXPECT_EQ(v.type, blobs[i].type);
    EXPECT_EQ(v.stride, blobs[i].stride);
    EXPECT_EQ(v.count, blobs[i].count());
    ASSERT_EQ(v.bytes.size(), blobs[i].bytes.size());
    EXPECT_TRUE(std::equal(v.bytes.begin(), v.bytes.end(), blobs[i].bytes.begin()));
    EXPECT_EQ(reinterpret_cast<uintptr_t>(v.bytes.data()) % 4, 0u);
    if (const decal::BlobInfo* info = decal::find_blob_info(blobs[i].id))
      EXPECT_EQ(v.name, info->name);
    else
      EXPECT_EQ(v.name, "blob_" + std::to_string(v.id));
  }
}

enum class ReadPath { mmap, read, memory };

struct Case {
  prep::Codec codec;
  ReadPath path;
};

class RoundTrip : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override { dir_ = make_temp_dir("roundtrip"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  decal::Package write_and_read(const std::vector<OwnedBlob>& blobs) {
    const std::string path = dir_ + "/p.decals";
    prep::WriteOptions wo;
    wo.codec = GetParam().codec;
    wo.zstd_level = 1;
    prep::write_package(path, R"({"format":"decals"})", inputs(blobs), wo);
    decal::Package p;
    decal::OpenOptions oo;
    oo.allow_mmap = GetParam().path == ReadPath::mmap;
    decal::Status s = GetParam().path == ReadPath::memory
                          ? decal::Package::from_memory(read_file(path), p, oo)
                          : decal::Package::open(path, p, oo);
    EXPECT_TRUE(s) << s.message;
    const bool mapped = GetParam().path == ReadPath::mmap && GetParam().codec == prep::Codec::none;
    EXPECT_EQ(p.memory_mapped(), mapped);
    EXPECT_EQ(p.metadata_json(), R"({"format":"decals"})");
    EXPECT_EQ(p.major(), decal::kVersionMajor);
    EXPECT_EQ(p.minor(), decal::kVersionMinor);
    EXPECT_EQ((p.flags() & decal::kFlagAllUncompressed) != 0,
              GetParam().codec == prep::Codec::none);
    return p;
  }

  std::string dir_;
};

TEST_P(RoundTrip, EveryElementTypeAndEmptyBlobsComeBackByteForByte) {
  const auto blobs = every_type_blobs();
  decal::Package p = write_and_read(blobs);
  expect_same_blobs(p, blobs);
  // Typed access agrees with the raw bytes.
  auto verts = p.array<BlobId::line_vertices>();
  ASSERT_EQ(verts.size(), 1000u);
  int32_t first[2];
  std::memcpy(first, blobs[0].bytes.data(), 8);
  EXPECT_EQ(verts[0][0], first[0]);
  EXPECT_EQ(verts[0][1], first[1]);
  ASSERT_NE(p.find(BlobId::cell_segment_range), nullptr);
  EXPECT_EQ(p.find(BlobId::cell_segment_range)->count, 0u);
  EXPECT_EQ(p.find(BlobId::poly_props), nullptr);
}

TEST_P(RoundTrip, BlobLargerThan64MiBRawComesBackByteForByte) {
  // 9 Mi ivec2 elements = 72 MiB raw.
  std::vector<OwnedBlob> blobs;
  blobs.push_back(make_blob(1, ElementType::ivec2, 8, uint64_t(9) << 20, 42));
  blobs.push_back(make_blob(2, ElementType::u32, 4, 10, 43));
  ASSERT_GT(blobs[0].bytes.size(), uint64_t(64) << 20);
  decal::Package p = write_and_read(blobs);
  expect_same_blobs(p, blobs);
}

INSTANTIATE_TEST_SUITE_P(CodecsAndReadPaths, RoundTrip,
                         ::testing::Values(Case{prep::Codec::none, ReadPath::mmap},
                                           Case{prep::Codec::none, ReadPath::read},
                                           Case{prep::Codec::none, ReadPath::memory},
                                           Case{prep::Codec::zstd, ReadPath::mmap},
                                           Case{prep::Codec::zstd, ReadPath::read},
                                           Case{prep::Codec::zstd, ReadPath::memory}),
                         [](const auto& param_info) {
                           const char* c =
                               param_info.param.codec == prep::Codec::none ? "none" : "zstd";
                           const char* r = param_info.param.path == ReadPath::mmap   ? "mmap"
                                           : param_info.param.path == ReadPath::read ? "read"
                                                                                     : "memory";
                           return std::string(c) + "_" + r;
                         });

TEST(WritePackage, SameInputGivesIdenticalFileBytes) {
  const std::string dir = make_temp_dir("determinism");
  const auto blobs = every_type_blobs();
  for (prep::Codec codec : {prep::Codec::none, prep::Codec::zstd}) {
    prep::WriteOptions wo;
    wo.codec = codec;
    prep::write_package(dir + "/a.decals", "{}", inputs(blobs), wo);
    prep::write_package(dir + "/b.decals", "{}", inputs(blobs), wo);
    EXPECT_EQ(read_file(dir + "/a.decals"), read_file(dir + "/b.decals"));
  }
  std::filesystem::remove_all(dir);
}

TEST(WritePackage, ZstdActuallyCompressesAndHigherLevelsAreNotLarger) {
  const std::string dir = make_temp_dir("levels");
  std::vector<OwnedBlob> blobs;
  blobs.push_back(make_blob(1, ElementType::ivec2, 8, 200000, 5));
  uint64_t prev = UINT64_MAX;
  for (int level : {1, 9, 19}) {
    prep::WriteOptions wo{prep::Codec::zstd, level};
    prep::write_package(dir + "/p.decals", "{}", inputs(blobs), wo);
    const uint64_t size = std::filesystem::file_size(dir + "/p.decals");
    EXPECT_LT(size, blobs[0].bytes.size()) << "level " << level;
    EXPECT_LE(size, prev) << "level " << level;
    prev = size;
  }
  std::filesystem::remove_all(dir);
}

TEST(WritePackage, BlobsStartOn256ByteBoundaries) {
  const std::string dir = make_temp_dir("align");
  const auto blobs = every_type_blobs();
  prep::write_package(dir + "/p.decals", "{}", inputs(blobs), {prep::Codec::none, 0});
  const auto bytes = read_file(dir + "/p.decals");
  decal::PackageLayout layout;
  ASSERT_TRUE(decal::read_layout(bytes, layout));
  for (const auto& e : layout.entries) EXPECT_EQ(e.offset % 256, 0u) << e.name;
  std::filesystem::remove_all(dir);
}

TEST(WritePackage, RejectsInputsThatDisagreeWithTheCatalogue) {
  const std::string dir = make_temp_dir("reject");
  std::vector<std::byte> bytes(16);
  // line_vertices is ivec2/8 in the catalogue.
  prep::BlobInput wrong_type{BlobId::line_vertices, ElementType::uvec4, 16, 1, bytes};
  EXPECT_THROW(prep::write_package(dir + "/p.decals", "{}", {&wrong_type, 1}), prep::output_error);
  prep::BlobInput wrong_size{BlobId::line_vertices, ElementType::ivec2, 8, 3, bytes};
  EXPECT_THROW(prep::write_package(dir + "/p.decals", "{}", {&wrong_size, 1}), prep::output_error);
  prep::BlobInput twice[2] = {{BlobId::line_vertices, ElementType::ivec2, 8, 2, bytes},
                              {BlobId::line_vertices, ElementType::ivec2, 8, 2, bytes}};
  EXPECT_THROW(prep::write_package(dir + "/p.decals", "{}", twice), prep::output_error);
  EXPECT_THROW(prep::write_package(dir + "/p.decals", "not json", {}), prep::output_error);
  EXPECT_FALSE(std::filesystem::exists(dir + "/p.decals"));
  std::filesystem::remove_all(dir);
}

// ------------------------------------------------------------ write_model --

template <class T>
void expect_blob_equals(const decal::Package& p, BlobId id, const std::vector<T>& expected) {
  const decal::BlobView* b = p.find(id);
  ASSERT_NE(b, nullptr) << decal::find_blob_info(id)->name;
  ASSERT_EQ(b->count, expected.size()) << b->name;
  EXPECT_EQ(std::memcmp(b->bytes.data(), expected.data(), b->bytes.size()), 0) << b->name;
}

TEST(WriteModel, EveryModelArrayBecomesItsCatalogueBlobInCatalogueOrder) {
  const prep::DecalModel m = decal_test::small_model();
  const auto bytes = decal_test::model_package_bytes(m, {});
  decal::Package p;
  ASSERT_TRUE(decal::Package::from_memory(bytes, p));
  // Every catalogue blob but the v1.2 layout that v1.3 replaced.
  std::vector<uint32_t> written;
  for (const auto& b : decal::kBlobCatalogue)
    if (!decal::is_superseded(b.id)) written.push_back(static_cast<uint32_t>(b.id));
  ASSERT_EQ(p.blobs().size(), written.size());
  for (size_t i = 0; i < p.blobs().size(); ++i) EXPECT_EQ(p.blobs()[i].id, written[i]);
  expect_blob_equals(p, BlobId::line_vertices, m.line_vertices);
  expect_blob_equals(p, BlobId::line_vertex_line, m.line_vertex_line);
  expect_blob_equals(p, BlobId::line_props, m.line_props);
  expect_blob_equals(p, BlobId::line_corners, m.line_corners);
  expect_blob_equals(p, BlobId::cell_segments, m.cell_segments);
  expect_blob_equals(p, BlobId::poly_props, m.poly_props);
  expect_blob_equals(p, BlobId::poly_root_node, m.poly_root_node);
  expect_blob_equals(p, BlobId::qt_node_box, m.qt_node_box);
  expect_blob_equals(p, BlobId::qt_node, m.qt_node);
  expect_blob_equals(p, BlobId::qt_leaf_vertices, m.qt_leaf_vertices);
  expect_blob_equals(p, BlobId::cell_holes, m.cell_holes);
  expect_blob_equals(p, BlobId::cell_line_first, m.cell_line_first);
  expect_blob_equals(p, BlobId::line_bvh_box16, m.line_bvh_box16);
  expect_blob_equals(p, BlobId::cell_poly_first, m.cell_poly_first);
  expect_blob_equals(p, BlobId::poly_bvh_box16, m.poly_bvh_box16);
  expect_blob_equals(p, BlobId::cell_poly_entries, m.cell_poly_entries);
  expect_blob_equals(p, BlobId::cell_poly_holes, m.cell_poly_holes);
  expect_blob_equals(p, BlobId::qt_leaf_loop_range, m.qt_leaf_loop_range);
  expect_blob_equals(p, BlobId::qt_leaf_loops, m.qt_leaf_loops);
  // The compact blobs decode to the fixture's v1.2 ranges and boxes
  // (decal/layout.hpp).
  const prep::test::V12Cells want = decal_test::small_model_cells();
  namespace L = decal::layout;
  std::vector<L::u2> range;
  std::vector<L::u4> bvh;
  L::decode_cells(p.array<BlobId::cell_line_first>(), range, bvh);
  EXPECT_EQ(range, want.segment_range);
  EXPECT_EQ(bvh, want.line_bvh_range);
  L::decode_cells(p.array<BlobId::cell_poly_first>(), range, bvh);
  EXPECT_EQ(range, want.poly_range);
  EXPECT_EQ(bvh, want.poly_bvh_range);
  std::vector<L::u4> cell_polys;
  L::decode_poly_entries(p.array<BlobId::cell_poly_entries>(), p.array<BlobId::cell_poly_holes>(),
                         cell_polys);
  EXPECT_EQ(cell_polys, want.cell_polys);
  const L::CellGrid cg{m.grid.origin_x, m.grid.origin_y, m.grid.cell_w, m.grid.cell_h, m.grid.nx};
  ASSERT_EQ(L::box16_shift(m.grid.cell_w, m.grid.cell_h), 0u);
  const auto first = p.array<BlobId::cell_line_first>();
  const auto boxes = L::decode_boxes16(first, p.array<BlobId::line_bvh_box16>(), cg);
  ASSERT_EQ(boxes.size(), want.line_bvh_box.size());
  for (size_t c = 0; c + 1 < first.size(); ++c)
    for (uint32_t i = first[c][1]; i < first[c + 1][1]; ++i) {
      // The full box clipped to the cell grown by one quantum.
      const int64_t cx = m.grid.origin_x + int64_t(c % m.grid.nx) * m.grid.cell_w - 1,
                    cy = m.grid.origin_y + int64_t(c / m.grid.nx) * m.grid.cell_h - 1;
      const auto& b = want.line_bvh_box[i];
      if (b[0] > b[2]) {
        EXPECT_GT(boxes[i][0], boxes[i][2]);
        continue;
      }
      const std::array<int32_t, 4> box{int32_t(std::max<int64_t>(b[0], cx)),
                                       int32_t(std::max<int64_t>(b[1], cy)),
                                       int32_t(std::min<int64_t>(b[2], cx + m.grid.cell_w + 2)),
                                       int32_t(std::min<int64_t>(b[3], cy + m.grid.cell_h + 2))};
      EXPECT_EQ(boxes[i], box) << "node " << i << " of cell " << c;
    }
  expect_blob_equals(p, BlobId::dyn_vertices, m.dyn_vertices);
  expect_blob_equals(p, BlobId::dyn_prev_next, m.dyn_prev_next);
  expect_blob_equals(p, BlobId::dyn_line_start, m.dyn_line_start);
  expect_blob_equals(p, BlobId::dyn_line_props, m.dyn_line_props);
  expect_blob_equals(p, BlobId::lod_points, m.lod_points);
  expect_blob_equals(p, BlobId::lod_segments, m.lod_segments);
  expect_blob_equals(p, BlobId::lod_line_range, m.lod_line_range);
  EXPECT_TRUE(decal::validate_indices(p)) << decal::validate_indices(p).message;
}

TEST(WriteModel, EmptyModelStillListsEveryBlob) {
  const auto bytes = decal_test::model_package_bytes(prep::DecalModel{}, {});
  decal::Package p;
  ASSERT_TRUE(decal::Package::from_memory(bytes, p));
  ASSERT_EQ(p.blobs().size(),
            std::size(decal::kBlobCatalogue) - std::size(decal::kSupersededBlobs));
  for (const auto& b : p.blobs()) {
    if (b.id == static_cast<uint32_t>(decal::BlobId::manifest_entries)) {
      // An empty manifest is still a JSON array.
      EXPECT_EQ(std::string(reinterpret_cast<const char*>(b.bytes.data()), b.count), "[]");
    } else {
      EXPECT_EQ(b.count, 0u) << b.name;
    }
  }
}

TEST(WriteModel, MetadataCarriesFrameGridCountsManifestAndExtraKeys) {
  const prep::DecalModel m = decal_test::small_model();
  const auto bytes = decal_test::model_package_bytes(
      m, {},
      R"({"build":{"threads":2},"provenance":{"inputs":[{"path":"a.shp","xxh64":"00ff"}]}})");
  decal::Package p;
  ASSERT_TRUE(decal::Package::from_memory(bytes, p));
  const auto j = nlohmann::json::parse(p.metadata_json());
  EXPECT_EQ(j.at("format"), "decals");
  EXPECT_DOUBLE_EQ(j.at("quantum_m").get<double>(), 0.001);
  EXPECT_EQ(j.at("crs_wkt"), m.frame.crs_wkt);
  EXPECT_EQ(j.at("frame"), m.frame.description);
  EXPECT_DOUBLE_EQ(j.at("origin").at("x").get<double>(), m.frame.origin_x);
  EXPECT_DOUBLE_EQ(j.at("origin").at("y").get<double>(), m.frame.origin_y);
  EXPECT_EQ(j.at("extent"), nlohmann::json({-10.0, -5.0, 10.0, 5.0}));
  EXPECT_EQ(j.at("grid").at("origin"), nlohmann::json({-10000, -5000}));
  EXPECT_EQ(j.at("grid").at("cell"), nlohmann::json({10000, 10000}));
  EXPECT_EQ(j.at("grid").at("dims"), nlohmann::json({2, 1}));
  EXPECT_DOUBLE_EQ(j.at("max_representation_error_m").get<double>(), 0.0004);
  EXPECT_DOUBLE_EQ(j.at("terrain").at("min").get<double>(), 99.0);
  EXPECT_DOUBLE_EQ(j.at("terrain").at("max").get<double>(), 130.25);
  EXPECT_EQ(j.at("counts").at("line_vertices"), m.line_vertices.size());
  EXPECT_EQ(j.at("counts").at("lines"), m.line_props.size());
  EXPECT_EQ(j.at("counts").at("polygons"), m.poly_props.size());
  EXPECT_EQ(j.at("manifest").at("layers").at(0).at("dropped"), 1);
  EXPECT_FALSE(j.at("manifest").contains("entries"));  // they live in their own blob
  EXPECT_EQ(j.at("manifest").at("entry_count"), m.manifest.entries.size());
  const decal::BlobView* eb = p.find(decal::BlobId::manifest_entries);
  ASSERT_NE(eb, nullptr);
  const auto entries = nlohmann::json::parse(
      std::string(reinterpret_cast<const char*>(eb->bytes.data()), eb->count));
  ASSERT_EQ(entries.size(), m.manifest.entries.size());
  EXPECT_EQ(entries.at(0).at("fid"), 17);
  EXPECT_TRUE(entries.at(0).at("area_before").is_null());
  EXPECT_EQ(j.at("manifest").at("notes").at(0), "flat terrain");
  EXPECT_EQ(j.at("build").at("threads"), 2);
  EXPECT_EQ(j.at("provenance").at("inputs").at(0).at("path"), "a.shp");
}

// The manifest's enums are written as the words formats/SPEC.md "Manifest
// entries" lists (literals here, from the SPEC tables), and read back.
TEST(ManifestEntryJson, WordsAreThoseOfTheSpecAndReadBack) {
  prep::ManifestEntry failed{"roads", 7, -1, prep::ManifestAction::dropped, "vertex 1 is NaN"};
  failed.failed_in = prep::FailureStage::project;
  const nlohmann::json j = prep::manifest_entry_json(failed);
  EXPECT_EQ(j.at("action"), "dropped");
  EXPECT_EQ(j.at("reason"), "failed in project: vertex 1 is NaN");
  const prep::ManifestEntry back = prep::manifest_entry_from_json(j);
  EXPECT_EQ(back.action, prep::ManifestAction::dropped);
  ASSERT_TRUE(back.failed_in.has_value());
  EXPECT_EQ(*back.failed_in, prep::FailureStage::project);
  EXPECT_EQ(back.reason, "vertex 1 is NaN");
  EXPECT_EQ(prep::manifest_entry_json(back), j);

  const std::pair<prep::ManifestAction, const char*> actions[] = {
      {prep::ManifestAction::repaired, "repaired"},
      {prep::ManifestAction::part_dropped, "part_dropped"},
      {prep::ManifestAction::dropped, "dropped"},
      {prep::ManifestAction::clipped_away, "clipped_away"},
      {prep::ManifestAction::note, "note"}};
  for (const auto& [a, w] : actions) {
    prep::ManifestEntry e{"l", 1, 0, a, "why", 2.5, 3.0};
    const nlohmann::json je = prep::manifest_entry_json(e);
    EXPECT_EQ(je.at("action"), w);
    EXPECT_EQ(je.at("reason"), "why");
    const prep::ManifestEntry eb = prep::manifest_entry_from_json(je);
    EXPECT_EQ(eb.action, a) << w;
    EXPECT_FALSE(eb.failed_in.has_value()) << w;
    EXPECT_DOUBLE_EQ(eb.area_after, 3.0);
  }
  const std::pair<prep::FailureStage, const char*> stages[] = {
      {prep::FailureStage::read, "failed in read: x: y"},
      {prep::FailureStage::project, "failed in project: x: y"},
      {prep::FailureStage::clean, "failed in clean: x: y"},
      {prep::FailureStage::build, "failed in build: x: y"}};
  for (const auto& [st, w] : stages) {
    prep::ManifestEntry e{"l", 1, -1, prep::ManifestAction::dropped, "x: y"};
    e.failed_in = st;
    EXPECT_EQ(prep::manifest_entry_json(e).at("reason"), w);
    EXPECT_EQ(prep::manifest_entry_from_json(prep::manifest_entry_json(e)).failed_in, st) << w;
  }
  // A reason that merely starts like a failure, with no stage of the SPEC,
  // stays free text.
  nlohmann::json odd = j;
  odd["reason"] = "failed in style: no colour";
  EXPECT_FALSE(prep::manifest_entry_from_json(odd).failed_in.has_value());
  EXPECT_EQ(prep::manifest_entry_from_json(odd).reason, "failed in style: no colour");
  odd["action"] = "vanished";
  EXPECT_THROW(prep::manifest_entry_from_json(odd), prep::format_error);
}

TEST(WriteModel, ExtraMetadataThatOverridesAModelKeyIsRejected) {
  const std::string dir = make_temp_dir("conflict");
  EXPECT_THROW(prep::write_model(dir + "/p.decals", prep::DecalModel{}, R"({"format":"x"})"),
               prep::output_error);
  EXPECT_THROW(prep::write_model(dir + "/p.decals", prep::DecalModel{}, R"([1,2])"),
               prep::output_error);
  EXPECT_THROW(prep::write_model(dir + "/p.decals", prep::DecalModel{}, R"({"a":)"),
               prep::output_error);
  EXPECT_FALSE(std::filesystem::exists(dir + "/p.decals"));
  std::filesystem::remove_all(dir);
}

}  // namespace

// write_model of an rvalue model frees each array once its blob is
// compressed (libprep/pipeline passes its model so): the file must be the
// same bytes as writing the model it was, compressed or stored, and the
// model's blob arrays are taken.
TEST(WriteModel, ConsumingTheModelWritesTheSameBytesAndTakesItsArrays) {
  for (const prep::WriteOptions& o :
       {prep::WriteOptions{prep::Codec::zstd, 3}, prep::WriteOptions{prep::Codec::none, 0}}) {
    const prep::DecalModel m = decal_test::small_model();
    const auto want = decal_test::model_package_bytes(m, o);
    const std::string dir = decal_test::make_temp_dir("consume");
    prep::DecalModel taken = m;
    prep::write_model(dir + "/p.decals", std::move(taken), "", o);
    EXPECT_TRUE(decal_test::read_file(dir + "/p.decals") == want);
    std::filesystem::remove_all(dir);
    // What write_model left of the model it took is the point of the test.
    // NOLINTNEXTLINE(bugprone-use-after-move)
    EXPECT_TRUE(taken.qt_leaf_vertices.empty() && taken.cell_poly_first.empty() &&
                taken.line_vertices.empty() && taken.lod_points.empty());
    EXPECT_EQ(taken.grid.nx, m.grid.nx);  // not a blob: kept
    EXPECT_EQ(taken.manifest.notes, m.manifest.notes);
  }
}

}  // namespace write_roundtrip
