// Hostile inputs: the reader must return a clear failure status, never
// crash, never read out of bounds (run under ASan+UBSan), for every
// truncated prefix, every single-bit flip and each crafted hostile case (fixtures.hpp).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <functional>

#include "byte_damage.hpp"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "fixtures.hpp"
#include "prep/write.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace formats_reader_hostile {

namespace {

using decal_test::entry_at;
using decal_test::get;
using decal_test::put;
using decal_test::reseal;
using H = decal::FileHeader;
using E = decal::BlobTableEntry;

// A deliberately small package (3 short blobs, short metadata), so that
// every bit of it can be flipped in a few seconds.
std::vector<std::byte> tiny_package(prep::Codec codec) {
  const std::string dir = decal_test::make_temp_dir("tiny");
  std::vector<std::array<int32_t, 2>> verts = {{1, 2}, {300, -400}, {5000, 6000}, {-7, 8}};
  std::vector<uint32_t> line = {0, 0, 1, 1};
  std::vector<decal::LineProps> props = {{1.0f, 0xff0000ffu, 0, 0, 0.5f, 0, 0, 0},
                                         {2.0f, 0xff00ff00u, 1, 1, 1.5f, 0, 1, 0}};
  std::vector<prep::BlobInput> blobs = {
      {decal::BlobId::line_vertices, decal::ElementType::ivec2, 8, verts.size(),
       std::as_bytes(std::span(verts))},
      {decal::BlobId::line_vertex_line, decal::ElementType::u32, 4, line.size(),
       std::as_bytes(std::span(line))},
      {decal::BlobId::line_props, decal::ElementType::record, 32, props.size(),
       std::as_bytes(std::span(props))},
  };
  prep::write_package(dir + "/t.decals", R"({"format":"decals"})", blobs, {codec, 3});
  auto bytes = decal_test::read_file(dir + "/t.decals");
  std::filesystem::remove_all(dir);
  return bytes;
}

decal::Status open_bytes(const std::vector<std::byte>& b, const decal::OpenOptions& o = {}) {
  decal::Package p;
  return decal::Package::from_memory(b, p, o);
}

// Opens a copy of `b` resealed (fixtures.hpp), so that the structural check,
// not a checksum, is what must reject the edit made to `b`.
decal::Status open_resealed(std::vector<std::byte> b) {
  reseal(b);
  return open_bytes(b);
}

class Hostile : public ::testing::TestWithParam<prep::Codec> {};

TEST_P(Hostile, EveryTruncatedPrefixIsRejectedWithAMessage) {
  const auto good = tiny_package(GetParam());
  ASSERT_TRUE(open_bytes(good));
  for (size_t n = 0; n < good.size(); ++n) {
    std::vector<std::byte> prefix(good.begin(), good.begin() + static_cast<long>(n));
    const decal::Status s = open_bytes(prefix);
    ASSERT_FALSE(s) << "prefix of " << n << " bytes was accepted";
    ASSERT_FALSE(s.message.empty());
    ASSERT_EQ(s.message.find('\n'), std::string::npos) << s.message;
  }
}

TEST_P(Hostile, EverySingleBitFlipIsRejected) {
  const auto good = tiny_package(GetParam());
  ASSERT_TRUE(open_bytes(good));
  EXPECT_TRUE(prep::test::every_bit_flip_rejected(good, good.size(), [](const auto& bytes) {
    const decal::Status s = open_bytes(bytes);
    if (s) return ::testing::AssertionFailure() << "opened";
    if (s.message.empty()) return ::testing::AssertionFailure() << "with no message";
    return ::testing::AssertionSuccess();
  }));
}

TEST_P(Hostile, EverySingleBitFlipOfAFullModelPackageIsRejected) {
  // Every blob of the catalogue, a real metadata chunk: ~11 KB, ~86k flips.
  const auto good = decal_test::model_package_bytes(decal_test::small_model(), {GetParam(), 3});
  ASSERT_TRUE(open_bytes(good));
  size_t flips = 0;
  EXPECT_TRUE(prep::test::every_bit_flip_rejected(
      good, good.size(),
      [](const auto& bytes) {
        return open_bytes(bytes) ? ::testing::AssertionFailure() << "opened"
                                 : ::testing::AssertionSuccess();
      },
      &flips));
  EXPECT_EQ(flips, good.size() * 8);
}

TEST_P(Hostile, EveryTruncatedPrefixOfAFileIsRejectedByOpenToo) {
  // Through the mmap path as well: a few prefixes written to disk.
  const auto good = tiny_package(GetParam());
  const std::string dir = decal_test::make_temp_dir("prefix");
  for (size_t n :
       {size_t(0), size_t(7), size_t(95), size_t(96), good.size() / 2, good.size() - 1}) {
    decal_test::write_file(dir + "/p.decals", {good.begin(), good.begin() + static_cast<long>(n)});
    decal::Package p;
    const decal::Status s = decal::Package::open(dir + "/p.decals", p);
    EXPECT_FALSE(s) << n;
    EXPECT_NE(s.message.find(dir + "/p.decals"), std::string::npos) << s.message;
    EXPECT_TRUE(p.blobs().empty());
  }
  std::filesystem::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Codecs, Hostile, ::testing::Values(prep::Codec::none, prep::Codec::zstd),
                         [](const auto& p) {
                           return p.param == prep::Codec::none ? "none" : "zstd";
                         });

TEST(HostileVariants, EachIsRejectedWithTheRightMessage) {
  const auto good =
      decal_test::model_package_bytes(decal_test::small_model(), {prep::Codec::zstd, 3});
  decal::Package ok;
  ASSERT_TRUE(decal::Package::from_memory(good, ok));
  ASSERT_TRUE(decal::validate_indices(ok)) << decal::validate_indices(ok).message;
  const auto variants = decal_test::hostile_variants(good);
  ASSERT_GE(variants.size(), 15u);
  for (const auto& h : variants) {
    SCOPED_TRACE(h.name);
    decal::Package p;
    decal::Status s = decal::Package::from_memory(h.bytes, p);
    if (h.structure_valid) {
      ASSERT_TRUE(s) << s.message;
      s = decal::validate_indices(p);
    }
    ASSERT_FALSE(s);
    EXPECT_NE(s.message.find(h.expect), std::string::npos) << s.message;
  }
}

TEST(HostileVariants, UnknownMajorVersionMessageNamesTheVersion) {
  auto b = tiny_package(prep::Codec::zstd);
  put<uint16_t>(b, offsetof(H, version_major), 7);
  reseal(b);
  const decal::Status s = open_bytes(b);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message.find("major version 7"), std::string::npos) << s.message;
  // Even without resealing (a newer major may checksum differently).
  put<uint16_t>(b, offsetof(H, version_major), 300);
  EXPECT_NE(open_bytes(b).message.find("major version 300"), std::string::npos);
}

