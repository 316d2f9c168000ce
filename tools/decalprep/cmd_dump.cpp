// cmd_dump.cpp — `decalprep dump PACKAGE [--json|--summary] [--blob NAME]`:
// the canonical text of every blob, every blob's decoded elements as JSON
// (positions also in scene metres), so that outside tools can check a package
// without knowing its encoding, or a summary short enough to review as a
// diff (golden tests: tests/tools/golden): the metadata one value per line,
// each blob as its count, the xxh64 of its decoded bytes and its first and
// last elements, the manifest entries counted per layer and action.
//
// The text depends only on the package contents, never on how the blobs are
// stored (codec, offsets), so a compressed and an uncompressed package of the
// same model dump identically. Floats print with %.9g (round-trips float32).
#include <xxhash.h>
#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <tuple>
#include <vector>

#include "command.hpp"
#include "decal/reader.hpp"
#include "prep/manifest_words.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"

namespace {

using json = nlohmann::ordered_json;
using decal::BlobId;
using decal::ElementType;

std::string num(float v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", static_cast<double>(v));
  return b;
}

// A float as JSON; JSON has no NaN or infinity, so those become null.
json jnum(float v) {
  return std::isfinite(v) ? json(static_cast<double>(v)) : json(nullptr);
}

std::string hex32(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%08x", v);
  return b;
}

template <class T>
T load(const decal::BlobView& b, uint64_t i) {
  T v;
  std::memcpy(&v, b.bytes.data() + i * b.stride, sizeof v);
  return v;
}

// Blobs whose elements are positions in quanta: how many of the leading
// components are coordinates (dyn_vertices: x, y, z; boxes: all four).
int position_components(uint32_t id) {
  switch (static_cast<BlobId>(id)) {
    case BlobId::line_vertices:
    case BlobId::qt_leaf_vertices:
    case BlobId::lod_points: return 2;
    case BlobId::dyn_vertices: return 3;
    case BlobId::qt_node_box:
    case BlobId::line_bvh_box:
    case BlobId::poly_bvh_box: return 4;
    default: return 0;
  }
}

// --------------------------------------------------------------- records --

std::string text_line_props(const decal::LineProps& p) {
  return "half_width=" + num(p.half_width) + " rgba=" + hex32(p.rgba) +
         " order=" + std::to_string(p.order) + " style=" + hex32(p.style) +
         " value=" + num(p.value) + " layer=" + std::to_string(p.layer) +
         " feature=" + std::to_string(p.feature) + " clip_node=" + std::to_string(p.clip_node);
}
json json_line_props(const decal::LineProps& p) {
  return {{"half_width", jnum(p.half_width)},
          {"rgba", p.rgba},
          {"order", p.order},
          {"style", p.style},
          {"value", jnum(p.value)},
          {"layer", p.layer},
          {"feature", p.feature},
          {"clip_node", p.clip_node}};
}
std::string text_corner(const decal::LineCorner& c) {
  return "miter=(" + num(c.miter[0]) + "," + num(c.miter[1]) + ") bevel_in=(" + num(c.bevel_in[0]) +
         "," + num(c.bevel_in[1]) + ") bevel_out=(" + num(c.bevel_out[0]) + "," +
         num(c.bevel_out[1]) + ")";
}
json json_corner(const decal::LineCorner& c) {
  return {{"miter", {jnum(c.miter[0]), jnum(c.miter[1])}},
          {"bevel_in", {jnum(c.bevel_in[0]), jnum(c.bevel_in[1])}},
          {"bevel_out", {jnum(c.bevel_out[0]), jnum(c.bevel_out[1])}}};
}
std::string text_poly(const decal::PolyProps& p) {
  return "rgba=" + hex32(p.rgba) + " order=" + std::to_string(p.order) +
         " exterior=" + std::to_string(p.exterior) + " value=" + num(p.value) +
         " layer=" + std::to_string(p.layer) + " feature=" + std::to_string(p.feature) +
         " reserved=" + std::to_string(p.reserved[0]) + "," + std::to_string(p.reserved[1]);
}
json json_poly(const decal::PolyProps& p) {
  return {{"rgba", p.rgba},
          {"order", p.order},
          {"exterior", p.exterior},
          {"value", jnum(p.value)},
          {"layer", p.layer},
          {"feature", p.feature},
          {"reserved", {p.reserved[0], p.reserved[1]}}};
}
std::string text_lod_point(const decal::LodPoint& p) {
  return "x=" + std::to_string(p.x) + " y=" + std::to_string(p.y) +
         " eval_x=" + std::to_string(p.eval_x) + " eval_y=" + std::to_string(p.eval_y) +
         " e_star=" + num(p.e_star) + " d_star=" + num(p.d_star) +
         " line=" + std::to_string(p.line) + " flags=" + std::to_string(p.flags);
}
json json_lod_point(const decal::LodPoint& p) {
  return {{"x", p.x},
          {"y", p.y},
          {"eval_x", p.eval_x},
          {"eval_y", p.eval_y},
          {"e_star", jnum(p.e_star)},
          {"d_star", jnum(p.d_star)},
          {"line", p.line},
          {"flags", p.flags}};
}
std::string lod_index(uint32_t v) {
  return v == decal::kLodNone ? std::string("none") : std::to_string(v);
}
std::string text_lod_segment(const decal::LodSegment& s) {
  return "a=" + std::to_string(s.a) + " b=" + std::to_string(s.b) +
         " generator=" + lod_index(s.generator) + " splitter=" + lod_index(s.splitter);
}
json json_lod_segment(const decal::LodSegment& s) {
  auto idx = [](uint32_t v) { return v == decal::kLodNone ? json(nullptr) : json(v); };
  return {{"a", s.a}, {"b", s.b}, {"generator", idx(s.generator)}, {"splitter", idx(s.splitter)}};
}

// One element as text (components separated by spaces) and as JSON.
void element(const decal::BlobView& b, uint64_t i, std::string* text, json* out) {
  auto ints = [&](auto tag, int n) {
    using T = decltype(tag);
    json arr = json::array();
    for (int k = 0; k < n; ++k) {
      T v;
      std::memcpy(&v, b.bytes.data() + i * b.stride + k * sizeof(T), sizeof v);
      if (text) *text += (k ? " " : "") + std::to_string(v);
      if (out) arr.push_back(v);
    }
    if (out) *out = n == 1 ? arr[0] : arr;
  };
  auto floats = [&](int n) {
    json arr = json::array();
    for (int k = 0; k < n; ++k) {
      float v;
      std::memcpy(&v, b.bytes.data() + i * b.stride + k * 4, 4);
      if (text) *text += (k ? " " : "") + num(v);
      if (out) arr.push_back(jnum(v));
    }
    if (out) *out = n == 1 ? arr[0] : arr;
  };
  switch (b.type) {
    case ElementType::u8: return ints(uint8_t{}, 1);
    case ElementType::u32: return ints(uint32_t{}, 1);
    case ElementType::i32: return ints(int32_t{}, 1);
    case ElementType::f32: return floats(1);
    case ElementType::ivec2: return ints(int32_t{}, 2);
    case ElementType::uvec2: return ints(uint32_t{}, 2);
    case ElementType::ivec4: return ints(int32_t{}, 4);
    case ElementType::uvec4: return ints(uint32_t{}, 4);
    case ElementType::vec2: return floats(2);
    case ElementType::vec4: return floats(4);
    case ElementType::record: break;
  }
#define RECORD(T, txt, js)     \
  do {                         \
    const T r = load<T>(b, i); \
    if (text) *text += txt(r); \
    if (out) *out = js(r);     \
    return;                    \
  } while (0)
  switch (static_cast<BlobId>(b.id)) {
    case BlobId::line_props:
    case BlobId::dyn_line_props: RECORD(decal::LineProps, text_line_props, json_line_props);
    case BlobId::line_corners: RECORD(decal::LineCorner, text_corner, json_corner);
    case BlobId::poly_props: RECORD(decal::PolyProps, text_poly, json_poly);
    case BlobId::lod_points: RECORD(decal::LodPoint, text_lod_point, json_lod_point);
    case BlobId::lod_segments: RECORD(decal::LodSegment, text_lod_segment, json_lod_segment);
    default: break;
  }
#undef RECORD
  // A record this build does not know: its bytes in hex.
  std::string hex;
  for (uint32_t k = 0; k < b.stride; ++k) {
    char h[3];
    std::snprintf(h, sizeof h, "%02x", static_cast<unsigned>(b.bytes[i * b.stride + k]));
    hex += h;
  }
  if (text) *text += hex;
  if (out) *out = hex;
}

// The leading coordinates of a position element, in scene metres.
json scene_metres(const decal::BlobView& b, uint64_t i, int n) {
  json arr = json::array();
  for (int k = 0; k < n; ++k) {
    int32_t q;
    std::memcpy(&q, b.bytes.data() + i * b.stride + k * 4, 4);
    arr.push_back(static_cast<double>(q) * decal::kQuantumMetres);
  }
  return arr;
}

std::string as_text(const decal::BlobView& b) {
  return {reinterpret_cast<const char*>(b.bytes.data()), static_cast<size_t>(b.count)};
}

std::string type_name(const decal::BlobView& b) {
  return std::string(decal::element_type_name(b.type));
}

// ------------------------------------------------------------- summary --

// Elements shown at each end of a blob in the summary.
constexpr uint64_t kSummaryEnds = 3;

// XXH64 (seed 0) of a blob's decoded bytes as 16 hex digits, the way
// `decalprep info` prints the checksum of a blob stored uncompressed.
std::string xxh64_hex(const decal::BlobView& b) {
  char h[17];
  std::snprintf(h, sizeof h, "%016" PRIx64,
                static_cast<uint64_t>(XXH64(b.bytes.data(), b.bytes.size(), 0)));
  return h;
}

// One line per leaf: `  path value`, objects and arrays that hold more than
// numbers unfolded (`a.b`, `a[2].c`), other values as compact JSON.
void flatten(const json& v, const std::string& path, std::string& out) {
  const auto structured = [](const json& x) { return x.is_structured() || x.is_string(); };
  if (v.is_object() && !v.empty()) {
    for (const auto& [k, x] : v.items()) flatten(x, path.empty() ? k : path + "." + k, out);
    return;
  }
  if (v.is_array() && std::any_of(v.begin(), v.end(), structured)) {
    for (size_t i = 0; i < v.size(); ++i) flatten(v[i], path + "[" + std::to_string(i) + "]", out);
    return;
  }
  out += "  " + path + " " + v.dump(-1, ' ', false, json::error_handler_t::replace) + "\n";
}

// Calls show(i) for the elements a summary lists: all of a short blob, else
// the first and last kSummaryEnds with a `... N more` line between.
template <class F>
void ends(uint64_t count, F&& show) {
  for (uint64_t i = 0; i < count; ++i) {
    if (count > 2 * kSummaryEnds && i == kSummaryEnds) {
      std::printf("  ... %" PRIu64 " more\n", count - 2 * kSummaryEnds);
      i = count - kSummaryEnds;
    }
    show(i);
  }
}

// The manifest entries counted per layer (in order of first appearance) and
// action word, dropped entries split by the failure stage their reason names
// (formats/SPEC.md "Manifest entries"); then the first and last entries.
void summarise_manifest(const std::string& path, const decal::BlobView& b) {
  json entries;
  try {
    entries = json::parse(as_text(b));
  } catch (const json::exception& e) {
    prep::fail<prep::format_error>(prep::kDumpStage,
                                   path + ": manifest_entries is not valid JSON: " + e.what());
  }
  if (!entries.is_array())
    prep::fail<prep::format_error>(prep::kDumpStage,
                                   path + ": manifest_entries is not a JSON array");
  // (action rank, stage rank, label) -> count, per layer.
  using Key = std::tuple<int, int, std::string>;
  std::vector<std::pair<std::string, std::vector<std::pair<Key, uint64_t>>>> layers;
  for (size_t i = 0; i < entries.size(); ++i) {
    const json& e = entries[i];
    const auto text = [&](const char* k) {
      const auto it = e.is_object() ? e.find(k) : e.end();
      if (it == e.end() || !it->is_string())
        prep::fail<prep::format_error>(
            prep::kDumpStage,
            path + ": manifest entry " + std::to_string(i) + " has no string '" + k + "'");
      return it->get<std::string>();
    };
    const std::string layer = text("layer"), action = text("action");
    const auto a = prep::manifest_action_from_word(action);
    Key key{a ? static_cast<int>(*a) : 99, -1, action};  // a word outside the vocabulary: last
    if (a == prep::ManifestAction::dropped) {
      if (const auto stage = prep::parse_reason_text(text("reason")).failed_in) {
        std::get<1>(key) = static_cast<int>(*stage);
        std::get<2>(key) = action + " (" + prep::failure_label(*stage) + ")";
      }
    }
    auto l =
        std::find_if(layers.begin(), layers.end(), [&](const auto& x) { return x.first == layer; });
    if (l == layers.end()) l = layers.insert(layers.end(), {layer, {}});
    auto c = std::find_if(l->second.begin(), l->second.end(),
                          [&](const auto& x) { return x.first == key; });
    if (c == l->second.end()) c = l->second.insert(l->second.end(), {key, 0});
    ++c->second;
  }
  std::printf("  entries %zu\n", entries.size());
  for (auto& [layer, counts] : layers) {
    std::sort(counts.begin(), counts.end());
    std::string line =
        "  layer " + json(layer).dump(-1, ' ', false, json::error_handler_t::replace) + ":";
    for (size_t k = 0; k < counts.size(); ++k)
      line +=
          (k ? ", " : " ") + std::get<2>(counts[k].first) + " " + std::to_string(counts[k].second);
    std::printf("%s\n", line.c_str());
  }
  ends(entries.size(), [&](uint64_t i) {
    std::printf("  [%" PRIu64 "] %s\n", i,
                entries[i].dump(-1, ' ', false, json::error_handler_t::replace).c_str());
  });
}

void run_summary(const decal::Package& p, const std::string& path, const std::string& only) {
  std::printf("decals %u.%u\n", p.major(), p.minor());
  if (only.empty()) {
    const json meta = decalprep::parse_metadata(p.metadata_json(), path, prep::kDumpStage);
    std::string text;
    flatten(meta, "", text);
    std::printf("metadata\n%s", text.c_str());
  }
  std::string line;
  for (const auto& b : p.blobs()) {
    if (!only.empty() && b.name != only) continue;
    std::printf("blob %s id=%u type=%s stride=%u count=%" PRIu64 " xxh64=%s\n", b.name.c_str(),
                b.id, type_name(b).c_str(), b.stride, b.count, xxh64_hex(b).c_str());
    if (b.id == static_cast<uint32_t>(BlobId::manifest_entries)) {
      summarise_manifest(path, b);
      continue;
    }
    ends(b.count, [&](uint64_t i) {
      line = "  [" + std::to_string(i) + "] ";
      element(b, i, &line, nullptr);
      line += '\n';
      std::fwrite(line.data(), 1, line.size(), stdout);
    });
  }
}

// The package to dump: PACKAGE itself, or a tileset's tile --tile X,Y.
std::string tile_package(const std::string& path, const std::string& tile, int level) {
  if (!prep::is_tileset(path)) {
    if (!tile.empty())
      prep::fail<prep::usage_error>(prep::kDumpStage, "--tile needs a tileset directory");
    if (level != 0)
      prep::fail<prep::usage_error>(prep::kDumpStage, "--level needs a tileset directory");
    return path;
  }
  long long x = 0, y = 0;
  char end = 0;
  if (tile.empty() || std::sscanf(tile.c_str(), "%lld,%lld%c", &x, &y, &end) != 2)
    prep::fail<prep::usage_error>(prep::kDumpStage,
                                  path + " is a tileset: name one tile with --tile X,Y" +
                                      (tile.empty() ? "" : " ('" + tile + "' is not X,Y)"));
  const prep::TilesetIndex ix = prep::read_tileset_index(path);
  if (level < 0 || size_t(level) > ix.levels.size())
    prep::fail<prep::usage_error>(
        prep::kDumpStage, "--level " + std::to_string(level) + ": " + path + " has levels 0" +
                              (ix.levels.empty() ? "" : " to " + std::to_string(ix.levels.size())));
  const std::vector<prep::TileEntry>& tiles =
      level == 0 ? ix.tiles : ix.levels[size_t(level - 1)].tiles;
  for (const prep::TileEntry& t : tiles)
    if (t.key.x == x && t.key.y == y) return path + "/" + t.file;
  prep::fail<prep::usage_error>(
      prep::kDumpStage, path + " has no tile " + tile +
                            (level ? " on level " + std::to_string(level) : std::string()) + " (" +
                            std::to_string(tiles.size()) + " tiles; `decalprep info " + path +
                            "` lists them)");
}

// A tileset's tile must be the tile its index entry names: its metadata's
// `tile` key and level (formats/SPEC.md "tileset.json"), so that a tile
// swapped on disk (its size and hash swapped in the index too) is refused,
// not dumped as the other one.
void check_tile_key(const decal::Package& p, const std::string& path, long long x, long long y,
                    int level) {
  const json meta = decalprep::parse_metadata(p.metadata_json(), path, prep::kDumpStage);
  const json* tile = meta.is_object() && meta.contains("tile") ? &meta["tile"] : nullptr;
  const json want = {{"x", x}, {"y", y}, {"level", level}};
  json got = {{"x", nullptr}, {"y", nullptr}, {"level", 0}};
  if (tile && tile->is_object())
    for (auto& [k, v] : got.items())
      if (tile->contains(k)) v = (*tile)[k];
  if (got != want)
    prep::fail<prep::format_error>(prep::kDumpStage,
                                   path + ": package metadata tile " + got.dump() +
                                       " is not the index's tile " + want.dump() +
                                       " (`decalprep verify` checks the whole tileset)");
}

// `tile`: the key and level of a tileset's tile, checked against the
// package's own metadata; null for a package.
struct TileRequest {
  long long x = 0, y = 0;
  int level = 0;
};

void run_dump(const std::string& path, bool as_json, bool summary, const std::string& only,
              const TileRequest* tile = nullptr) {
  decal::Package p;
  if (decal::Status s = decal::Package::open(path, p); !s)
    prep::fail<prep::format_error>(prep::kDumpStage, s.message);
  if (tile) check_tile_key(p, path, tile->x, tile->y, tile->level);
  bool found = only.empty();
  std::string names;
  for (const auto& b : p.blobs()) {
    found = found || b.name == only;
    names += (names.empty() ? "" : ", ") + std::string(b.name);
  }
  if (!found)
    prep::fail<prep::usage_error>(
        prep::kDumpStage, path + " has no blob named '" + only + "' (its blobs: " + names + ")");

  if (summary) return run_summary(p, path, only);
  if (as_json) {
    json out = {{"version", {{"major", p.major()}, {"minor", p.minor()}}}};
    const json meta = decalprep::parse_metadata(p.metadata_json(), path, prep::kDumpStage);
    out["metadata"] = meta;
    out["quantum_m"] = decal::kQuantumMetres;
    json blobs = json::array();
    for (const auto& b : p.blobs()) {
      if (!only.empty() && b.name != only) continue;
      if (b.id == static_cast<uint32_t>(BlobId::manifest_entries)) {
        // A JSON document stored as bytes: decode it instead of listing bytes.
        json entries;
        try {
          entries = json::parse(as_text(b));
        } catch (const json::exception& e) {
          prep::fail<prep::format_error>(
              prep::kDumpStage, path + ": manifest_entries is not valid JSON: " + e.what());
        }
        blobs.push_back({{"id", b.id},
                         {"name", b.name},
                         {"type", type_name(b)},
                         {"stride", b.stride},
                         {"count", b.count},
                         {"elements", std::move(entries)}});
        continue;
      }
      json elements = json::array();
      const int pos = position_components(b.id);
      json scene = json::array();
      for (uint64_t i = 0; i < b.count; ++i) {
        json e;
        element(b, i, nullptr, &e);
        elements.push_back(std::move(e));
        if (pos) scene.push_back(scene_metres(b, i, pos));
      }
      json jb = {{"id", b.id},         {"name", b.name},   {"type", type_name(b)},
                 {"stride", b.stride}, {"count", b.count}, {"elements", std::move(elements)}};
      if (pos) jb["scene_m"] = std::move(scene);
      blobs.push_back(std::move(jb));
    }
    out["blobs"] = std::move(blobs);
    std::cout << out.dump() << "\n";
    return;
  }

  std::string line;
  std::printf("decals %u.%u\n", p.major(), p.minor());
  if (only.empty())
    std::printf("metadata %.*s\n", int(p.metadata_json().size()), p.metadata_json().data());
  for (const auto& b : p.blobs()) {
    if (!only.empty() && b.name != only) continue;
    std::printf("blob %s id=%u type=%s stride=%u count=%" PRIu64 "\n", b.name.c_str(), b.id,
                type_name(b).c_str(), b.stride, b.count);
    if (b.id == static_cast<uint32_t>(BlobId::manifest_entries)) {
      const std::string text = as_text(b);  // one JSON line, canonical (sorted keys)
      std::printf("  %s\n", text.c_str());
      continue;
    }
    for (uint64_t i = 0; i < b.count; ++i) {
      line = "  [" + std::to_string(i) + "] ";
      element(b, i, &line, nullptr);
      line += '\n';
      std::fwrite(line.data(), 1, line.size(), stdout);
    }
  }
}

constexpr decalprep::CommandHelp kDumpHelp{
    "dump", "Print every blob of a package as canonical text or JSON",
    "Text: one line per element, records as name=value pairs; identical for\n"
    "compressed and uncompressed packages of the same model (golden tests).\n"
    "JSON: {version, metadata, quantum_m, blobs:[{id,name,type,stride,count,elements,\n"
    "scene_m}]}; scene_m (position blobs only) holds coordinates in scene metres.\n"
    "Summary: text short enough to review as a diff: the metadata one value per\n"
    "line (`path value`); per blob its count, xxh64 (seed 0, hex) of its decoded\n"
    "bytes (what `info` lists for a blob stored uncompressed) and its first and\n"
    "last 3 elements; for manifest_entries (hashed as the JSON text stored) the\n"
    "entries counted per layer and action, then the first and last 3 entries.\n"
    "Examples:\n  decalprep dump city.decals > city.txt\n"
    "  decalprep dump city.decals --summary > city.summary.txt\n"
    "  decalprep dump city.decals --json --blob line_vertices"};

const decalprep::CommandRegistrar kDump(22, kDumpHelp, [](CLI::App* cmd) {
  auto path = std::make_shared<std::string>();
  auto as_json = std::make_shared<bool>(false);
  auto summary = std::make_shared<bool>(false);
  auto only = std::make_shared<std::string>();
  auto tile = std::make_shared<std::string>();
  auto level = std::make_shared<int>(0);
  cmd->add_option("PACKAGE", *path, "the .decals file, or a tileset directory (with --tile)")
      ->required();
  cmd->add_option("--tile", *tile,
                  // not a stage prefix: help text
                  "tileset: the tile to dump, X,Y (its key; `decalprep info DIR` lists them)");
  cmd->add_option("--level", *level,
                  // not a stage prefix: help text
                  "tileset: the overview level of --tile (default 0, full detail)");
  auto* json_flag = cmd->add_flag("--json", *as_json, "print the decoded elements as JSON");
  cmd->add_flag(
         "--summary", *summary,
         "print a short text to review as a diff (golden tests): hashes and counts, see below")
      ->excludes(json_flag);
  cmd->add_option("--blob", *only, "only the blob with this name (e.g. line_vertices)");
  cmd->callback([path, as_json, summary, only, tile, level] {
    const std::string package = tile_package(*path, *tile, *level);
    TileRequest key;
    key.level = *level;
    char end = 0;
    const bool is_tile =
        package != *path && std::sscanf(tile->c_str(), "%lld,%lld%c", &key.x, &key.y, &end) == 2;
    run_dump(package, *as_json, *summary, *only, is_tile ? &key : nullptr);
    decalprep::set_exit_code(prep::ExitCode::ok);
  });
});

}  // namespace
