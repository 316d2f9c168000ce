// The tileset index, tileset.json (formats/SPEC.md "Tilesets"): written by
// the pipeline, read as untrusted input by every tool that takes a tileset.
#include <ogr_spatialref.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <initializer_list>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "decal/reader.hpp"
#include "prep/error.hpp"
#include "prep/files.hpp"
#include "prep/manifest_json.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

namespace prep {

// An overview level's per-layer record in tileset.json (formats/SPEC.md
// "Overview levels"), in its words: counts of parts, read into LayerCounts'
// members (parts_in is `read`).
constexpr std::pair<const char*, uint64_t LayerCounts::*> kLevelCountFields[] = {
    {"parts_in", &LayerCounts::read},
    {"parts", &LayerCounts::parts},
    {"dropped_small", &LayerCounts::dropped_small},
    {"holes_dropped_small", &LayerCounts::holes_dropped_small},
    {"vertices_in", &LayerCounts::vertices_in},
    {"vertices_out", &LayerCounts::vertices_out}};

namespace {

using json = nlohmann::json;

json extent_json(const Extent& e) {
  return json::array({e.xmin, e.ymin, e.xmax, e.ymax});
}

// Every read goes through these: a missing key or a wrong type names the
// file and the field.
class Fields {
 public:
  explicit Fields(std::string file) : file_(std::move(file)) {}
  [[noreturn]] void bad(const std::string& field, const std::string& what) const {
    fail<format_error>(kNoStage, file_ + ": " + field + ": " + what);
  }
  const json& at(const json& j, const char* key, const std::string& where) const {
    if (!j.is_object()) bad(where, "is not an object");
    auto it = j.find(key);
    if (it == j.end()) bad(where.empty() ? key : where + "." + key, "missing");
    return *it;
  }
  double number(const json& j, const char* key, const std::string& where) const {
    const json& v = at(j, key, where);
    if (!v.is_number() || !std::isfinite(v.get<double>()))
      bad(where + "." + key, "is not a finite number");
    return v.get<double>();
  }
  uint64_t count(const json& j, const char* key, const std::string& where) const {
    const json& v = at(j, key, where);
    if (!v.is_number_unsigned()) bad(where + "." + key, "is not a non-negative integer");
    return v.get<uint64_t>();
  }
  int64_t integer(const json& j, const char* key, const std::string& where) const {
    const json& v = at(j, key, where);
    if (!v.is_number_integer()) bad(where + "." + key, "is not an integer");
    if (v.is_number_unsigned() && v.get<uint64_t>() > uint64_t(INT64_MAX))
      bad(where + "." + key, "is out of range");
    return v.get<int64_t>();
  }
  std::string text(const json& j, const char* key, const std::string& where) const {
    const json& v = at(j, key, where);
    if (!v.is_string()) bad(where + "." + key, "is not a string");
    return v.get<std::string>();
  }
  uint64_t hash(const json& j, const char* key, const std::string& where) const {
    const std::string h = text(j, key, where);
    if (h.size() != 16 || h.find_first_not_of("0123456789abcdef") != std::string::npos)
      bad(where + "." + key, "is not 16 lowercase hex digits");
    return std::stoull(h, nullptr, 16);
  }
  Extent extent(const json& j, const char* key, const std::string& where) const {
    const json& v = at(j, key, where);
    if (!v.is_array() || v.size() != 4) bad(where + "." + key, "is not [xmin, ymin, xmax, ymax]");
    double c[4];
    for (int i = 0; i < 4; ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>()))
        bad(where + "." + key, "is not [xmin, ymin, xmax, ymax] of finite numbers");
      c[i] = v[i].get<double>();
    }
    return {c[0], c[1], c[2], c[3]};
  }
  LayerCounts layer_counts(const json& j, const std::string& where) const {
    LayerCounts c;
    c.layer = text(j, "layer", where);
    for (const auto& [name, m] : kLayerCountFields) c.*m = count(j, name, where);
    return c;
  }
  // An overview level's per-layer counts (level_counts_json).
  LayerCounts level_counts(const json& j, const std::string& where) const {
    LayerCounts c;
    c.layer = text(j, "layer", where);
    // holes_dropped_small is absent in indexes written before holes were
    // dropped: none were.
    for (const auto& [name, m] : kLevelCountFields)
      if (m != &LayerCounts::holes_dropped_small || j.contains(name)) c.*m = count(j, name, where);
    c.kept = c.parts;
    if (c.read != c.parts + c.dropped_small) bad(where, "parts_in is not parts + dropped_small");
    return c;
  }

