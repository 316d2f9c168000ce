// The work folder of a tileset build (tileset_work.hpp): the cleaned parts
// written back to back in scene order to parts.bin, with a packed R-tree of
// their boxes (part_index.hpp), and read back one tile's window at a time.
#include "tileset_work.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <limits>
#include <set>
#include <type_traits>

#include "part_index.hpp"
#include "prep/error.hpp"
#include "prep/manifest_json.hpp"
#include "prep/stage_error.hpp"

namespace prep::tiling {

namespace {

// A part's record in parts.bin: this head, then `rings` uint32 point counts
// (the shell's first, then each hole's; one for a line) padded to 8 bytes,
// then the points as x, y doubles (exact: the bytes are the doubles).
struct PartHead {
  uint8_t kind;
  uint8_t closed;
  uint16_t reserved;
  uint32_t layer;
  int64_t fid;
  int32_t part;
  uint32_t rings;
  // area, length, width, order value, colour value: as their bytes, so a
  // NaN and the sign of a zero come back as they went.
  double keys[5];
};
static_assert(sizeof(PartHead) == 64, "PartHead is stored as its bytes");
static_assert(std::is_trivially_copyable_v<Point2> && sizeof(Point2) == 16,
              "points are stored as their bytes");

constexpr uint64_t counts_bytes(uint64_t rings) {
  return (4 * rings + 7) / 8 * 8;
}

}  // namespace

// ---------------------------------------------------------------- writer --

struct PartWriter::Impl {
  std::string path, boxes_path, index_path;
  std::FILE* data = nullptr;
  std::FILE* boxes = nullptr;
  uint64_t offset = 0;
  std::vector<char> record;
};

PartWriter::PartWriter(const WorkPaths& paths) : impl_(std::make_unique<Impl>()) {
  impl_->path = paths.parts();
  impl_->boxes_path = paths.boxes();
  impl_->index_path = paths.parts_index();
  // The work folder is an intermediate: nothing here is fsynced, and a
  // machine that loses power mid-build runs the prepare step again.
  for (auto [file, path] :
       {std::pair{&impl_->data, &impl_->path}, std::pair{&impl_->boxes, &impl_->boxes_path}}) {
    *file = std::fopen(path->c_str(), "wb");
    if (!*file)
      fail<output_error>(kTilesetStage, "cannot create " + *path + ": " + std::strerror(errno));
    std::setvbuf(*file, nullptr, _IOFBF, 1 << 20);
  }
}

PartWriter::~PartWriter() {
  if (impl_->boxes) std::fclose(impl_->boxes);
  if (impl_->data) std::fclose(impl_->data);
}

void PartWriter::add(const SceneFeatures& chunk) {
  std::vector<char>& rec = impl_->record;
  // One part: its head, counts and points to parts.bin, its box and place
  // to boxes.bin.
  auto write = [&](PartKind kind, const FeatureKeys& id, uint32_t layer, bool closed,
                   const double(&keys)[5], const Ring& outer, const std::vector<Ring>* holes) {
    const uint64_t rings = 1 + (holes ? holes->size() : 0);
    uint64_t points = outer.size();
    if (holes)
      for (const Ring& h : *holes) points += h.size();
    const uint64_t bytes = sizeof(PartHead) + counts_bytes(rings) + 16 * points;
    if (rings > std::numeric_limits<uint32_t>::max() ||
        bytes > std::numeric_limits<uint32_t>::max())
      fail<resource_error>(kTilesetStage,
                           "a part of " + std::to_string(points) + " points in " +
                               std::to_string(rings) +
                               " rings is larger than a tileset part may be (4 GiB)");
    rec.assign(size_t(bytes), 0);
    PartHead head{};
    head.kind = uint8_t(kind);
    head.closed = closed ? 1 : 0;
    head.layer = layer;
    head.fid = id.fid;
    head.part = id.part;
    head.rings = uint32_t(rings);
    std::memcpy(head.keys, keys, sizeof head.keys);
    std::memcpy(rec.data(), &head, sizeof head);
    char* counts = rec.data() + sizeof head;
    char* pts = counts + counts_bytes(rings);
    auto put_ring = [&](const Ring& r, size_t i) {
      const auto n = uint32_t(r.size());
      std::memcpy(counts + 4 * i, &n, 4);
      if (!r.empty()) std::memcpy(pts, r.data(), 16 * r.size());
      pts += 16 * r.size();
    };
    put_ring(outer, 0);
    if (holes)
      for (size_t i = 0; i < holes->size(); ++i) put_ring((*holes)[i], i + 1);
    const Extent b = ring_box(outer);
    const BoxRecord box{
        static_cast<int32_t>(kind), uint32_t(bytes), b.xmin, b.ymin, b.xmax, b.ymax, impl_->offset};
    if (std::fwrite(rec.data(), 1, rec.size(), impl_->data) != rec.size())
      fail<output_error>(kTilesetStage,
                         "cannot write " + impl_->path + ": " + std::strerror(errno));
    if (std::fwrite(&box, sizeof box, 1, impl_->boxes) != 1)
      fail<output_error>(kTilesetStage,
                         "cannot write " + impl_->boxes_path + ": " + std::strerror(errno));
    impl_->offset += bytes;
    ++seq_[static_cast<int>(kind)];
    if (!outer.empty()) {  // the running extent from the part's box, not its points again
      extend(box_, Point2{b.xmin, b.ymin});
      extend(box_, Point2{b.xmax, b.ymax});
    }
  };
  for (const ScenePolygon& p : chunk.polygons) {
    const double keys[5] = {p.area, 0, 0, p.order_value, p.color_value};
    write(PartKind::polygon, p, p.layer, false, keys, p.shell, &p.holes);
  }
  for (const SceneLine& l : chunk.lines) {
    const double keys[5] = {0, l.length, l.width, l.order_value, l.color_value};
    write(PartKind::line, l, l.layer, l.closed, keys, l.points, nullptr);
  }
  for (const SceneLine& l : chunk.dynamic_lines) {
    const double keys[5] = {0, l.length, l.width, l.order_value, l.color_value};
    write(PartKind::dynamic_line, l, l.layer, l.closed, keys, l.points, nullptr);
  }
  half_width_ = std::max(half_width_, stroke_half_width(chunk));
}

void PartWriter::close() {
  for (auto [file, path] :
       {std::pair{&impl_->data, &impl_->path}, std::pair{&impl_->boxes, &impl_->boxes_path}}) {
    if (!*file) continue;
    const bool ok = std::fclose(*file) == 0;
    *file = nullptr;
    if (!ok) fail<output_error>(kTilesetStage, "cannot write " + *path);
  }
  write_box_index(impl_->boxes_path, impl_->index_path);
}

Extent PartWriter::extent() const {
  return box_.xmax >= box_.xmin ? box_ : Extent{};
}

std::vector<TileKey> planned_tiles(const WorkPaths& paths, const TilePlan& plan) {
  std::FILE* f = std::fopen(paths.boxes().c_str(), "rb");
  if (!f) fail<output_error>(kTilesetStage, "cannot read " + paths.boxes());
  std::set<TileKey> keys;
  const double ox = plan.frame.origin_x, oy = plan.frame.origin_y;
  std::vector<BoxRecord> buf(4096);
  for (;;) {
    const size_t n = std::fread(buf.data(), sizeof(BoxRecord), buf.size(), f);
    for (size_t i = 0; i < n; ++i) {
      const BoxRecord& r = buf[i];
      const double by =
          r.kind == static_cast<int>(PartKind::dynamic_line) ? plan.dynamic_margin : plan.margin;
      const TileRange t = tile_range({r.xmin, r.ymin, r.xmax, r.ymax}, by, ox, oy, plan.size);
      // A part (with its stroke margin) over more tiles than any index can
      // list would plan for ever: refused, with the numbers.
      const double reach = double(t.hi.x - t.lo.x + 1) * double(t.hi.y - t.lo.y + 1);
      if (reach > double(kMaxPlannedTiles) || keys.size() > kMaxPlannedTiles) {
        char m[256];
        std::snprintf(m, sizeof m,
                      "the tiles of %.10g m reached by the parts (each with its stroke margin of "
                      "%.10g m) number more than %zu; use a larger --tile-size or narrower lines",
                      plan.size, by, kMaxPlannedTiles);
        std::fclose(f);
        fail<resource_error>(kTilesetStage, m);
      }
      for (int64_t y = t.lo.y; y <= t.hi.y; ++y)
        for (int64_t x = t.lo.x; x <= t.hi.x; ++x) keys.insert({x, y});
    }
    if (n < buf.size()) break;
  }
  std::fclose(f);
  return {keys.begin(), keys.end()};
}

// ---------------------------------------------------------------- reader --

namespace {

// The part in `rec` (its box record `r`, already checked to lie within the
// file) into `p` or `l`; output_error naming the file and the offset when
// the record's counts do not fill it exactly.
struct RecordParser {
  const std::string& path;

