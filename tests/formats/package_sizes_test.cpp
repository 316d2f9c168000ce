// decal::read_package_sizes / package_sizes_from_memory (decal/reader.hpp):
// the blobs' decoded sizes from a package's header and blob table alone.
// Checked against the independent full path, Package::open, which decodes
// every blob: on small models of either codec, the checked-in golden
// package and a Monaco package built by the tool. Hostile inputs: every
// truncated prefix, every bit flip of the header and the table, and crafted
// cases, each rejected with its reason; never a size open() would not give.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "byte_damage.hpp"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "fixtures.hpp"
#include "test_support.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace formats_package_sizes {

namespace {

namespace fs = std::filesystem;
using namespace decal_test;
using H = decal::FileHeader;
using E = decal::BlobTableEntry;

// The sizes agree with what Package::open decoded: blob by blob (id, name,
// type, stride, count, decoded bytes) and in total.
void expect_same(const decal::PackageSizes& s, const decal::Package& p) {
  ASSERT_EQ(s.blobs.size(), p.blobs().size());
  uint64_t total = 0;
  for (size_t i = 0; i < s.blobs.size(); ++i) {
    const decal::BlobSize& a = s.blobs[i];
    const decal::BlobView& b = p.blobs()[i];
    EXPECT_EQ(a.id, b.id) << i;
    EXPECT_EQ(a.name, b.name) << i;
    EXPECT_EQ(a.type, b.type) << i;
    EXPECT_EQ(a.stride, b.stride) << i;
    EXPECT_EQ(a.count, b.count) << i;
    EXPECT_EQ(a.raw_bytes, b.bytes.size()) << b.name;
    total += b.bytes.size();
  }
  EXPECT_EQ(s.raw_bytes, total);
  EXPECT_EQ(s.major, p.major());
  EXPECT_EQ(s.minor, p.minor());
  EXPECT_EQ(s.flags, p.flags());
}

// Opens `path` both ways; returns the decoded total.
uint64_t expect_same_on_file(const std::string& path) {
  decal::Package p;
  const decal::Status opened = decal::Package::open(path, p);
  EXPECT_TRUE(opened) << opened.message;
  decal::PackageSizes s;
  const decal::Status read = decal::read_package_sizes(path, s);
  EXPECT_TRUE(read) << read.message;
  expect_same(s, p);
  EXPECT_EQ(s.file_bytes, fs::file_size(path));
  return s.raw_bytes;
}

decal::Status sizes_of(const std::vector<std::byte>& b, decal::PackageSizes* out = nullptr) {
  decal::PackageSizes s;
  decal::Status st = decal::package_sizes_from_memory(b, s);
  if (!st) {
    EXPECT_TRUE(s.blobs.empty() && s.raw_bytes == 0) << "out not left empty";
  }
  if (out) *out = std::move(s);
  return st;
}

std::vector<std::byte> small_package(prep::Codec codec) {
  return model_package_bytes(small_model(), {codec, 3});
}

TEST(PackageSizes, EqualWhatOpenDecodesOnSmallModelsOfEitherCodec) {
  const std::string dir = make_temp_dir("sizes");
  for (prep::Codec codec : {prep::Codec::none, prep::Codec::zstd}) {
    const auto b = small_package(codec);
    decal::Package p;
    ASSERT_TRUE(decal::Package::from_memory(b, p));
    decal::PackageSizes s;
    ASSERT_TRUE(sizes_of(b, &s));
    expect_same(s, p);
    EXPECT_GT(s.raw_bytes, 0u);
    for (const decal::BlobSize& blob : s.blobs) {
      EXPECT_TRUE(blob.known()) << blob.name;
      EXPECT_EQ(blob.raw_bytes, blob.count * blob.stride) << blob.name;
    }
    write_file(dir + "/p.decals", b);
    expect_same_on_file(dir + "/p.decals");
  }
  fs::remove_all(dir);
}

TEST(PackageSizes, EqualWhatOpenDecodesOnTheGoldenPackage) {
  const std::string golden =
      std::string(DECALPREP_SOURCE_DIR) + "/tests/formats/legacy/golden_v1_1.decals";
  const uint64_t total = expect_same_on_file(golden);
  EXPECT_GT(total, fs::file_size(golden));  // zstd: more decoded than stored
}

TEST(PackageSizes, EqualWhatOpenDecodesOnABuiltMonacoPackage) {
  prep::test::TempDir dir("sizes_monaco");
  const std::string out = dir.file("monaco.decals");
  const auto r = prep::test::run_tool(
      "build " + prep::test::shell_quote(prep::test::monaco_sample("scene.toml")) + " -q -o " +
          prep::test::shell_quote(out),
      dir);
  ASSERT_EQ(r.rc, 0) << r.output;
  const uint64_t total = expect_same_on_file(out);
  std::printf("[ measured ] Monaco: %llu package bytes, %llu decoded blob bytes (x%.1f)\n",
              static_cast<unsigned long long>(fs::file_size(out)),
              static_cast<unsigned long long>(total), double(total) / double(fs::file_size(out)));
  EXPECT_GT(total, 4 * fs::file_size(out));
}

// Neither the metadata nor a blob is read: damage to their bytes leaves the
// sizes as they were, while open() refuses the file.
TEST(PackageSizes, ReadNeitherTheMetadataNorAnyBlob) {
  const auto good = small_package(prep::Codec::zstd);
  decal::PackageSizes before;
  ASSERT_TRUE(sizes_of(good, &before));
  const auto count = get<uint32_t>(good, offsetof(H, blob_count));
  const auto moff = get<uint64_t>(good, offsetof(H, metadata_offset));
  const size_t table_end = entry_at(count);
  ASSERT_EQ(moff, table_end);
  // Every byte after the table, flipped: open() refuses each.
  auto b = good;
  for (size_t i = table_end; i < b.size(); i += 97) {
    b[i] ^= std::byte{0x20};
    decal::Package p;
    EXPECT_FALSE(decal::Package::from_memory(b, p)) << "byte " << i;
    decal::PackageSizes after;
    ASSERT_TRUE(sizes_of(b, &after)) << "byte " << i;
    EXPECT_EQ(after.raw_bytes, before.raw_bytes);
    b[i] ^= std::byte{0x20};
  }
  // From a file too: the blobs zeroed.
  const std::string dir = make_temp_dir("sizes_noread");
  b = good;
  std::memset(b.data() + moff, 0, b.size() - moff);
  write_file(dir + "/z.decals", b);
  decal::PackageSizes s;
  ASSERT_TRUE(decal::read_package_sizes(dir + "/z.decals", s));
  EXPECT_EQ(s.raw_bytes, before.raw_bytes);
  fs::remove_all(dir);
}

TEST(PackageSizes, EveryTruncatedPrefixIsRejectedWithAMessage) {
  const auto good = small_package(prep::Codec::zstd);
  ASSERT_TRUE(sizes_of(good));
  for (size_t n = 0; n < good.size(); ++n) {
    const std::vector<std::byte> prefix(good.begin(), good.begin() + static_cast<long>(n));
    const decal::Status s = sizes_of(prefix);
    ASSERT_FALSE(s) << "prefix of " << n << " bytes was accepted";
    ASSERT_FALSE(s.message.empty());
    ASSERT_EQ(s.message.find('\n'), std::string::npos) << s.message;
  }
  // On disk, the message names the file.
  const std::string dir = make_temp_dir("sizes_prefix");
  for (size_t n : {size_t(0), size_t(7), size_t(95), size_t(96), size_t(500), good.size() - 1}) {
    write_file(dir + "/p.decals", {good.begin(), good.begin() + static_cast<long>(n)});
    decal::PackageSizes s;
    const decal::Status st = decal::read_package_sizes(dir + "/p.decals", s);
    EXPECT_FALSE(st) << n;
    EXPECT_NE(st.message.find(dir + "/p.decals"), std::string::npos) << st.message;
    EXPECT_TRUE(s.blobs.empty());
  }
  fs::remove_all(dir);
}

TEST(PackageSizes, EveryBitFlipOfTheHeaderAndTheTableIsRejected) {
  const auto good = small_package(prep::Codec::none);
  const size_t table_end = entry_at(get<uint32_t>(good, offsetof(H, blob_count)));
  EXPECT_TRUE(prep::test::every_bit_flip_rejected(good, table_end, [](const auto& b) {
    const decal::Status s = sizes_of(b);
    if (s) return ::testing::AssertionFailure() << "read_package_sizes succeeded";
    if (s.message.empty()) return ::testing::AssertionFailure() << "with no message";
    return ::testing::AssertionSuccess();
  }));
}

TEST(PackageSizes, HostileHeadersAndTablesAreRejectedWithTheirReason) {
  const auto good = small_package(prep::Codec::zstd);
  const uint64_t size = good.size();
  struct Case {
    const char* name;
    std::vector<std::byte> bytes;
    const char* expect;
  };
  std::vector<Case> cases;
  auto edited = [&](auto edit, bool seal = true) {
    auto b = good;
    edit(b);
    if (seal) reseal(b);
    return b;
  };
  cases.push_back({"wrong magic", edited([](auto& b) { b[1] = std::byte{'X'}; }, false),
                   "magic bytes do not match"});
  cases.push_back({"truncated header", {good.begin(), good.begin() + 60}, "truncated package"});
  cases.push_back({"major version 7",
                   edited([](auto& b) { put<uint16_t>(b, offsetof(H, version_major), 7); }),
                   "major version 7"});
  cases.push_back({"trailing bytes", edited([](auto& b) { b.push_back(std::byte{0}); }, false),
                   "trailing bytes"});
  cases.push_back({"table past the end of the file",
                   edited([](auto& b) { put<uint32_t>(b, offsetof(H, blob_count), 100000); }),
                   "blob table (100000 entries x 96 bytes at byte 96) runs past the end"});
  cases.push_back({"metadata past the end of the file",
                   edited([&](auto& b) { put<uint64_t>(b, offsetof(H, metadata_size), size); }),
                   "runs past the end"});
  cases.push_back({"blob past the end of the file", edited([&](auto& b) {
                     put<uint64_t>(b, entry_at(1) + offsetof(E, offset), (size / 256 + 1) * 256);
                   }),
                   "run past the end"});
  cases.push_back({"blob overlapping the metadata",
                   edited([](auto& b) { put<uint64_t>(b, entry_at(0) + offsetof(E, offset), 0); }),
                   "overlaps the metadata"});
  // count x 4 wraps to the stored raw_size: the overflow itself is caught.
  cases.push_back({"count x stride overflows", edited([](auto& b) {
                     const auto raw = get<uint64_t>(b, entry_at(1) + offsetof(E, raw_size));
                     const auto stride = get<uint32_t>(b, entry_at(1) + offsetof(E, stride));
                     ASSERT_EQ(stride, 4u);
                     put<uint64_t>(b, entry_at(1) + offsetof(E, count),
                                   (uint64_t(1) << 62) + raw / 4);
                   }),
                   "overflows uint64"});
  cases.push_back({"raw_size no zstd frame of its size can hold", edited([](auto& b) {
                     put<uint64_t>(b, entry_at(1) + offsetof(E, count), uint64_t(1) << 40);
                     put<uint64_t>(b, entry_at(1) + offsetof(E, raw_size), uint64_t(4) << 40);
                   }),
                   "cannot come from"});
  cases.push_back({"raw_size not count x stride", edited([](auto& b) {
                     put<uint64_t>(b, entry_at(1) + offsetof(E, raw_size), 12345);
                   }),
                   "raw_size 12345 != count"});
  cases.push_back({"table checksum",
                   edited([](auto& b) { b[entry_at(0) + 16] ^= std::byte{1}; }, false),
                   "checksum mismatch"});
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    decal::Package p;
    EXPECT_FALSE(decal::Package::from_memory(c.bytes, p));  // the full path agrees
    const decal::Status s = sizes_of(c.bytes);
    ASSERT_FALSE(s);
    EXPECT_NE(s.message.find(c.expect), std::string::npos) << s.message;
  }
}