 private:
  std::string file_;
};

// A level's layer record: its counts are of parts (TileLevel::layers).
json level_counts_json(const LayerCounts& c) {
  json j = {{"layer", c.layer}};
  for (const auto& [name, m] : kLevelCountFields) j[name] = c.*m;
  return j;
}

json tiles_json(const std::vector<TileEntry>& entries) {
  json tiles = json::array();
  for (const TileEntry& t : entries) {
    json tl = json::array();
    for (const LayerCounts& c : t.layers) tl.push_back(layer_counts_json(c));
    tiles.push_back(
        {{"x", t.key.x},
         {"y", t.key.y},
         {"square", extent_json(t.square)},
         {"origin", {t.origin_x, t.origin_y}},
         {"file", t.file},
         {"bytes", t.bytes},
         {"xxh64", hex64(t.xxh64)},
         {"counts",
          {{"polygons", t.polygons}, {"lines", t.lines}, {"dynamic_lines", t.dynamic_lines}}},
         {"layers", tl}});
  }
  return tiles;
}

// The tiles of level `level` (0: the index's own), `where` "tiles" or
// "levels[i].tiles".
std::vector<TileEntry> read_tiles(const Fields& f, const json& tiles, const std::string& where,
                                  double tile_size, int level) {
  if (!tiles.is_array()) f.bad(where, "is not an array");
  std::vector<TileEntry> out;
  std::set<TileKey> seen;
  for (size_t i = 0; i < tiles.size(); ++i) {
    const std::string w = where + "[" + std::to_string(i) + "]";
    const json& t = tiles[i];
    TileEntry e;
    e.key = {f.integer(t, "x", w), f.integer(t, "y", w)};
    // |x| * size must stay a finite, exact coordinate.
    if (std::fabs(double(e.key.x)) > 1e12 || std::fabs(double(e.key.y)) > 1e12)
      f.bad(w, "tile key out of range");
    if (!seen.insert(e.key).second) f.bad(w, "tile " + tile_name(e.key) + " is listed twice");
    e.square = f.extent(t, "square", w);
    TilePlan plan;
    plan.size = tile_size;
    const Extent want = plan.square(e.key);
    if (e.square.xmin != want.xmin || e.square.ymin != want.ymin || e.square.xmax != want.xmax ||
        e.square.ymax != want.ymax)
      f.bad(w + ".square", "does not match the tile's key and the tile size");
    const json& o = f.at(t, "origin", w);
    if (!o.is_array() || o.size() != 2 || !o[0].is_number() || !o[1].is_number())
      f.bad(w + ".origin", "is not [x, y]");
    e.origin_x = o[0].get<double>();
    e.origin_y = o[1].get<double>();
    if (std::make_pair(e.origin_x, e.origin_y) != plan.origin(e.key))
      f.bad(w + ".origin", "is not the centre of the tile's square");
    e.file = f.text(t, "file", w);
    // Only the name the writer gives: nothing that could leave the directory.
    const std::string want_file = tile_file(level, e.key);
    if (e.file != want_file) f.bad(w + ".file", "'" + e.file + "' is not " + want_file);
    e.bytes = f.count(t, "bytes", w);
    e.xxh64 = f.hash(t, "xxh64", w);
    const json& counts = f.at(t, "counts", w);
    e.polygons = f.count(counts, "polygons", w + ".counts");
    e.lines = f.count(counts, "lines", w + ".counts");
    e.dynamic_lines = f.count(counts, "dynamic_lines", w + ".counts");
    const json& tl = f.at(t, "layers", w);
    if (!tl.is_array()) f.bad(w + ".layers", "is not an array");
    for (size_t k = 0; k < tl.size(); ++k)
      e.layers.push_back(f.layer_counts(tl[k], w + ".layers[" + std::to_string(k) + "]"));
    out.push_back(std::move(e));
  }
  return out;
}