TEST(HostileVariants, NewerMinorVersionIsReadAndMayUseReservedFields) {
  auto b = tiny_package(prep::Codec::zstd);
  put<uint16_t>(b, offsetof(H, version_minor), decal::kVersionMinor + 1);
  put<uint64_t>(b, offsetof(H, reserved1), 42);
  put<uint32_t>(b, offsetof(H, flags), 1u << 20);  // an optional flag we do not know
  reseal(b);
  decal::Package p;
  const decal::Status s = decal::Package::from_memory(b, p);
  ASSERT_TRUE(s) << s.message;
  EXPECT_EQ(p.minor(), decal::kVersionMinor + 1);
  // The same in a file of our own minor version is rejected.
  put<uint16_t>(b, offsetof(H, version_minor), decal::kVersionMinor);
  reseal(b);
  EXPECT_FALSE(open_bytes(b));
}

TEST(HostileVariants, NonzeroReservedFieldsAreRejected) {
  const auto good = tiny_package(prep::Codec::none);
  auto b = good;
  put<uint32_t>(b, offsetof(H, reserved0), 1);
  EXPECT_NE(open_resealed(b).message.find("reserved"), std::string::npos);
  b = good;
  put<uint32_t>(b, entry_at(1) + offsetof(E, reserved), 1);
  EXPECT_NE(open_resealed(b).message.find("reserved"), std::string::npos);
}

TEST(HostileVariants, CountAndStrideCannotOverflowEvenWhenRawSizeAgrees) {
  auto b = tiny_package(prep::Codec::none);
  // count * 8 wraps to exactly the stored 32 bytes: must still be caught.
  put<uint64_t>(b, entry_at(0) + offsetof(E, count), (uint64_t(1) << 61) + 4);
  const decal::Status s = open_resealed(b);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message.find("overflows uint64"), std::string::npos) << s.message;
}