  [[noreturn]] void bad(const BoxRecord& r, const std::string& what) const {
    fail<output_error>(kTilesetStage, path + ": the part at offset " + std::to_string(r.offset) +
                                          " is not a part this build wrote: " + what);
  }

  // The head, and each ring's points (the shell's or the line's first).
  PartHead parse(const BoxRecord& r, const char* rec, std::vector<Ring>& rings) const {
    PartHead head;
    if (r.bytes < sizeof head) bad(r, "shorter than its head");
    std::memcpy(&head, rec, sizeof head);
    if (head.kind != r.kind) bad(r, "kind " + std::to_string(head.kind));
    const uint64_t after = r.bytes - sizeof head;
    if (head.rings < 1 || (head.kind != 0 && head.rings != 1) || counts_bytes(head.rings) > after)
      bad(r, std::to_string(head.rings) + " rings");
    const char* counts = rec + sizeof head;
    uint64_t points = 0;
    for (uint32_t i = 0; i < head.rings; ++i) {
      uint32_t n;
      std::memcpy(&n, counts + 4 * i, 4);
      points += n;
    }
    if (points * 16 != after - counts_bytes(head.rings))
      bad(r, std::to_string(points) + " points in " + std::to_string(r.bytes) + " bytes");
    rings.resize(head.rings);
    const char* pts = counts + counts_bytes(head.rings);
    for (uint32_t i = 0; i < head.rings; ++i) {
      uint32_t n;
      std::memcpy(&n, counts + 4 * i, 4);
      rings[i].resize(n);
      if (n > 0) std::memcpy(static_cast<void*>(rings[i].data()), pts, 16 * size_t(n));
      pts += 16 * size_t(n);
    }
    return head;
  }
};

// The most bytes read in one pread when consecutive records are joined.
constexpr uint64_t kReadRun = 1 << 20;

}  // namespace

struct PartReader::Impl {
  std::string path;
  int fd = -1;
  std::unique_ptr<BoxIndex> index;
  std::vector<BoxRecord> hits;
  std::vector<char> buf;
  std::vector<Ring> rings;
};

PartReader::PartReader(const WorkPaths& paths) : impl_(std::make_unique<Impl>()) {
  impl_->path = paths.parts();
  impl_->fd = ::open(impl_->path.c_str(), O_RDONLY | O_CLOEXEC);
  struct stat st {};
  if (impl_->fd < 0 || ::fstat(impl_->fd, &st) != 0)
    fail<output_error>(kTilesetStage, "cannot open " + impl_->path + ": " + std::strerror(errno));
  impl_->index = std::make_unique<BoxIndex>(paths.parts_index(), uint64_t(st.st_size));
}

PartReader::~PartReader() {
  if (impl_->fd >= 0) ::close(impl_->fd);
}

void PartReader::read_tile(const TilePlan& plan, const TileKey& key, SceneFeatures& scene,
                           PartFilter* filter) {
  scene.polygons.clear();
  scene.lines.clear();
  scene.dynamic_lines.clear();
  const double ox = plan.frame.origin_x, oy = plan.frame.origin_y;
  const Extent sq = plan.square(key);
  // A window wider than any reach: the exact test is tile_range's, on each
  // part's exact box.
  const double by = std::max(plan.margin, plan.dynamic_margin) + 1.0;
  std::vector<BoxRecord>& hits = impl_->hits;
  hits.clear();
  impl_->index->query({sq.xmin - ox - by, sq.ymin - oy - by, sq.xmax - ox + by, sq.ymax - oy + by},
                      hits);
  std::erase_if(hits, [&](const BoxRecord& r) {
    const double m =
        r.kind == static_cast<int>(PartKind::dynamic_line) ? plan.dynamic_margin : plan.margin;
    return !tile_range({r.xmin, r.ymin, r.xmax, r.ymax}, m, ox, oy, plan.size).holds(key);
  });
  // File order is scene order within each kind.
  std::sort(hits.begin(), hits.end(),
            [](const BoxRecord& a, const BoxRecord& b) { return a.offset < b.offset; });
  const RecordParser parser{impl_->path};
  std::vector<Ring>& rings = impl_->rings;
  for (size_t i = 0; i < hits.size();) {
    // A run of records that follow each other in the file, read at once.
    size_t j = i + 1;
    uint64_t run = hits[i].bytes;
    while (j < hits.size() && hits[j].offset == hits[i].offset + run &&
           run + hits[j].bytes <= kReadRun)
      run += hits[j++].bytes;
    impl_->buf.resize(size_t(run));
    errno = 0;
    if (!pread_exact(impl_->fd, impl_->buf.data(), size_t(run), hits[i].offset))
      fail<output_error>(kTilesetStage, "cannot read " + impl_->path + " at offset " +
                                            std::to_string(hits[i].offset) + ": " +
                                            (errno ? std::strerror(errno) : "short file"));
    for (size_t k = i; k < j; ++k) {
      const BoxRecord& r = hits[k];
      const PartHead head = parser.parse(r, impl_->buf.data() + (r.offset - hits[i].offset), rings);
      FeatureKeys keys;
      keys.fid = head.fid;
      keys.part = head.part;
      keys.order_value = head.keys[3];
      keys.color_value = head.keys[4];
      if (head.kind == static_cast<int>(PartKind::polygon)) {
        ScenePolygon p;
        static_cast<FeatureKeys&>(p) = keys;
        p.shell = std::move(rings[0]);
        p.holes.assign(std::make_move_iterator(rings.begin() + 1),
                       std::make_move_iterator(rings.end()));
        p.layer = head.layer;
        p.area = head.keys[0];
        if (filter && !filter->polygon(p)) continue;
        scene.polygons.push_back(std::move(p));
      } else {
        const bool dynamic = head.kind == static_cast<int>(PartKind::dynamic_line);
        SceneLine l;
        static_cast<FeatureKeys&>(l) = keys;
        l.points = std::move(rings[0]);
        l.closed = head.closed != 0;
        l.layer = head.layer;
        l.length = head.keys[1];
        l.width = head.keys[2];
        if (filter && !filter->line(l, dynamic)) continue;
        (dynamic ? scene.dynamic_lines : scene.lines).push_back(std::move(l));
      }
    }
    i = j;
  }
}

// --------------------------------------------------------------- entries --

EntryWriter::EntryWriter(const std::string& path) : path_(path) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) fail<output_error>(kTilesetStage, "cannot create " + path + ": " + std::strerror(errno));
}