std::vector<const TileEntry*> meeting(const std::vector<TileEntry>& tiles, const Extent& view) {
  std::vector<const TileEntry*> out;
  for (const TileEntry& t : tiles) {
    if (t.square.xmin < view.xmax && view.xmin < t.square.xmax && t.square.ymin < view.ymax &&
        view.ymin < t.square.ymax)
      out.push_back(&t);
  }
  return out;
}

}  // namespace

namespace {

// What check_tileset_index found first, as "field: what".
class IndexProblem {
 public:
  bool found() const { return !text_.empty(); }
  const std::string& text() const { return text_; }
  void bad(const std::string& field, const std::string& what) {
    if (text_.empty()) text_ = field + ": " + what;
  }
  void count(const std::string& field, uint64_t v) {
    if (v > kMaxTilesetCount)
      bad(field, std::to_string(v) + " is above 2^53, the largest count an index holds");
  }
  // count() of each field `w`.NAME.
  void counts(const std::string& w,
              std::initializer_list<std::pair<const char*, uint64_t>> fields) {
    for (const auto& [name, v] : fields) count(w + "." + name, v);
  }
  // A tile entry's own counts.
  void tile(const std::string& w, const TileEntry& t) {
    counts(w, {{"bytes", t.bytes},
               {"counts.polygons", t.polygons},
               {"counts.lines", t.lines},
               {"counts.dynamic_lines", t.dynamic_lines}});
  }
  void coordinate(const std::string& field, double v) {
    if (!std::isfinite(v) || std::fabs(v) > kMaxTilesetCoordinate)
      bad(field, number_text(v) + " is not a finite coordinate within +-1e12 m");
  }
  void length(const std::string& field, double v) {
    if (!std::isfinite(v) || v < 0 || v > kMaxTilesetCoordinate)
      bad(field, number_text(v) + " is not in [0, 1e12] m");
  }
  void extent(const std::string& field, const Extent& e) {
    coordinate(field + "[0]", e.xmin);
    coordinate(field + "[1]", e.ymin);
    coordinate(field + "[2]", e.xmax);
    coordinate(field + "[3]", e.ymax);
    if (!found() && (e.xmin > e.xmax || e.ymin > e.ymax))
      bad(field, "[" + number_text(e.xmin) + ", " + number_text(e.ymin) + ", " +
                     number_text(e.xmax) + ", " + number_text(e.ymax) +
                     "] is inverted (xmin > xmax or ymin > ymax)");
  }
  // A layer record of the manifest or of a tile (`tile`: read = kept).
  void layer(const std::string& w, const LayerCounts& c, bool tile) {
    for (const auto& [name, m] : kLayerCountFields) count(w + "." + name, c.*m);
    if (found()) return;
    // Each at most 2^53: the sum cannot wrap.
    if (c.read != c.kept + c.clipped_away + c.dropped)
      bad(w, "read " + std::to_string(c.read) + " is not kept + clipped_away + dropped (" +
                 std::to_string(c.kept) + " + " + std::to_string(c.clipped_away) + " + " +
                 std::to_string(c.dropped) + ")");
    else if (c.repaired > c.kept)
      bad(w + ".repaired",
          std::to_string(c.repaired) + " is more than kept " + std::to_string(c.kept));
    else if (tile && (c.clipped_away != 0 || c.dropped != 0))
      bad(w, "a tile's layer counts have read = kept, no clipped_away or dropped");
  }
  static std::string number_text(double v) {
    char b[64];
    std::snprintf(b, sizeof b, "%.17g", v);
    return b;
  }