TEST(HostileVariants, ImplausibleRawSizeIsRefusedBeforeAllocating) {
  auto b = tiny_package(prep::Codec::zstd);
  // Claim 2^40 elements: far more than any zstd frame of this size holds.
  put<uint64_t>(b, entry_at(1) + offsetof(E, count), uint64_t(1) << 40);
  put<uint64_t>(b, entry_at(1) + offsetof(E, raw_size), uint64_t(4) << 40);
  const decal::Status s = open_resealed(b);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message.find("cannot come from"), std::string::npos) << s.message;
}

TEST(HostileVariants, ZstdFrameThatDisagreesWithRawSizeIsRejected) {
  auto b = tiny_package(prep::Codec::zstd);
  put<uint64_t>(b, entry_at(1) + offsetof(E, count), 5);
  put<uint64_t>(b, entry_at(1) + offsetof(E, raw_size), 20);
  const decal::Status s = open_resealed(b);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message.find("content size"), std::string::npos) << s.message;
}

TEST(HostileVariants, InflationBeyondTheLimitIsRefused) {
  const auto b = tiny_package(prep::Codec::zstd);
  decal::OpenOptions o;
  o.max_raw_bytes = 40;
  const decal::Status s = open_bytes(b, o);
  ASSERT_FALSE(s);
  EXPECT_NE(s.message.find("max_raw_bytes"), std::string::npos) << s.message;
}

TEST(HostileVariants, DuplicateBlobIdsAreRejected) {
  auto b = tiny_package(prep::Codec::none);
  // Make entry 1 claim entry 0's identity (type, stride and name agree).
  const uint64_t off = get<uint64_t>(b, entry_at(1) + offsetof(E, offset));
  std::memcpy(b.data() + entry_at(1), b.data() + entry_at(0), sizeof(E));
  put<uint64_t>(b, entry_at(1) + offsetof(E, offset), off);
  put<uint64_t>(b, entry_at(1) + offsetof(E, count), 4);
  put<uint64_t>(b, entry_at(1) + offsetof(E, raw_size), 32);
  put<uint64_t>(b, entry_at(1) + offsetof(E, stored_size), 32);
  const decal::Status s = open_resealed(b);
  EXPECT_NE(s.message.find("duplicate"), std::string::npos) << s.message;
}

TEST(Reader, ZeroLengthDirectoryAndMissingFilesAreRejected) {
  const std::string dir = decal_test::make_temp_dir("files");
  decal_test::write_file(dir + "/empty.decals", {});
  decal::Package p;
  decal::Status s = decal::Package::open(dir + "/empty.decals", p);
  EXPECT_FALSE(s);
  EXPECT_NE(s.message.find("empty file"), std::string::npos) << s.message;
  s = decal::Package::open(dir, p);
  EXPECT_FALSE(s);
  EXPECT_NE(s.message.find("not a regular file"), std::string::npos) << s.message;
  s = decal::Package::open(dir + "/missing.decals", p);
  EXPECT_FALSE(s);
  EXPECT_NE(s.message.find("cannot open"), std::string::npos) << s.message;
  std::filesystem::remove_all(dir);
}

TEST(Reader, MisalignedInputBufferIsReadCorrectly) {
  const auto good = tiny_package(prep::Codec::none);
  std::vector<std::byte> shifted(good.size() + 1);
  std::memcpy(shifted.data() + 1, good.data(), good.size());
  decal::Package p;
  ASSERT_TRUE(decal::Package::from_memory(std::span(shifted).subspan(1), p));
  const auto verts = p.array<decal::BlobId::line_vertices>();
  ASSERT_EQ(verts.size(), 4u);
  EXPECT_EQ(verts[1][0], 300);
  EXPECT_EQ(verts[1][1], -400);
}