// Over the hostile variants and the fuzz seeds: what open() accepts, the
// sizes accept with open()'s figures; what the sizes refuse, open() refuses.
TEST(PackageSizes, AgreeWithOpenOnEveryHostileVariantAndSeed) {
  std::vector<std::vector<std::byte>> images;
  for (auto& h : hostile_variants(small_package(prep::Codec::zstd)))
    images.push_back(std::move(h.bytes));
  for (auto& [name, bytes] : seed_corpus()) images.push_back(std::move(bytes));
  size_t both = 0, refused = 0;
  for (size_t i = 0; i < images.size(); ++i) {
    decal::Package p;
    const bool opened = bool(decal::Package::from_memory(images[i], p));
    decal::PackageSizes s;
    const decal::Status st = sizes_of(images[i], &s);
    if (opened) {
      ASSERT_TRUE(st) << "image " << i << ": " << st.message;
      expect_same(s, p);
      ++both;
    }
    if (!st) {
      EXPECT_FALSE(opened) << i;
      ++refused;
    }
  }
  EXPECT_GT(both, 0u);
  EXPECT_GT(refused, 10u);
}

TEST(PackageSizes, MissingFilesAndDirectoriesAreRejected) {
  const std::string dir = make_temp_dir("sizes_files");
  decal::PackageSizes s;
  decal::Status st = decal::read_package_sizes(dir + "/missing.decals", s);
  EXPECT_FALSE(st);
  EXPECT_NE(st.message.find("cannot open"), std::string::npos) << st.message;
  st = decal::read_package_sizes(dir, s);
  EXPECT_FALSE(st);
  EXPECT_NE(st.message.find("not a regular file"), std::string::npos) << st.message;
  write_file(dir + "/empty.decals", {});
  st = decal::read_package_sizes(dir + "/empty.decals", s);
  EXPECT_FALSE(st);
  EXPECT_NE(st.message.find("empty file"), std::string::npos) << st.message;
  fs::remove_all(dir);
}

}  // namespace

}  // namespace formats_package_sizes