 private:
  std::string text_;
};

// The tiles of one level against the scene's manifest: every layer a tile
// names is the manifest's, no tile keeps more features of a layer than the
// scene kept, and every kept feature lies in some tile (a feature kept has a
// part, and every part reaches at least one tile).
void check_tiles(IndexProblem& p, const TilesetIndex& ix, const std::vector<TileEntry>& tiles,
                 const std::string& where) {
  std::map<std::string, uint64_t> scene_kept, in_tiles;
  for (const LayerCounts& c : ix.manifest.layers) scene_kept[c.layer] = c.kept;
  for (size_t i = 0; i < tiles.size() && !p.found(); ++i) {
    const TileEntry& t = tiles[i];
    const std::string w = where + "[" + std::to_string(i) + "]";
    p.tile(w, t);
    for (size_t k = 0; k < t.layers.size() && !p.found(); ++k) {
      const LayerCounts& c = t.layers[k];
      const std::string wl = w + ".layers[" + std::to_string(k) + "]";
      p.layer(wl, c, true);
      auto it = scene_kept.find(c.layer);
      if (p.found()) break;
      if (it == scene_kept.end()) {
        p.bad(wl + ".layer", "'" + c.layer + "' is not a layer of manifest.layers");
      } else if (c.kept > it->second) {
        p.bad(wl + ".kept", std::to_string(c.kept) + " features, more than the " +
                                std::to_string(it->second) + " manifest.layers says '" + c.layer +
                                "' kept");
      } else {
        uint64_t& sum = in_tiles[c.layer];
        sum = std::min(sum + c.kept, kMaxTilesetCount + 1);  // both <= 2^53: no wrap
      }
    }
  }
  for (size_t i = 0; i < ix.manifest.layers.size() && !p.found(); ++i) {
    const LayerCounts& c = ix.manifest.layers[i];
    if (in_tiles[c.layer] < c.kept)
      p.bad("manifest.layers[" + std::to_string(i) + "].kept",
            std::to_string(c.kept) + " features of '" + c.layer + "' kept, but the " +
                std::to_string(tiles.size()) + " tiles of " + where + " hold " +
                std::to_string(in_tiles[c.layer]) + " of them in all");
  }
}

}  // namespace

std::string tileset_index_problem(const TilesetIndex& ix) {
  IndexProblem p;
  if (ix.major != kTilesetMajor || ix.minor < 0)
    p.bad("tileset_version",
          std::to_string(ix.major) + "." + std::to_string(ix.minor) +
              " is not supported (this reader: " + std::to_string(kTilesetMajor) + ".x)");
  if (!p.found()) {
    // PROJ through GDAL, as every stage that takes a CRS: a frame no CRS
    // library reads would leave every consumer guessing (render would drape
    // nothing on flat terrain).
    OGRSpatialReference srs;
    if (ix.frame.crs_wkt.empty() || srs.importFromWkt(ix.frame.crs_wkt.c_str()) != OGRERR_NONE)
      p.bad("frame.crs_wkt", "'" + ix.frame.crs_wkt.substr(0, 60) +
                                 (ix.frame.crs_wkt.size() > 60 ? "..." : "") +
                                 "' is not a CRS WKT PROJ can read");
  }
  p.coordinate("frame.origin[0]", ix.frame.origin_x);
  p.coordinate("frame.origin[1]", ix.frame.origin_y);
  if (!(ix.tile_size >= kMinTileSize && ix.tile_size <= kMaxTileSize))
    p.bad("tiling.tile_size_m",
          IndexProblem::number_text(ix.tile_size) + " is outside [1, 4000000]");
  p.length("tiling.margin_m", ix.margin);
  p.length("tiling.dynamic_margin_m", ix.dynamic_margin);
  p.extent("extent", ix.extent);
  if (!std::isfinite(ix.resolution) || ix.resolution < 0 || ix.resolution > kMaxTilesetCoordinate)
    p.bad("resolution_m", IndexProblem::number_text(ix.resolution) + " is not in [0, 1e12] m");
  p.count("manifest.entry_count", ix.entry_count);
  p.count("manifest.bytes", ix.manifest_bytes);
  std::set<std::string> names;
  for (size_t i = 0; i < ix.manifest.layers.size() && !p.found(); ++i) {
    const std::string w = "manifest.layers[" + std::to_string(i) + "]";
    p.layer(w, ix.manifest.layers[i], false);
    if (!names.insert(ix.manifest.layers[i].layer).second)
      p.bad(w + ".layer", "'" + ix.manifest.layers[i].layer + "' is listed twice");
  }
  if (!p.found()) check_tiles(p, ix, ix.tiles, "tiles");
  for (size_t l = 0; l < ix.levels.size() && !p.found(); ++l) {
    const TileLevel& lv = ix.levels[l];
    const std::string w = "levels[" + std::to_string(l) + "]";
    for (size_t k = 0; k < lv.layers.size() && !p.found(); ++k) {
      const LayerCounts& c = lv.layers[k];
      const std::string wl = w + ".layers[" + std::to_string(k) + "]";
      for (const auto& [name, m] : kLevelCountFields) p.count(wl + "." + name, c.*m);
      if (!p.found() && c.read != c.parts + c.dropped_small)
        p.bad(wl, "parts_in is not parts + dropped_small");
    }
    for (size_t i = 0; i < lv.tiles.size() && !p.found(); ++i) {
      const TileEntry& t = lv.tiles[i];
      const std::string wt = w + ".tiles[" + std::to_string(i) + "]";
      p.tile(wt, t);
      for (size_t k = 0; k < t.layers.size(); ++k)
        p.layer(wt + ".layers[" + std::to_string(k) + "]", t.layers[k], true);
    }
  }
  return p.text();
}

