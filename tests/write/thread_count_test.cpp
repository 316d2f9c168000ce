// Thread count: write_package compresses and checksums the blobs in parallel
// (oneTBB, one blob per task), and the package bytes must not depend on it
// (ARCHITECTURE.md "write"). Checked two ways:
//   - the file written with 1 thread (tbb::global_control, as `--threads 1`)
//     against those written with 2, 4 and 8, several times each;
//   - every stored blob against an independent oracle: the one zstd frame
//     that ZSTD_compress2 makes of the blob alone on this thread (a frame of
//     ZSTD_c_nbWorkers > 0, or a blob cut into several frames, differs), and
//     the blob table against the file layout of formats/SPEC.md.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>
#include <xxhash.h>
#include <zstd.h>

#include <cstring>
#include <filesystem>

#include "decal/format.hpp"
#include "fixtures.hpp"
#include "prep/write.hpp"

// One test binary holds several files (a unity build): each keeps its
// names in a namespace of its own.
namespace write_thread_count {

namespace {

using decal::BlobId;
using decal::ElementType;
using decal_test::make_temp_dir;
using decal_test::read_file;
using decal_test::walk_blob;

using decal_test::OwnedBlob;

// Blobs of very different sizes (so that the largest-first order differs
// from the table order and threads finish out of order), with an empty one
// between them. 2 MiB blobs are larger than one zstd block (128 KiB) and
// than a ZSTD_c_nbWorkers job at level 1 (zstd splits jobs of 512 KiB and up
// at low levels), so a multithreaded frame would show.
std::vector<OwnedBlob> blobs() {
  std::vector<OwnedBlob> v;
  v.push_back(walk_blob(BlobId::line_vertex_line, ElementType::u32, 4, 1000, 1));
  v.push_back(walk_blob(BlobId::cell_segment_range, ElementType::uvec2, 8, 0, 2));
  v.push_back(walk_blob(BlobId::qt_node_box, ElementType::ivec4, 16, 1 << 17, 3));  // 2 MiB
  v.push_back(walk_blob(BlobId::qt_node, ElementType::ivec2, 8, 77, 4));
  v.push_back(walk_blob(BlobId::qt_leaf_segments, ElementType::uvec2, 8, 3 << 17, 5));  // 3 MiB
  v.push_back(walk_blob(BlobId::qt_leaf_vertices, ElementType::ivec2, 8, 1 << 18, 6));  // 2 MiB
  v.push_back(walk_blob(BlobId::cell_polys, ElementType::uvec4, 16, 5000, 7));
  v.push_back(walk_blob(BlobId::poly_bvh_box, ElementType::ivec4, 16, 1 << 16, 8));  // 1 MiB
  return v;
}

using decal_test::inputs;

// Writes with at most `threads` threads, as the pipeline caps `--threads`.
std::vector<std::byte> write_with(const std::string& path, const std::vector<OwnedBlob>& blobs,
                                  const prep::WriteOptions& wo, size_t threads) {
  const tbb::global_control cap(tbb::global_control::max_allowed_parallelism, threads);
  tbb::task_arena arena(static_cast<int>(threads));
  arena.execute([&] { prep::write_package(path, R"({"k":1})", inputs(blobs), wo); });
  return read_file(path);
}

// One zstd frame of `raw`, single-threaded, with the parameters SPEC.md asks
// of a writer (content size, checksum).
std::vector<std::byte> oracle_frame(std::span<const std::byte> raw, int level) {
  ZSTD_CCtx* c = ZSTD_createCCtx();
  ZSTD_CCtx_setParameter(c, ZSTD_c_compressionLevel, level);
  ZSTD_CCtx_setParameter(c, ZSTD_c_checksumFlag, 1);
  ZSTD_CCtx_setParameter(c, ZSTD_c_contentSizeFlag, 1);
  std::vector<std::byte> out(ZSTD_compressBound(raw.size()));
  const size_t n = ZSTD_compress2(c, out.data(), out.size(), raw.data(), raw.size());
  ZSTD_freeCCtx(c);
  EXPECT_FALSE(ZSTD_isError(n));
  out.resize(ZSTD_isError(n) ? 0 : n);
  return out;
}

class ThreadCount : public ::testing::TestWithParam<prep::Codec> {
 protected:
  void SetUp() override { dir_ = make_temp_dir("threads"); }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  // The parameter's codec at zstd level 1.
  prep::WriteOptions options() const {
    prep::WriteOptions wo;
    wo.codec = GetParam();
    wo.zstd_level = 1;
    return wo;
  }
  std::string dir_;
};

TEST_P(ThreadCount, PackageBytesAreTheSameForOneAndManyThreads) {
  const auto b = blobs();
  const prep::WriteOptions wo = options();
  const std::vector<std::byte> serial = write_with(dir_ + "/t1.decals", b, wo, 1);
  ASSERT_GT(serial.size(), sizeof(decal::FileHeader));
  for (size_t threads : {2, 4, 8}) {
    for (int run = 0; run < 3; ++run) {
      SCOPED_TRACE(std::to_string(threads) + " threads, run " + std::to_string(run));
      const std::string path = dir_ + "/t" + std::to_string(threads) + ".decals";
      const std::vector<std::byte> parallel = write_with(path, b, wo, threads);
      ASSERT_EQ(parallel.size(), serial.size());
      EXPECT_TRUE(parallel == serial);
    }
  }
}

TEST_P(ThreadCount, EveryBlobIsStoredAsItsOwnSingleThreadedFrame) {
  const auto b = blobs();
  const prep::WriteOptions wo = options();
  const std::vector<std::byte> file = write_with(dir_ + "/p.decals", b, wo, 8);
  decal::FileHeader h;
  ASSERT_GE(file.size(), sizeof h);
  std::memcpy(&h, file.data(), sizeof h);
  ASSERT_EQ(h.blob_count, b.size());
  ASSERT_EQ(h.file_size, file.size());
  // SPEC.md layout: header, table, metadata, then the blobs in table order,
  // each at the next 256-byte boundary.
  uint64_t at = h.metadata_offset + h.metadata_size;
  for (size_t i = 0; i < b.size(); ++i) {
    decal::BlobTableEntry e;
    std::memcpy(&e, file.data() + h.table_offset + i * sizeof e, sizeof e);
    SCOPED_TRACE("blob " + std::string(e.name));
    EXPECT_EQ(e.id, static_cast<uint32_t>(b[i].id));
    EXPECT_EQ(e.raw_size, b[i].bytes.size());
    EXPECT_EQ(e.offset, (at + 255) / 256 * 256);
    ASSERT_LE(e.offset + e.stored_size, file.size());
    const std::span<const std::byte> stored(file.data() + e.offset, e.stored_size);
    const bool zstd = GetParam() == prep::Codec::zstd && !b[i].bytes.empty();
    EXPECT_EQ(e.codec, static_cast<uint32_t>(zstd ? decal::CodecId::zstd : decal::CodecId::none));
    const std::vector<std::byte> expected =
        zstd ? oracle_frame(b[i].bytes, wo.zstd_level) : b[i].bytes;
    ASSERT_EQ(stored.size(), expected.size());
    EXPECT_TRUE(std::equal(stored.begin(), stored.end(), expected.begin()));
    EXPECT_EQ(e.checksum, XXH64(expected.data(), expected.size(), 0));
    at = e.offset + e.stored_size;
  }
}

TEST_P(ThreadCount, ModelPackageBytesAreTheSameForOneAndManyThreads) {
  // write_model hands the writer the model's own arrays at once and the
  // v1.3 blobs (with the metadata, which counts them) later, made on one of
  // its threads while the others compress: the order the blobs finish in
  // varies, the file must not.
  const prep::DecalModel m = decal_test::small_model();
  const prep::WriteOptions wo = options();
  const auto write = [&](size_t threads) {
    const std::string path = dir_ + "/m" + std::to_string(threads) + ".decals";
    const tbb::global_control cap(tbb::global_control::max_allowed_parallelism, threads);
    tbb::task_arena arena(static_cast<int>(threads));
    arena.execute([&] { prep::write_model(path, m, R"({"k":1})", wo); });
    return read_file(path);
  };
  const std::vector<std::byte> serial = write(1);
  ASSERT_GT(serial.size(), sizeof(decal::FileHeader));
  for (size_t threads : {2, 4, 8}) {
    for (int run = 0; run < 3; ++run) {
      SCOPED_TRACE(std::to_string(threads) + " threads, run " + std::to_string(run));
      EXPECT_TRUE(write(threads) == serial);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Codecs, ThreadCount,
                         ::testing::Values(prep::Codec::none, prep::Codec::zstd),
                         [](const auto& param_info) {
                           return std::string(param_info.param == prep::Codec::none ? "none"
                                                                                    : "zstd");
                         });

}  // namespace

}  // namespace write_thread_count