TEST(Reader, UnknownBlobIdsAreListedAndDoNotDisturbKnownOnes) {
  const std::string dir = decal_test::make_temp_dir("unknown");
  std::vector<uint32_t> a = {1, 2, 3}, c = {9};
  std::vector<std::byte> u(5, std::byte{7});
  std::vector<prep::BlobInput> blobs = {
      {decal::BlobId::line_vertex_line, decal::ElementType::u32, 4, 3, std::as_bytes(std::span(a))},
      {static_cast<decal::BlobId>(999), decal::ElementType::u8, 1, 5, u},
      {decal::BlobId::poly_root_node, decal::ElementType::u32, 4, 1, std::as_bytes(std::span(c))},
  };
  prep::write_package(dir + "/u.decals", "{}", blobs);
  decal::Package p;
  ASSERT_TRUE(decal::Package::open(dir + "/u.decals", p));
  ASSERT_EQ(p.blobs().size(), 3u);
  EXPECT_FALSE(p.blobs()[1].known());
  EXPECT_EQ(p.blobs()[1].name, "blob_999");
  EXPECT_EQ(p.array<decal::BlobId::poly_root_node>()[0], 9u);
  std::filesystem::remove_all(dir);
}

TEST(Reader, PackageOfSmallModelPassesIndexValidation) {
  for (prep::Codec codec : {prep::Codec::none, prep::Codec::zstd}) {
    const auto b = decal_test::model_package_bytes(decal_test::small_model(), {codec, 3});
    decal::Package p;
    ASSERT_TRUE(decal::Package::from_memory(b, p));
    const decal::Status s = decal::validate_indices(p);
    EXPECT_TRUE(s) << s.message;
  }
}

TEST(ValidateIndices, EachKindOfDanglingIndexIsNamed) {
  struct Case {
    const char* expect;
    void (*edit)(prep::DecalModel&);
  };
  const Case cases[] = {
      {"line_vertex_line[4].line = 2", [](prep::DecalModel& m) { m.line_vertex_line[4] = 2; }},
      {"poly_root_node[1].node = 6", [](prep::DecalModel& m) { m.poly_root_node[1] = 6; }},
      {"qt_node[3].type = 4",
       [](prep::DecalModel& m) {
         m.qt_node[3] = {4, 0};
       }},
      {"qt_node[5].offset = 2",
       [](prep::DecalModel& m) {
         m.qt_node[5] = {3, 2};
       }},
      // An internal node whose children include itself: a descent would
      // never end (the CPU evaluator and the shaders loop until a leaf).
      {"qt_node[0].offset = 0: children must come after their parent",
       [](prep::DecalModel& m) {
         m.qt_node[0] = {0, 0};
       }},
      {"cell_holes[0].polygon = 2",
       [](prep::DecalModel& m) {
         m.cell_holes[0] = {2, 5};
       }},
      {"dyn_prev_next[1].next = 4",
       [](prep::DecalModel& m) {
         m.dyn_prev_next[1] = {0, 4};
       }},
      {"dyn_line_start[1].vertex = 4", [](prep::DecalModel& m) { m.dyn_line_start[1] = 4; }},
      {"lod_segments[1].b = 3", [](prep::DecalModel& m) { m.lod_segments[1].b = 3; }},
      {"poly_props[1].exterior = 2", [](prep::DecalModel& m) { m.poly_props[1].exterior = 2; }},
      {"line_props[0].clip_node = 1 without style bit 5",
       [](prep::DecalModel& m) { m.line_props[0].clip_node = 1; }},
      {"line_props[1].clip_node = 99 is out of range",
       [](prep::DecalModel& m) {
         m.line_props[1].style |= decal::kStyleClipBit;
         m.line_props[1].clip_node = 99;
       }},
      {"dyn_line_props[1].clip_node = 3",
       [](prep::DecalModel& m) { m.dyn_line_props[1].clip_node = 3; }},
      {"line_corners has 4 elements", [](prep::DecalModel& m) { m.line_corners.pop_back(); }},
  };
  for (const Case& c : cases) {
    prep::DecalModel m = decal_test::small_model();
    c.edit(m);
    const auto b = decal_test::model_package_bytes(m, {prep::Codec::none, 0});
    decal::Package p;
    ASSERT_TRUE(decal::Package::from_memory(b, p));
    const decal::Status s = decal::validate_indices(p);
    EXPECT_FALSE(s) << c.expect;
    EXPECT_NE(s.message.find(c.expect), std::string::npos)
        << "expected '" << c.expect << "' in: " << s.message;
  }
}