TileLevel level_parameters(double tile_size, int level) {
  TileLevel l;
  l.level = level;
  l.tile_size = std::ldexp(tile_size, level);
  l.resolution = l.tile_size / kLevelTilePixels;
  l.min_area = l.resolution * l.resolution;
  l.min_length = l.resolution;
  return l;
}

std::string tile_file(int level, const TileKey& key) {
  if (level == 0) return "tiles/" + tile_name(key) + ".decals";
  return "tiles/L" + std::to_string(level) + "/" + tile_name(key) + ".decals";
}

std::string tileset_index_json(const TilesetIndex& index) {
  // The writer never writes what the reader refuses (read_tileset_index runs
  // the same check), so a build fails here, before tileset.json is renamed
  // into place.
  if (const std::string why = tileset_index_problem(index); !why.empty())
    fail<output_error>(kTilesetStage,
                       std::string(kTilesetIndexName) + " would not verify, not written: " + why);
  json j;
  j["tileset_version"] = std::to_string(index.major) + "." + std::to_string(index.minor);
  j["generator"] = index.generator;
  j["frame"] = {{"crs_wkt", index.frame.crs_wkt},
                {"description", index.frame.description},
                {"origin", {index.frame.origin_x, index.frame.origin_y}}};
  j["tiling"] = {{"scheme", "grid"},
                 {"tile_size_m", index.tile_size},
                 {"margin_m", index.margin},
                 {"dynamic_margin_m", index.dynamic_margin}};
  j["extent"] = extent_json(index.extent);
  json layers = json::array();
  for (const LayerCounts& c : index.manifest.layers) layers.push_back(layer_counts_json(c));
  j["manifest"] = {{"layers", layers},
                   {"notes", index.manifest.notes},
                   {"entry_count", index.entry_count},
                   {"file", kTilesetManifestName},
                   {"bytes", index.manifest_bytes},
                   {"xxh64", hex64(index.manifest_xxh64)}};
  j["tiles"] = tiles_json(index.tiles);
  // 1.1 (formats/SPEC.md "Overview levels"); a 1.0 index has neither key.
  if (index.minor >= kTilesetMinorLevels || !index.levels.empty()) {
    j["resolution_m"] = index.resolution;
    json levels = json::array();
    for (const TileLevel& l : index.levels) {
      json ll = json::array();
      for (const LayerCounts& c : l.layers) ll.push_back(level_counts_json(c));
      levels.push_back({{"level", l.level},
                        {"tile_size_m", l.tile_size},
                        {"resolution_m", l.resolution},
                        {"min_area_m2", l.min_area},
                        {"min_length_m", l.min_length},
                        {"layers", ll},
                        {"tiles", tiles_json(l.tiles)}});
    }
    j["levels"] = std::move(levels);
  }
  std::string text = j.dump(2) + "\n";
  if (text.size() > kMaxTilesetIndexBytes)
    fail<output_error>(kTilesetStage,
                       std::string(kTilesetIndexName) + " would be " + std::to_string(text.size()) +
                           " bytes, above the " + std::to_string(kMaxTilesetIndexBytes) +
                           "-byte limit readers hold it to (formats/SPEC.md \"tileset.json\"): " +
                           std::to_string(index.tiles.size()) +
                           " tiles; a larger --tile-size makes fewer; not written");
  return text;
}