EntryWriter::~EntryWriter() {
  if (f_) std::fclose(f_);
}

void EntryWriter::add(const ManifestEntry& e) {
  // manifest.json is {"entries": [...]} dumped with indent 1: an entry sits
  // two levels deep, so each of its lines gets two more spaces. Entries
  // are separated by ",\n" (written by write_manifest_from).
  const std::string text = manifest_entry_json(e).dump(1);
  std::string out;
  out.reserve(text.size() + 64);
  if (count_ > 0) out += ",\n";
  out += "  ";
  for (char c : text) {
    out += c;
    if (c == '\n') out += "  ";
  }
  if (std::fwrite(out.data(), 1, out.size(), f_) != out.size())
    fail<output_error>(kTilesetStage, "cannot write " + path_);
  ++count_;
}

void EntryWriter::close() {
  if (!f_) return;
  const bool ok = std::fclose(f_) == 0;
  f_ = nullptr;
  if (!ok) fail<output_error>(kTilesetStage, "cannot write " + path_);
}

void write_manifest_from(const std::vector<std::string>& entry_files, uint64_t entries,
                         const std::string& path) {
  const std::string tmp = path + ".tmp";
  std::FILE* out = std::fopen(tmp.c_str(), "wb");
  if (!out) fail<output_error>(kTilesetStage, "cannot write " + path + ": " + std::strerror(errno));
  bool ok = true;
  auto put = [&](const char* s, size_t n) { ok = ok && std::fwrite(s, 1, n, out) == n; };
  if (entries == 0) {
    const std::string text = "{\n \"entries\": []\n}\n";
    put(text.data(), text.size());
  } else {
    const std::string head = "{\n \"entries\": [\n";
    put(head.data(), head.size());
    bool first = true;
    std::vector<char> buf(1 << 16);
    for (const std::string& file : entry_files) {
      std::FILE* in = std::fopen(file.c_str(), "rb");
      if (!in) {
        std::fclose(out);
        std::remove(tmp.c_str());
        fail<output_error>(kTilesetStage, "cannot read " + file);
      }
      // Each file's entries are joined with ",\n"; files are joined the same way.
      bool any = false;
      for (;;) {
        const size_t n = std::fread(buf.data(), 1, buf.size(), in);
        if (n == 0) break;
        if (!any && !first) put(",\n", 2);
        any = true;
        put(buf.data(), n);
      }
      std::fclose(in);
      if (any) first = false;
    }
    const std::string tail = "\n ]\n}\n";
    put(tail.data(), tail.size());
  }
  ok = std::fclose(out) == 0 && ok;
  if (!ok || std::rename(tmp.c_str(), path.c_str()) != 0) {
    std::remove(tmp.c_str());
    fail<output_error>(kTilesetStage, "cannot write " + path);
  }
}

