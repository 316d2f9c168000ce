#include "fixtures.hpp"

#include "v12_cells.hpp"

#include <xxhash.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>

namespace decal_test {

prep::test::V12Cells small_model_cells() {
  prep::test::V12Cells cells;
  // cell 0: both segments of line 0; cell 1: line 0's second and line 1's
  // segment; the exterior (with its hole) in cell 0 only. BVHs: (first box,
  // leaf slots, internal nodes), full binary trees, leaf k = the cell's k-th
  // entry.
  cells.segment_range = {{0, 2}, {2, 2}};
  cells.poly_range = {{0, 1}, {1, 0}};
  cells.cell_polys = {{0, 0, 0, 1}};
  cells.line_bvh_range = {{0, 2, 1, 0}, {3, 2, 1, 0}};
  cells.line_bvh_box = {{-9000, -100, 1000, 100}, {-1000, -100, 1000, 100},
                        {-9000, -100, 1000, 100}, {-1000, -100, 9000, 4000},
                        {-1000, -100, 1000, 100}, {2000, 2000, 9000, 4000}};
  cells.poly_bvh_range = {{0, 1, 0, 0}, {1, 0, 0, 0}};
  cells.poly_bvh_box = {{-8000, -4000, 8000, 4000}};
  return cells;
}

prep::DecalModel small_model() {
  prep::DecalModel m;
  m.frame.crs_wkt = "LOCAL_CS[\"test\"]";
  m.frame.description = "test frame";
  m.frame.origin_x = 500000.25;
  m.frame.origin_y = 4800000.5;
  m.extent = {-10.0, -5.0, 10.0, 5.0};
  m.grid = {-10000, -5000, 10000, 10000, 2, 1};
  // static lines: line 0 = vertices 0..2, line 1 = vertices 3..4
  m.line_vertices = {{-9000, 0}, {-1000, 100}, {1000, -100}, {2000, 2000}, {9000, 4000}};
  m.line_vertex_line = {0, 0, 0, 1, 1};
  m.line_props = {{1.5f, 0xff0000ffu, 1, 1u, 2.5f, 0, 7, 0},
                  {0.75f, 0x8000ff00u, 0, 0u | decal::kStyleClosedBit, NAN, 1, 8, 0}};
  for (int i = 0; i < 5; ++i)
    m.line_corners.push_back({{0.1f * i, -0.2f}, {0.5f, 0.25f * i}, {-1.0f, 2.0f}});
  m.cell_segments = {{0, 1}, {1, 2}, {1, 2}, {3, 4}};
  // polygons: 0 = exterior, 1 = its hole; rank 2, below both lines (one
  // rank space, formats/SPEC.md "Drawing order")
  m.poly_props = {{0xffffffffu, 2, -1, 1.0f, 0, 3, {0, 0}}, {0u, 2, 0, NAN, 0, 3, {0, 0}}};
  m.poly_root_node = {0, 5};
  m.qt_node = {{0, 1}, {1, 0}, {2, 0}, {3, 0}, {1, 0}, {3, 1}};
  m.qt_node_box = {{-8000, -4000, 8000, 4000}, {-8000, -4000, 0, 0}, {0, -4000, 8000, 0},
                   {-8000, 0, 0, 4000},        {0, 0, 8000, 4000},   {-2000, -1000, 2000, 1000}};
  m.qt_leaf_loop_range = {{0, 1}, {1, 1}};  // two triangles: vertices [0, 3) and [3, 6)
  m.qt_leaf_loops = {3, 6};
  m.qt_leaf_vertices = {{-8000, 0},     {0, 0},        {-4000, 4000},
                        {-2000, -1000}, {2000, -1000}, {0, 1000}};
  m.cell_holes = {{1, 5}};
  prep::test::set_cells(m, small_model_cells());  // the model holds the v1.3 layout
  // dynamic lines
  m.dyn_vertices = {
      {-5000, 0, 120500, 0}, {5000, 0, 130250, 0}, {0, -3000, 99000, 1}, {0, 3000, 101000, 1}};
  m.dyn_prev_next = {{-1, 1}, {0, -1}, {-1, 3}, {2, -1}};
  m.dyn_line_start = {0, 2};
  m.dyn_line_props = {{3.0f, 0xff00ffffu, 0, 0, NAN, 2, 9, 0},
                      {2.0f, 0xffff00ffu, 1, 0, NAN, 2, 10, 0}};
  m.terrain_min = 99.0;
  m.terrain_max = 130.25;
  // LOD
  m.lod_points = {{-9000, 0, -9000, 0, 0.0f, 0.0f, 0, decal::kLodPointAlways},
                  {0, 500, 0, 500, 0.5f, 4.0f, 0, 0},
                  {9000, 0, 9000, 0, 0.0f, 0.0f, 0, decal::kLodPointAlways}};
  m.lod_segments = {
      {0, 2, decal::kLodNone, 1}, {0, 1, 1, decal::kLodNone}, {1, 2, 1, decal::kLodNone}};
  m.lod_line_range = {{0, 3}};
  m.max_representation_error = 0.0004;
  m.manifest.layers.push_back({"roads", 3, 2, 1, 0, 1, 2, 10, 5});
  m.manifest.entries.push_back(
      {"roads", 17, -1, prep::ManifestAction::dropped, "ring has NaN coordinate", NAN, NAN});
  m.manifest.notes.push_back("flat terrain");
  return m;
}

std::vector<std::byte> read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::vector<char> c((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> out(c.size());
  if (!c.empty()) std::memcpy(out.data(), c.data(), c.size());
  return out;
}

void write_file(const std::string& path, const std::vector<std::byte>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path);
}

std::string make_temp_dir(const std::string& tag) {
  std::string tmpl =
      (std::filesystem::temp_directory_path() / ("decal-" + tag + "-XXXXXX")).string();
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
  return tmpl;
}

std::vector<std::byte> model_package_bytes(const prep::DecalModel& model,
                                           const prep::WriteOptions& options,
                                           const std::string& extra_metadata_json) {
  const std::string dir = make_temp_dir("fixture");
  const std::string path = dir + "/p.decals";
  // The fixtures make hostile packages on purpose: the writer's own check
  // would refuse them.
  prep::WriteOptions raw = options;
  raw.check_blobs = false;
  prep::write_model(path, model, extra_metadata_json, raw);
  auto bytes = read_file(path);
  std::filesystem::remove_all(dir);
  return bytes;
}

size_t entry_at(size_t i) {
  return sizeof(decal::FileHeader) + i * sizeof(decal::BlobTableEntry);
}

void reseal(std::vector<std::byte>& f) {
  const auto count = get<uint32_t>(f, offsetof(decal::FileHeader, blob_count));
  const size_t table = sizeof(decal::FileHeader);
  const size_t table_bytes = size_t(count) * sizeof(decal::BlobTableEntry);
  if (table + table_bytes <= f.size())
    put<uint64_t>(f, offsetof(decal::FileHeader, table_checksum),
                  XXH64(f.data() + table, table_bytes, 0));
  const auto moff = get<uint64_t>(f, offsetof(decal::FileHeader, metadata_offset));
  const auto msize = get<uint64_t>(f, offsetof(decal::FileHeader, metadata_size));
  if (moff <= f.size() && msize <= f.size() - moff)
    put<uint64_t>(f, offsetof(decal::FileHeader, metadata_checksum),
                  XXH64(f.data() + moff, msize, 0));
  put<uint64_t>(f, offsetof(decal::FileHeader, header_checksum),
                XXH64(f.data(), offsetof(decal::FileHeader, header_checksum), 0));
}

std::vector<Hostile> hostile_variants(const std::vector<std::byte>& good) {
  using H = decal::FileHeader;
  using E = decal::BlobTableEntry;
  std::vector<Hostile> v;
  auto add = [&](std::string name, std::vector<std::byte> bytes, std::string expect,
                 bool structure_valid = false) {
    v.push_back({std::move(name), std::move(bytes), std::move(expect), structure_valid});
  };
  const uint64_t size = good.size();
  add("truncated_half", {good.begin(), good.begin() + static_cast<long>(size / 2)}, "");
  add("truncated_in_header", {good.begin(), good.begin() + 40}, "truncated");
  add("zero_length", {}, "empty file");
  {
    const std::string text = R"({"format":"decals","note":"a JSON file, not a package"})";
    std::vector<std::byte> b(text.size());
    std::memcpy(b.data(), text.data(), text.size());
    add("not_a_package", b, "not a .decals package");
  }
  {
    auto b = good;
    put<uint16_t>(b, offsetof(H, version_major), 2);
    reseal(b);
    add("major_version_2", b, "major version 2");
  }
  {
    auto b = good;
    put<uint32_t>(b, offsetof(H, flags), get<uint32_t>(b, offsetof(H, flags)) | 0x1u);
    reseal(b);
    add("unknown_required_flag", b, "required flag");
  }
  {
    auto b = good;
    put<uint64_t>(b, entry_at(2) + offsetof(E, offset), (size + 1024) / 256 * 256);
    reseal(b);
    add("offset_past_end", b, "past the end");
  }
  {
    auto b = good;
    put<uint64_t>(b, entry_at(1) + offsetof(E, offset),
                  get<uint64_t>(b, entry_at(0) + offsetof(E, offset)));
    reseal(b);
    add("overlapping_blobs", b, "overlaps");
  }
  {
    auto b = good;
    put<uint64_t>(b, entry_at(0) + offsetof(E, count), (uint64_t(1) << 61) + 1);
    reseal(b);
    add("count_times_stride_overflows", b, "overflows uint64");
  }
  {
    auto b = good;
    put<uint64_t>(b, entry_at(0) + offsetof(E, stored_size), size);
    reseal(b);
    add("stored_size_past_end", b, "past the end");
  }
  {
    auto b = good;
    put<uint32_t>(b, entry_at(2) + offsetof(E, stride), 16);
    reseal(b);
    add("wrong_record_stride", b, "catalogue");
  }
  {
    auto b = good;
    // The first blob's stored bytes: flip one bit in the middle of them.
    const uint64_t off = get<uint64_t>(b, entry_at(0) + offsetof(E, offset));
    const uint64_t n = get<uint64_t>(b, entry_at(0) + offsetof(E, stored_size));
    b[off + n / 2] ^= std::byte{0x10};
    add("bit_flip_in_blob", b, "checksum mismatch");
  }
  {
    auto b = good;
    b[offsetof(H, header_checksum) + 3] ^= std::byte{0x01};
    add("bit_flip_in_header_checksum", b, "header checksum");
  }
  {
    auto b = good;
    // The last padding byte before the first blob (not under any checksum).
    const uint64_t off = get<uint64_t>(b, entry_at(0) + offsetof(E, offset));
    b[off - 1] = std::byte{0x5a};
    add("nonzero_padding", b, "padding");
  }
  {
    prep::DecalModel m = small_model();
    m.cell_segments[1][1] = 99;  // end vertex past the 5 line vertices
    add("index_out_of_range", model_package_bytes(m, {prep::Codec::zstd, 3}),
        "cell_segments[1].end = 99", true);
  }
  {
    prep::DecalModel m = small_model();
    m.qt_node[0] = {0, 4};  // internal node whose 4 children run past the 6 nodes
    add("child_nodes_out_of_range", model_package_bytes(m, {prep::Codec::none, 0}), "qt_node[0]",
        true);
  }
  return v;
}

std::vector<std::pair<std::string, std::vector<std::byte>>> seed_corpus() {
  std::vector<std::pair<std::string, std::vector<std::byte>>> out;
  const auto small = small_model();
  const auto good = model_package_bytes(small, {prep::Codec::zstd, 3});
  out.emplace_back("valid_small_zstd.decals", good);
  out.emplace_back("valid_small_none.decals", model_package_bytes(small, {prep::Codec::none, 0}));
  out.emplace_back("valid_empty_model.decals",
                   model_package_bytes(prep::DecalModel{}, {prep::Codec::zstd, 3}));
  for (auto& h : hostile_variants(good))
    out.emplace_back("broken_" + h.name + ".decals", std::move(h.bytes));
  return out;
}

}  // namespace decal_test