bool parse_tileset_version(const std::string& text, int& major, int& minor) {
  // Digits only: no sign, space, exponent or trailing text ("1.0garbage"),
  // at most 9 of them so the value fits an int ("1.99999999999999999999"),
  // and no leading zero, so that one version has one spelling.
  auto number = [](std::string_view d, int& out) {
    if (d.empty() || d.size() > 9 || (d.size() > 1 && d[0] == '0')) return false;
    int v = 0;
    for (char c : d) {
      if (c < '0' || c > '9') return false;
      v = v * 10 + (c - '0');
    }
    out = v;
    return true;
  };
  const size_t dot = text.find('.');
  if (dot == std::string::npos) return false;
  const std::string_view t(text);
  return number(t.substr(0, dot), major) && number(t.substr(dot + 1), minor);
}

bool is_tileset(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return false;
  return stat((path + "/" + kTilesetIndexName).c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

TilesetIndex read_tileset_index(const std::string& dir) {
  const std::string path = dir + "/" + kTilesetIndexName;
  // The reader's open (no FIFO or device), then the size limit, both before
  // a byte is parsed: a JSON DOM takes about 25 times its text.
  int fd = -1;
  uint64_t size = 0;
  if (const decal::Status s = decal::open_regular_file(path, fd, size); !s)
    fail<error>(kNoStage, "cannot read the tileset index: " + s.message, ExitCode::input);
  if (size > kMaxTilesetIndexBytes) {
    ::close(fd);
    fail<format_error>(
        kNoStage, path + ": " + std::to_string(size) + " bytes, above the " +
                      std::to_string(kMaxTilesetIndexBytes) +
                      "-byte limit of an index (formats/SPEC.md \"tileset.json\"); not parsed");
  }
  std::string text(static_cast<size_t>(size), '\0');
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::read(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      fail<error>(kNoStage,
                  "cannot read " + path + ": " + (n == 0 ? "file shrank" : std::strerror(err)),
                  ExitCode::input);
    }
    done += static_cast<size_t>(n);
  }
  ::close(fd);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    fail<format_error>(kNoStage, path + ": not JSON: " + e.what());
  }
  text = std::string();
  const Fields f(path);
  TilesetIndex ix;
  const std::string version = f.text(j, "tileset_version", "");
  if (!parse_tileset_version(version, ix.major, ix.minor))
    f.bad("tileset_version", "'" + version +
                                 "' is not MAJOR.MINOR (two decimal integers below 10^9, no sign, "
                                 "space or leading zero)");
  if (ix.major != kTilesetMajor)
    f.bad("tileset_version", "version " + version + " is not supported (this reader: " +
                                 std::to_string(kTilesetMajor) + ".x)");
  ix.generator = f.text(j, "generator", "");
  const json& frame = f.at(j, "frame", "");
  ix.frame.crs_wkt = f.text(frame, "crs_wkt", "frame");
  ix.frame.description = f.text(frame, "description", "frame");
  const json& origin = f.at(frame, "origin", "frame");
  if (!origin.is_array() || origin.size() != 2 || !origin[0].is_number() || !origin[1].is_number())
    f.bad("frame.origin", "is not [x, y]");
  ix.frame.origin_x = origin[0].get<double>();
  ix.frame.origin_y = origin[1].get<double>();
  const json& tiling = f.at(j, "tiling", "");
  if (f.text(tiling, "scheme", "tiling") != "grid")
    f.bad("tiling.scheme", "only \"grid\" is defined");
  ix.tile_size = f.number(tiling, "tile_size_m", "tiling");
  // Checked before the tiles, whose squares it gives (again in
  // tileset_index_problem, for the writer).
  if (!(ix.tile_size >= kMinTileSize && ix.tile_size <= kMaxTileSize))
    f.bad("tiling.tile_size_m", "is outside [1, 4000000]");
  ix.margin = f.number(tiling, "margin_m", "tiling");
  ix.dynamic_margin = f.number(tiling, "dynamic_margin_m", "tiling");
  ix.extent = f.extent(j, "extent", "");
  const json& manifest = f.at(j, "manifest", "");
  const json& layers = f.at(manifest, "layers", "manifest");
  if (!layers.is_array()) f.bad("manifest.layers", "is not an array");
  for (size_t i = 0; i < layers.size(); ++i)
    ix.manifest.layers.push_back(
        f.layer_counts(layers[i], "manifest.layers[" + std::to_string(i) + "]"));
  const json& notes = f.at(manifest, "notes", "manifest");
  if (!notes.is_array()) f.bad("manifest.notes", "is not an array");
  for (const json& n : notes) {
    if (!n.is_string()) f.bad("manifest.notes", "holds a value that is not a string");
    ix.manifest.notes.push_back(n.get<std::string>());
  }
  ix.entry_count = f.count(manifest, "entry_count", "manifest");
  if (f.text(manifest, "file", "manifest") != kTilesetManifestName)
    f.bad("manifest.file", std::string("is not \"") + kTilesetManifestName + "\"");
  ix.manifest_bytes = f.count(manifest, "bytes", "manifest");
  ix.manifest_xxh64 = f.hash(manifest, "xxh64", "manifest");

  ix.tiles = read_tiles(f, f.at(j, "tiles", ""), "tiles", ix.tile_size, 0);

  // Overview levels (1.1; formats/SPEC.md "Overview levels").
  const bool has_levels = j.is_object() && j.contains("levels");
  if (ix.minor >= kTilesetMinorLevels && !has_levels) f.bad("levels", "missing");
  if (j.is_object() && (j.contains("resolution_m") || ix.minor >= kTilesetMinorLevels)) {
    ix.resolution = f.number(j, "resolution_m", "");
    if (ix.resolution < 0) f.bad("resolution_m", "is negative");
  }
  if (has_levels) {
    const json& levels = j.at("levels");
    if (!levels.is_array()) f.bad("levels", "is not an array");
    if (levels.size() > size_t(kMaxLevels))
      f.bad("levels", "has " + std::to_string(levels.size()) + " levels, more than " +
                          std::to_string(kMaxLevels));
    for (size_t i = 0; i < levels.size(); ++i) {
      const std::string w = "levels[" + std::to_string(i) + "]";
      const json& l = levels[i];
      TileLevel lv;
      const int64_t n = f.integer(l, "level", w);
      if (n != int64_t(i) + 1)
        f.bad(w + ".level", "is " + std::to_string(n) + ", not " + std::to_string(i + 1) +
                                " (levels are consecutive from 1)");
      lv.level = static_cast<int>(n);
      lv.tile_size = f.number(l, "tile_size_m", w);
      const TileLevel rule = level_parameters(ix.tile_size, lv.level);
      if (lv.tile_size != rule.tile_size)
        f.bad(w + ".tile_size_m", "is not tiling.tile_size_m * 2^" + std::to_string(lv.level));
      if (lv.tile_size > kMaxTileSize) f.bad(w + ".tile_size_m", "is above 4000000");
      lv.resolution = f.number(l, "resolution_m", w);
      lv.min_area = f.number(l, "min_area_m2", w);
      lv.min_length = f.number(l, "min_length_m", w);
      if (!(lv.resolution > 0)) f.bad(w + ".resolution_m", "is not positive");
      if (lv.min_area < 0) f.bad(w + ".min_area_m2", "is negative");
      if (lv.min_length < 0) f.bad(w + ".min_length_m", "is negative");
      const json& ll = f.at(l, "layers", w);
      if (!ll.is_array()) f.bad(w + ".layers", "is not an array");
      for (size_t k = 0; k < ll.size(); ++k)
        lv.layers.push_back(f.level_counts(ll[k], w + ".layers[" + std::to_string(k) + "]"));
      lv.tiles = read_tiles(f, f.at(l, "tiles", w), w + ".tiles", lv.tile_size, lv.level);
      ix.levels.push_back(std::move(lv));
    }
  }
  if (const std::string why = tileset_index_problem(ix); !why.empty())
    fail<format_error>(kNoStage, path + ": " + why);
  return ix;
}

std::vector<const TileEntry*> tiles_in(const TilesetIndex& index, const Extent& view) {
  return meeting(index.tiles, view);
}

std::vector<const TileEntry*> tiles_in(const TileLevel& level, const Extent& view) {
  return meeting(level.tiles, view);
}

}  // namespace prep
