// The tileset build's parts file and its packed R-tree
// (libprep/tile/part_index.hpp, tileset_work.hpp; ARCHITECTURE.md "3b.
// tile"): what a query returns against a scan of every box (the oracle
// needs no index), a round trip of parts whose keys are a NaN and a
// negative zero, and damaged files refused with an error naming the file.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include "part_index.hpp"
#include "prep/error.hpp"
#include "test_support.hpp"
#include "tileset_work.hpp"

namespace prep::tiling {
namespace {

using prep::test::Rng;
using prep::test::TempDir;

void write_boxes(const std::string& path, const std::vector<BoxRecord>& boxes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  ASSERT_NE(f, nullptr);
  if (!boxes.empty()) {
    ASSERT_EQ(std::fwrite(boxes.data(), sizeof(BoxRecord), boxes.size(), f), boxes.size());
  }
  std::fclose(f);
}

std::vector<BoxRecord> random_boxes(size_t n, uint64_t seed) {
  Rng rng(seed);
  std::vector<BoxRecord> out(n);
  for (size_t i = 0; i < n; ++i) {
    const double x = rng.in(-5000, 5000), y = rng.in(-3000, 3000);
    // Mostly small boxes, a few long ones (a river across the scene).
    const double w = rng.uniform() < 0.02 ? rng.in(0, 4000) : rng.in(0, 40);
    const double h = rng.uniform() < 0.02 ? rng.in(0, 4000) : rng.in(0, 40);
    out[i] = {int32_t(i % 3), 64, x, y, x + w, y + h, 64 * uint64_t(i)};
  }
  return out;
}

std::set<uint64_t> scan(const std::vector<BoxRecord>& boxes, const Extent& w) {
  std::set<uint64_t> out;
  for (const BoxRecord& r : boxes)
    if (r.xmin <= w.xmax && r.xmax >= w.xmin && r.ymin <= w.ymax && r.ymax >= w.ymin)
      out.insert(r.offset);
  return out;
}

TEST(PartIndex, AQueryReturnsExactlyTheBoxesAScanFinds) {
  TempDir dir("part_index");
  // 0, 1, a full root, one more than a root (two levels), and enough for
  // four levels.
  for (size_t n : {size_t(0), size_t(1), size_t(16), size_t(17), size_t(5000)}) {
    SCOPED_TRACE(n);
    const std::vector<BoxRecord> boxes = random_boxes(n, 7 + n);
    write_boxes(dir.file("boxes.bin"), boxes);
    write_box_index(dir.file("boxes.bin"), dir.file("parts.idx"));
    const BoxIndex index(dir.file("parts.idx"), 64 * uint64_t(n));
    EXPECT_EQ(index.entries(), n);
    Rng rng(99);
    size_t found = 0;
    for (int q = 0; q < 300; ++q) {
      const double x = rng.in(-5500, 5500), y = rng.in(-3500, 3500);
      const double s = q % 10 == 0 ? rng.in(0, 6000) : rng.in(0, 300);
      const Extent w{x, y, x + s, y + s};
      std::vector<BoxRecord> got;
      index.query(w, got);
      std::set<uint64_t> offsets;
      for (const BoxRecord& r : got) offsets.insert(r.offset);
      EXPECT_EQ(offsets.size(), got.size()) << "a leaf returned twice";
      EXPECT_EQ(offsets, scan(boxes, w));
      found += got.size();
    }
    if (n == 5000) {
      EXPECT_GT(found, 1000u);  // the windows do meet boxes
    }
  }
}

// A byte of `path` at `at` replaced by the result of `f`.
template <typename F>
void patch(const std::string& path, uint64_t at, F f) {
  std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
  io.seekg(std::streamoff(at));
  char c = 0;
  io.read(&c, 1);
  c = f(c);
  io.seekp(std::streamoff(at));
  io.write(&c, 1);
}

void expect_refused(const std::string& path, uint64_t data_bytes, const std::string& what) {
  SCOPED_TRACE(what);
  try {
    const BoxIndex index(path, data_bytes);
    std::vector<BoxRecord> got;
    index.query({-1e9, -1e9, 1e9, 1e9}, got);
    ADD_FAILURE() << "a damaged index was read";
  } catch (const prep::output_error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(PartIndex, ADamagedIndexIsRefusedNamingTheFile) {
  TempDir dir("part_index_bad");
  const std::vector<BoxRecord> boxes = random_boxes(300, 3);
  write_boxes(dir.file("boxes.bin"), boxes);
  const std::string good = dir.file("good.idx");
  write_box_index(dir.file("boxes.bin"), good);
  const uint64_t data = 64 * 300;
  const auto size = uint64_t(std::filesystem::file_size(good));
  // 300 leaves: levels of 2, 19 and 300 items, root first.
  const uint64_t items = 24 + 3 * 8;
  auto copy = [&](const std::string& name) {
    const std::string p = dir.file(name);
    std::filesystem::copy_file(good, p, std::filesystem::copy_options::overwrite_existing);
    return p;
  };
  {
    const std::string p = copy("short.idx");
    std::filesystem::resize_file(p, size - 1);
    expect_refused(p, data, "one byte short");
  }
  {
    const std::string p = copy("magic.idx");
    patch(p, 0, [](char c) { return char(c ^ 1); });
    expect_refused(p, data, "magic");
  }
  {
    const std::string p = copy("levels.idx");
    patch(p, 16, [](char) { return char(40); });
    expect_refused(p, data, "levels");
  }
  {
    const std::string p = copy("count.idx");
    patch(p, 24 + 8, [](char c) { return char(c + 1); });
    expect_refused(p, data, "a level's count");
  }
  {
    // The root's first item's first child (its `offset`, at byte 40 of the
    // record) past the next level.
    const std::string p = copy("child.idx");
    patch(p, items + 40, [](char) { return char(100); });
    expect_refused(p, data, "a child range");
  }
  {
    // A leaf's record past the end of parts.bin: the data file is shorter.
    expect_refused(copy("leaf.idx"), data - 64, "a leaf past the data");
  }
  {
    const std::string p = copy("missing.idx");
    std::filesystem::remove(p);
    expect_refused(p, data, "no file");
  }
}

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

TEST(PartsFile, PartsComeBackInSceneOrderWithTheirKeysBitForBit) {
  TempDir dir("parts_file");
  WorkPaths paths{dir.path().string()};
  std::filesystem::create_directories(paths.work());
  SceneFeatures chunk;
  chunk.layers.resize(2);
  ScenePolygon p;
  p.shell = {{0, 0}, {100, 0}, {100, 100}, {0, 100}};
  p.holes = {{{10, 10}, {20, 10}, {20, 20}}, {{50, 50}, {60, 50}, {60, 60}, {50, 60}}};
  p.fid = 41;
  p.part = 2;
  p.layer = 1;
  p.area = -0.0;
  p.order_value = std::nan("");
  p.color_value = 0.1;
  SceneLine l;
  l.points = {{0.1, 0.2}, {300.3, 0.4}};
  l.closed = true;
  l.fid = -1;
  l.layer = 0;
  l.width = 3;
  l.length = 300.2;
  l.color_value = -0.0;
  SceneLine d = l;
  d.closed = false;
  d.width = 4;
  d.fid = 7;
  // Two chunks: the second's polygon follows the first's in scene order.
  ScenePolygon p2 = p;
  p2.fid = 42;
  p2.holes.clear();
  chunk.polygons = {p};
  chunk.lines = {l};
  chunk.dynamic_lines = {d};
  PartWriter writer(paths);
  writer.add(chunk);
  chunk.polygons = {p2};
  chunk.lines.clear();
  chunk.dynamic_lines.clear();
  writer.add(chunk);
  writer.close();
  EXPECT_EQ(writer.parts(), 4u);

  TilePlan plan;
  plan.size = 1000;
  plan.margin = 5;
  plan.dynamic_margin = 1000;
  SceneFeatures back;
  PartReader reader(paths);
  reader.read_tile(plan, {0, 0}, back);
  ASSERT_EQ(back.polygons.size(), 2u);
  ASSERT_EQ(back.lines.size(), 1u);
  ASSERT_EQ(back.dynamic_lines.size(), 1u);
  const ScenePolygon& q = back.polygons[0];
  EXPECT_EQ(q.fid, 41);
  EXPECT_EQ(back.polygons[1].fid, 42);
  EXPECT_EQ(q.part, 2);
  EXPECT_EQ(q.layer, 1u);
  ASSERT_EQ(q.holes.size(), 2u);
  EXPECT_EQ(q.holes[1].size(), 4u);
  EXPECT_EQ(q.holes[1][2].x, 60);
  EXPECT_TRUE(back.polygons[1].holes.empty());
  EXPECT_TRUE(same_bits(q.area, -0.0));
  EXPECT_TRUE(std::isnan(q.order_value));
  EXPECT_EQ(q.color_value, 0.1);
  EXPECT_TRUE(back.lines[0].closed);
  EXPECT_EQ(back.lines[0].points[1].x, 300.3);
  EXPECT_TRUE(same_bits(back.lines[0].color_value, -0.0));
  EXPECT_EQ(back.lines[0].length, 300.2);
  EXPECT_FALSE(back.dynamic_lines[0].closed);
  EXPECT_EQ(back.dynamic_lines[0].width, 4);
  EXPECT_EQ(back.dynamic_lines[0].fid, 7);

  // A tile the static parts do not reach (their margin is 5 m) but the
  // dynamic line's 1000 m margin does.
  reader.read_tile(plan, {0, 1}, back);
  EXPECT_TRUE(back.polygons.empty());
  EXPECT_TRUE(back.lines.empty());
  EXPECT_EQ(back.dynamic_lines.size(), 1u);

  // A record whose ring count no longer fits its bytes: refused, naming
  // the file and the record's offset.
  patch(paths.parts(), 20, [](char c) { return char(c + 2); });
  PartReader damaged(paths);
  try {
    damaged.read_tile(plan, {0, 0}, back);
    ADD_FAILURE() << "a damaged part was read";
  } catch (const prep::output_error& e) {
    EXPECT_NE(std::string(e.what()).find(paths.parts()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("offset 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace prep::tiling