// The v1.3 compact blobs (formats/SPEC.md "Compact layout (v1.3)") of
// small_model(), each broken in one way, with the grid: the check names the
// blob and the value.
TEST(ValidateIndices, EachBrokenCompactBlobIsNamed) {
  using decal::BlobId;
  const prep::DecalModel m = decal_test::small_model();
  const decal::Grid grid{m.grid.origin_x, m.grid.origin_y, m.grid.cell_w,
                         m.grid.cell_h,   m.grid.nx,       m.grid.ny};
  struct Blob {
    BlobId id;
    uint64_t count;
    std::vector<std::byte> bytes;
  };
  std::vector<Blob> good;
  for (const prep::BlobInput& b : prep::model_blobs(m, false))
    good.push_back({b.id, b.count, {b.bytes.begin(), b.bytes.end()}});
  auto validate = [&](const std::vector<Blob>& blobs) {
    std::vector<decal::BlobBytes> v;
    for (const Blob& b : blobs) v.push_back({b.id, b.count, b.bytes});
    return decal::validate_blobs(v, {&grid, false});
  };
  ASSERT_TRUE(validate(good)) << validate(good).message;
  auto u32_at = [](std::vector<Blob>& blobs, BlobId id, size_t k) -> uint32_t& {
    for (Blob& b : blobs)
      if (b.id == id) return reinterpret_cast<uint32_t*>(b.bytes.data())[k];
    throw std::runtime_error("no such blob");
  };
  auto drop = [](std::vector<Blob>& blobs, BlobId id) {
    std::erase_if(blobs, [&](const Blob& b) { return b.id == id; });
  };
  struct Case {
    const char* expect;
    std::function<void(std::vector<Blob>&)> edit;
  };
  const Case cases[] = {
      // cell 1 starts at (2, 7): cell 0 is a tree of 4 slots, cell 1 ends before it starts
      {"cell_line_first[2] = (4, 6) is less than cell_line_first[1] = (2, 7)",
       [&](std::vector<Blob>& b) { u32_at(b, BlobId::cell_line_first, 3) = 7; }},
      {"cell_line_first runs from (0, 0) to",
       [&](std::vector<Blob>& b) { u32_at(b, BlobId::cell_line_first, 4) += 1; }},
      {"nodes are not a full binary tree",
       [&](std::vector<Blob>& b) { u32_at(b, BlobId::cell_poly_first, 3) += 1; }},
      {"qt_leaf_loops[0] = 99 runs past the end of qt_leaf_vertices",
       [&](std::vector<Blob>& b) { u32_at(b, BlobId::qt_leaf_loops, 0) = 99; }},
      {"qt_leaf_loop_range[0] = (first 5",
       [&](std::vector<Blob>& b) { u32_at(b, BlobId::qt_leaf_loop_range, 0) = 5; }},
      {"line_bvh_box16 has 6 elements but cell_line_first is absent",
       [&](std::vector<Blob>& b) {
         drop(b, BlobId::cell_line_first);
         drop(b, BlobId::cell_segments);
       }},
      {"cell_poly_first has 2 elements for the 2 grid cells",
       [&](std::vector<Blob>& b) {
         for (Blob& x : b)
           if (x.id == BlobId::cell_poly_first) {
             x.bytes.resize(x.bytes.size() - 8);
             x.count -= 1;
           }
       }},
      {"cell_poly_holes runs from 0 to 5",
       [&](std::vector<Blob>& b) { u32_at(b, BlobId::cell_poly_holes, 1) = 5; }},
      {"cell_poly_entries[0].node = 6 is out of range",
       [&](std::vector<Blob>& b) { u32_at(b, BlobId::cell_poly_entries, 1) = 6; }},
      {"are both present",
       [&](std::vector<Blob>& b) {
         b.push_back({BlobId::cell_segment_range, 2, std::vector<std::byte>(16)});
         b.push_back({BlobId::line_bvh_range, 2, std::vector<std::byte>(32)});
       }},
  };
  for (const Case& c : cases) {
    std::vector<Blob> blobs = good;
    c.edit(blobs);
    const decal::Status s = validate(blobs);
    EXPECT_FALSE(s) << c.expect;
    EXPECT_NE(s.message.find(c.expect), std::string::npos)
        << "expected '" << c.expect << "' in: " << s.message;
  }
}

}  // namespace

}  // namespace formats_reader_hostile