// ------------------------------------------------------------- plan.json --

namespace {
nlohmann::json number(double v) {
  return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v);
}
double number_of(const nlohmann::json& j) {
  return j.is_null() ? std::numeric_limits<double>::quiet_NaN() : j.get<double>();
}
}  // namespace

nlohmann::json frame_to_json(const SceneFrame& f) {
  return {{"crs_wkt", f.crs_wkt},   {"description", f.description}, {"origin_x", f.origin_x},
          {"origin_y", f.origin_y}, {"tm_lon0", number(f.tm_lon0)}, {"tm_lat0", number(f.tm_lat0)}};
}

SceneFrame frame_from_json(const nlohmann::json& j) {
  SceneFrame f;
  f.crs_wkt = j.at("crs_wkt").get<std::string>();
  f.description = j.at("description").get<std::string>();
  f.origin_x = j.at("origin_x").get<double>();
  f.origin_y = j.at("origin_y").get<double>();
  f.tm_lon0 = number_of(j.at("tm_lon0"));
  f.tm_lat0 = number_of(j.at("tm_lat0"));
  return f;
}

nlohmann::json counts_to_json(const std::vector<LayerCounts>& layers) {
  nlohmann::json a = nlohmann::json::array();
  for (const LayerCounts& c : layers) a.push_back(layer_counts_json(c));
  return a;
}

std::vector<LayerCounts> counts_from_json(const nlohmann::json& j) {
  std::vector<LayerCounts> out;
  for (const nlohmann::json& c : j) {
    LayerCounts l;
    l.layer = c.at("layer").get<std::string>();
    for (const auto& [name, m] : kLayerCountFields) l.*m = c.at(name).get<uint64_t>();
    out.push_back(std::move(l));
  }
  return out;
}

void remove_tree(const std::string& path) {
  std::error_code ec;
  std::filesystem::remove_all(path, ec);
}

}  // namespace prep::tiling
