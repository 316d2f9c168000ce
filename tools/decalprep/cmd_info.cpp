// cmd_info.cpp — `decalprep info PACKAGE [--json]`: header, metadata and
// blob table of a package (formats/SPEC.md), as text or JSON. Checks the
// structure (decal::read_layout) but not the blob checksums; `verify` does.
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <nlohmann/json.hpp>
#include <span>
#include <string>
#include <vector>

#include "command.hpp"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "prep/files.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

namespace {

using json = nlohmann::ordered_json;

// The file's bytes, memory-mapped (info reads only the header, the table
// and the metadata, so even a huge package costs a few pages).
class MappedFile {
 public:
  explicit MappedFile(const std::string& path) {
    // The reader's open: a FIFO or a device is refused without blocking.
    int fd = -1;
    uint64_t size = 0;
    if (const decal::Status s = decal::open_regular_file(path, fd, size); !s)
      prep::fail<prep::input_error>(prep::kInfoStage, s.message);
    size_ = static_cast<size_t>(size);
    if (size_ > 0) {
      void* m = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
      if (m == MAP_FAILED) {
        const int err = errno;
        ::close(fd);
        prep::fail<prep::input_error>(prep::kInfoStage,
                                      "cannot map '" + path + "': " + std::strerror(err));
      }
      data_ = static_cast<const std::byte*>(m);
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (data_) ::munmap(const_cast<std::byte*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  std::span<const std::byte> bytes() const { return {data_, size_}; }

 private:
  const std::byte* data_ = nullptr;
  size_t size_ = 0;
};

using prep::hex64;

std::string type_name(uint32_t t) {
  const auto n = decal::element_type_name(static_cast<decal::ElementType>(t));
  return n.empty() ? std::to_string(t) : std::string(n);
}

json blob_json(size_t index, const decal::BlobTableEntry& e) {
  return {{"index", index},
          {"id", e.id},
          {"name", std::string(e.name, strnlen(e.name, decal::kBlobNameSize))},
          {"known", decal::find_blob_info(static_cast<decal::BlobId>(e.id)) != nullptr},
          {"type", type_name(e.element_type)},
          {"stride", e.stride},
          {"count", e.count},
          {"codec", std::string(decal::codec_name(e.codec))},
          {"offset", e.offset},
          {"stored_size", e.stored_size},
          {"raw_size", e.raw_size},
          {"xxh64", hex64(e.checksum)}};
}

// A tileset: its frame, tiling, the scene's per-layer counts (each feature
// once) and one line per tile; --json prints tileset.json as read.
void run_tileset_info(const std::string& dir, bool as_json) {
  const prep::TilesetIndex ix = prep::read_tileset_index(dir);
  if (as_json) {
    std::cout << prep::tileset_index_json(ix);
    return;
  }
  uint64_t bytes = 0;
  for (const prep::TileEntry& t : ix.tiles) bytes += t.bytes;
  std::printf("tileset   %s\n", dir.c_str());
  std::printf("version   %d.%d (%s)\n", ix.major, ix.minor, ix.generator.c_str());
  std::printf("frame     %s\n", ix.frame.description.c_str());
  std::printf("tiling    grid of %.10g m tiles, margin %.10g m (dynamic lines %.10g m)\n",
              ix.tile_size, ix.margin, ix.dynamic_margin);
  std::printf("extent    %.3f %.3f %.3f %.3f (frame CRS)\n", ix.extent.xmin, ix.extent.ymin,
              ix.extent.xmax, ix.extent.ymax);
  size_t all_tiles = ix.tiles.size();
  uint64_t all_bytes = bytes;
  for (const prep::TileLevel& l : ix.levels) {
    all_tiles += l.tiles.size();
    for (const prep::TileEntry& t : l.tiles) all_bytes += t.bytes;
  }
  if (ix.levels.empty())
    std::printf("tiles     %zu packages, %" PRIu64 " bytes\n", ix.tiles.size(), bytes);
  else
    std::printf("tiles     %zu packages, %" PRIu64
                " bytes at full detail (level 0); %zu packages, "
                "%" PRIu64 " bytes with the %zu overview levels\n",
                ix.tiles.size(), bytes, all_tiles, all_bytes, ix.levels.size());
  std::printf("features  (each once, however many tiles it reaches; %" PRIu64
              " manifest entries in manifest.json)\n",
              ix.entry_count);
  std::printf("  %-24s %10s %10s %10s %12s %10s\n", "layer", "read", "kept", "repaired",
              "clipped_away", "dropped");
  prep::LayerCounts total;
  for (const prep::LayerCounts& c : ix.manifest.layers) {
    std::printf("  %-24s %10" PRIu64 " %10" PRIu64 " %10" PRIu64 " %12" PRIu64 " %10" PRIu64 "\n",
                c.layer.c_str(), c.read, c.kept, c.repaired, c.clipped_away, c.dropped);
    total += c;
  }
  std::printf("  %-24s %10" PRIu64 " %10" PRIu64 " %10" PRIu64 " %12" PRIu64 " %10" PRIu64 "\n",
              "(total)", total.read, total.kept, total.repaired, total.clipped_away, total.dropped);
  std::printf("  %-22s %10s %10s %10s %12s\n", "tile", "polygons", "lines", "dynamic", "bytes");
  for (const prep::TileEntry& t : ix.tiles)
    std::printf("  %-22s %10" PRIu64 " %10" PRIu64 " %10" PRIu64 " %12" PRIu64 "\n", t.file.c_str(),
                t.polygons, t.lines, t.dynamic_lines, t.bytes);
  if (ix.levels.empty()) return;
  // Overview levels (formats/SPEC.md "Overview levels"): counts of parts.
  std::printf("levels    %zu overview levels (level 0: the tiles above, resolution %.10g m%s)\n",
              ix.levels.size(), ix.resolution, ix.resolution > 0 ? "" : ", exact");
  for (const prep::TileLevel& l : ix.levels) {
    uint64_t lbytes = 0;
    for (const prep::TileEntry& t : l.tiles) lbytes += t.bytes;
    prep::LayerCounts sum;
    for (const prep::LayerCounts& c : l.layers) sum += c;
    std::printf(
        "  level %d: %.10g m tiles, resolution %.10g m, min area %.10g m2, min length "
        "%.10g m; %zu packages, %" PRIu64 " bytes; parts %" PRIu64 " of %" PRIu64 " (%" PRIu64
        " dropped small, %" PRIu64 " holes dropped small), vertices %" PRIu64 " of %" PRIu64 "\n",
        l.level, l.tile_size, l.resolution, l.min_area, l.min_length, l.tiles.size(), lbytes,
        sum.parts, sum.read, sum.dropped_small, sum.holes_dropped_small, sum.vertices_out,
        sum.vertices_in);
    std::printf("    %-24s %10s %10s %13s %19s %12s %12s\n", "layer", "parts_in", "parts",
                "dropped_small", "holes_dropped_small", "vertices_in", "vertices_out");
    for (const prep::LayerCounts& c : l.layers)
      std::printf("    %-24s %10" PRIu64 " %10" PRIu64 " %13" PRIu64 " %19" PRIu64 " %12" PRIu64
                  " %12" PRIu64 "\n",
                  c.layer.c_str(), c.read, c.parts, c.dropped_small, c.holes_dropped_small,
                  c.vertices_in, c.vertices_out);
  }
}

void run_info(const std::string& path, bool as_json) {
  if (prep::is_tileset(path)) return run_tileset_info(path, as_json);
  const MappedFile file(path);
  const std::span<const std::byte> bytes = file.bytes();
  decal::PackageLayout layout;
  if (decal::Status s = decal::read_layout(bytes, layout); !s)
    prep::fail<prep::format_error>(prep::kInfoStage, path + ": " + s.message);
  const decal::FileHeader& h = layout.header;
  const std::string meta_text(reinterpret_cast<const char*>(bytes.data() + h.metadata_offset),
                              h.metadata_size);
  const json meta = decalprep::parse_metadata(meta_text, path, prep::kInfoStage);

  if (as_json) {
    json out = {{"path", path},
                {"file_size", h.file_size},
                {"version", {{"major", h.version_major}, {"minor", h.version_minor}}},
                {"flags", h.flags},
                {"header",
                 {{"header_size", h.header_size},
                  {"blob_entry_size", h.blob_entry_size},
                  {"blob_count", h.blob_count},
                  {"table_offset", h.table_offset},
                  {"table_xxh64", hex64(h.table_checksum)},
                  {"metadata_offset", h.metadata_offset},
                  {"metadata_size", h.metadata_size},
                  {"metadata_xxh64", hex64(h.metadata_checksum)},
                  {"header_xxh64", hex64(h.header_checksum)}}},
                {"metadata", meta},
                {"blobs", json::array()}};
    for (size_t i = 0; i < layout.entries.size(); ++i)
      out["blobs"].push_back(blob_json(i, layout.entries[i]));
    std::cout << out.dump(2) << "\n";
    return;
  }

  std::printf("package   %s\n", path.c_str());
  std::printf("size      %" PRIu64 " bytes\n", h.file_size);
  std::printf("version   %u.%u\n", h.version_major, h.version_minor);
  std::printf("flags     0x%08x%s\n", h.flags,
              (h.flags & decal::kFlagAllUncompressed) ? " (all blobs uncompressed)" : "");
  std::printf("metadata  %" PRIu64 " bytes at %" PRIu64 "\n", h.metadata_size, h.metadata_offset);
  if (meta.is_object())
    for (auto it = meta.begin(); it != meta.end(); ++it) {
      std::string v = it.value().is_string() ? it.value().get<std::string>() : it.value().dump();
      if (v.size() > 100) v = v.substr(0, 97) + "...";
      std::printf("  %-28s %s\n", it.key().c_str(), v.c_str());
    }
  std::printf("blobs     %u\n", h.blob_count);
  std::printf("  %3s %5s %-20s %-7s %6s %12s %12s %12s %-5s %12s %-16s\n", "#", "id", "name",
              "type", "stride", "count", "raw", "stored", "codec", "offset", "xxh64");
  for (size_t i = 0; i < layout.entries.size(); ++i) {
    const decal::BlobTableEntry& e = layout.entries[i];
    const std::string name(e.name, strnlen(e.name, decal::kBlobNameSize));
    std::printf("  %3zu %5u %-20s %-7s %6u %12" PRIu64 " %12" PRIu64 " %12" PRIu64
                " %-5s %12" PRIu64 " %s\n",
                i, e.id, name.c_str(), type_name(e.element_type).c_str(), e.stride, e.count,
                e.raw_size, e.stored_size, std::string(decal::codec_name(e.codec)).c_str(),
                e.offset, hex64(e.checksum).c_str());
  }
}

constexpr decalprep::CommandHelp kInfoHelp{
    "info", "Print a package's header, metadata and blob table",
    "Checks the package structure but not blob checksums (use verify).\n"
    "A tileset directory prints its index: frame, tiling, the scene's per-layer counts and one\n"
    "line per tile, then each overview level: its tiles, bytes, resolution and per-layer\n"
    "parts, drops and vertices.\n"
    "Examples:\n  decalprep info city.decals\n  decalprep info city.decals --json | jq .blobs\n"
    "  decalprep info country/"};

const decalprep::CommandRegistrar kInfo(20, kInfoHelp, [](CLI::App* cmd) {
  auto path = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  cmd->add_option("PACKAGE", *path, "the .decals file, or a tileset directory")->required();
  cmd->add_flag("--json", *as_json, "print JSON (every blob of the table is listed)");
  cmd->callback([path, as_json] {
    run_info(*path, *as_json);
    decalprep::set_exit_code(prep::ExitCode::ok);
  });
});

}  // namespace
