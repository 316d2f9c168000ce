// The tileset index, tileset.json (formats/SPEC.md "Tilesets"): written by
// the pipeline, read as untrusted input by every tool that takes a tileset.
#include <sys/stat.h>
#include <xxhash.h>

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "prep/error.hpp"
#include "prep/manifest_json.hpp"
#include "prep/tileset.hpp"

namespace prep {

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
    throw format_error(file_ + ": " + field + ": " + what);
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
    c.read = count(j, "read", where);
    c.kept = count(j, "kept", where);
    c.repaired = count(j, "repaired", where);
    c.clipped_away = count(j, "clipped_away", where);
    c.dropped = count(j, "dropped", where);
    c.parts = count(j, "parts", where);
    c.vertices_in = count(j, "vertices_in", where);
    c.vertices_out = count(j, "vertices_out", where);
    return c;
  }
  // An overview level's per-layer counts (level_counts_json).
  LayerCounts level_counts(const json& j, const std::string& where) const {
    LayerCounts c;
    c.layer = text(j, "layer", where);
    c.read = count(j, "parts_in", where);
    c.kept = c.parts = count(j, "parts", where);
    c.dropped_small = count(j, "dropped_small", where);
    c.vertices_in = count(j, "vertices_in", where);
    c.vertices_out = count(j, "vertices_out", where);
    if (c.read != c.parts + c.dropped_small) bad(where, "parts_in is not parts + dropped_small");
    return c;
  }

 private:
  std::string file_;
};

// A level's layer record: its counts are of parts (TileLevel::layers).
json level_counts_json(const LayerCounts& c) {
  return {{"layer", c.layer},
          {"parts_in", c.read},
          {"parts", c.parts},
          {"dropped_small", c.dropped_small},
          {"vertices_in", c.vertices_in},
          {"vertices_out", c.vertices_out}};
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

std::optional<FileDigest> file_digest(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  XXH64_state_t* st = XXH64_createState();
  XXH64_reset(st, 0);
  std::vector<char> buf(1 << 16);
  FileDigest d;
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    const auto n = static_cast<size_t>(in.gcount());
    XXH64_update(st, buf.data(), n);
    d.bytes += n;
  }
  d.xxh64 = XXH64_digest(st);
  XXH64_freeState(st);
  return d;
}

std::string hex64(uint64_t v) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016" PRIx64, v);
  return hex;
}

std::string tileset_index_json(const TilesetIndex& index) {
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
  return j.dump(2) + "\n";
}

bool is_tileset(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0 || !S_ISDIR(st.st_mode)) return false;
  return stat((path + "/" + kTilesetIndexName).c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

TilesetIndex read_tileset_index(const std::string& dir) {
  const std::string path = dir + "/" + kTilesetIndexName;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw error("cannot read " + path, ExitCode::input);
  std::ostringstream text;
  text << in.rdbuf();
  json j;
  try {
    j = json::parse(text.str());
  } catch (const json::exception& e) {
    throw format_error(path + ": not JSON: " + e.what());
  }
  const Fields f(path);
  TilesetIndex ix;
  const std::string version = f.text(j, "tileset_version", "");
  if (std::sscanf(version.c_str(), "%d.%d", &ix.major, &ix.minor) != 2)
    f.bad("tileset_version", "'" + version + "' is not MAJOR.MINOR");
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
  return ix;
}

std::vector<const TileEntry*> tiles_in(const TilesetIndex& index, const Extent& view) {
  return meeting(index.tiles, view);
}

std::vector<const TileEntry*> tiles_in(const TileLevel& level, const Extent& view) {
  return meeting(level.tiles, view);
}

}  // namespace prep
