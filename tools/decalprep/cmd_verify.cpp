// cmd_verify.cpp — `decalprep verify PACKAGE...`: every checksum and every
// structural check a package can be given (formats/SPEC.md §"Validation").
// Prints one line per package (or, with --json, one JSON object); exits 0
// when all are good, 5 (verify_failed) when any is corrupt, else 3 (input)
// when a path could not be read at all.
#include <unistd.h>

#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "command.hpp"
#include "decal/inspect.hpp"
#include "decal/reader.hpp"
#include "prep/evaluate.hpp"
#include "prep/files.hpp"
#include "prep/manifest_json.hpp"
#include "prep/tile.hpp"

namespace {

// What verify found, one entry per path checked: printed as it is found
// ("<path>: ok (...)" on stdout, "<path>: FAILED: <reason>" on stderr) or,
// with --json, kept and printed as one object at the end.
struct Findings {
  bool as_json = false;
  nlohmann::json entries = nlohmann::json::array();
  bool corrupt = false, unreadable = false;

  void ok(const std::string& path, const std::string& summary) {
    if (as_json)
      entries.push_back({{"path", path}, {"ok", true}, {"summary", summary}});
    else
      std::printf("%s: ok (%s)\n", path.c_str(), summary.c_str());
  }
  // `cannot_read`: the path could not be read at all (missing, not
  // readable), not a package found corrupt.
  void failed(const std::string& path, const std::string& reason, bool cannot_read = false) {
    (cannot_read ? unreadable : corrupt) = true;
    if (as_json)
      entries.push_back(
          {{"path", path}, {"ok", false}, {"reason", reason}, {"unreadable", cannot_read}});
    else
      std::fprintf(stderr, "%s: FAILED: %s\n", path.c_str(), reason.c_str());
  }
  prep::ExitCode exit_code() const {
    return corrupt      ? prep::ExitCode::verify_failed
           : unreadable ? prep::ExitCode::input
                        : prep::ExitCode::ok;
  }
};

// The metadata must be a JSON object; where it states a format or blob
// counts (SPEC.md §"Metadata"), they must agree with the package.
decal::Status check_metadata(const decal::Package& p) {
  nlohmann::json meta;
  try {
    meta = nlohmann::json::parse(p.metadata_json());
  } catch (const nlohmann::json::exception& e) {
    return decal::Status::failure(std::string("metadata is not valid JSON: ") + e.what());
  }
  if (!meta.is_object()) return decal::Status::failure("metadata is not a JSON object");
  if (auto f = meta.find("format"); f != meta.end() && *f != "decals")
    return decal::Status::failure("metadata format is " + f->dump() + ", expected \"decals\"");
  if (auto counts = meta.find("counts"); counts != meta.end() && counts->is_object())
    for (const decal::BlobView& b : p.blobs()) {
      auto c = counts->find(b.name);
      if (c == counts->end()) continue;
      if (!c->is_number_unsigned() || c->get<uint64_t>() != b.count)
        return decal::Status::failure("metadata counts." + b.name + " = " + c->dump() +
                                      " but the blob has " + std::to_string(b.count) + " elements");
    }
  return decal::Status::success();
}

// `meta`, when given, receives the package's metadata (checked to be a
// JSON object).
decal::Status verify_one(const std::string& path, std::string& summary,
                         nlohmann::json* meta = nullptr, decal::Package* opened = nullptr) {
  decal::Package p;
  decal::OpenOptions opt;
  opt.verify_checksums = true;
  if (decal::Status s = decal::Package::open(path, p, opt); !s) return s;
  if (decal::Status s = decal::validate_indices(p); !s)
    return decal::Status::failure(path + ": " + s.message);
  if (decal::Status s = check_metadata(p); !s)
    return decal::Status::failure(path + ": " + s.message);
  const nlohmann::json parsed = nlohmann::json::parse(p.metadata_json());  // checked above
  // Where the metadata states the grid, the blobs against it too, as the
  // evaluator and the GL loader check them (its int32 range, one per-cell
  // element per cell).
  if (parsed.contains("grid")) {
    prep::GridParams g;
    try {
      g = prep::grid_of_metadata(p.metadata_json());
    } catch (const std::exception& e) {
      return decal::Status::failure(path + ": " + e.what());
    }
    const decal::Grid grid{g.origin_x, g.origin_y, g.cell_w, g.cell_h, g.nx, g.ny};
    if (decal::Status s = decal::validate_indices(p, &grid); !s)
      return decal::Status::failure(path + ": " + s.message);
  }
  if (meta) *meta = parsed;
  uint64_t raw = 0;
  for (const auto& b : p.blobs()) raw += b.bytes.size();
  summary = "v" + std::to_string(p.major()) + "." + std::to_string(p.minor()) + ", " +
            std::to_string(p.blobs().size()) + " blobs, " + std::to_string(raw) + " raw bytes";
  if (opened) *opened = std::move(p);
  return decal::Status::success();
}

// What a tile's package says of itself against what the index says of the
// tile (formats/SPEC.md "tileset.json"): the key, square, tile size,
// margin and level in its metadata's `tile`, its origin, its frame CRS,
// its parts (the poly_props, line_props and dyn_line_props counts) and its
// per-layer counts. Empty when they agree, else the first difference,
// naming the metadata field and the index field. Catches tiles swapped
// with their bytes and hashes in the index, which the hashes cannot.
std::string tile_mismatch(const prep::TilesetIndex& ix, const prep::TileEntry& t,
                          const std::string& where, int level, double tile_size,
                          const decal::Package& p, const nlohmann::json& meta) {
  using nlohmann::json;
  auto differs = [&](const std::string& field, const json* got, const json& want,
                     const std::string& index_field) -> std::string {
    if (got && *got == want) return "";
    return "package metadata " + field + " = " + (got ? got->dump() : std::string("(missing)")) +
           ", tileset.json " + index_field + " = " + want.dump();
  };
  auto at = [](const json& j, const char* key) -> const json* {
    if (!j.is_object()) return nullptr;
    auto it = j.find(key);
    return it == j.end() ? nullptr : &*it;
  };
  const json* tile = at(meta, "tile");
  if (!tile || !tile->is_object()) return "package metadata has no \"tile\" object";
  std::string why = differs("tile.x", at(*tile, "x"), t.key.x, where + ".x");
  if (why.empty()) why = differs("tile.y", at(*tile, "y"), t.key.y, where + ".y");
  if (why.empty() && level > 0) why = differs("tile.level", at(*tile, "level"), level, "level");
  if (why.empty() && level == 0 && at(*tile, "level") && *at(*tile, "level") != 0)
    why = "package metadata tile.level = " + at(*tile, "level")->dump() + ", a level-0 tile";
  if (why.empty())
    why = differs("tile.square", at(*tile, "square"),
                  json::array({t.square.xmin, t.square.ymin, t.square.xmax, t.square.ymax}),
                  where + ".square");
  if (why.empty())
    why = differs("tile.tile_size_m", at(*tile, "tile_size_m"), tile_size,
                  level ? "levels[" + std::to_string(level - 1) + "].tile_size_m"
                        : std::string("tiling.tile_size_m"));
  if (why.empty())
    why = differs("tile.margin_m", at(*tile, "margin_m"), ix.margin, "tiling.margin_m");
  if (why.empty())
    why = differs("origin", at(meta, "origin"), json{{"x", t.origin_x}, {"y", t.origin_y}},
                  where + ".origin");
  if (why.empty() && !(at(meta, "crs_wkt") && *at(meta, "crs_wkt") == ix.frame.crs_wkt))
    why = "package metadata crs_wkt is not tileset.json frame.crs_wkt";
  // Polygon parts are the exterior rings of poly_props (a hole is a
  // poly_props element too); line parts and dynamic-line parts one element
  // each.
  uint64_t exteriors = 0;
  for (const decal::PolyProps& pp : p.array<decal::BlobId::poly_props>())
    exteriors += pp.exterior < 0 ? 1 : 0;
  auto count_of = [&](decal::BlobId id) {
    const decal::BlobView* b = p.find(id);
    return b ? b->count : 0;
  };
  struct Parts {
    uint64_t got;
    const char* what;
    uint64_t want;
    const char* field;
  };
  for (const Parts& k : {Parts{exteriors, "exterior poly_props", t.polygons, "polygons"},
                         Parts{count_of(decal::BlobId::line_props), "line_props", t.lines, "lines"},
                         Parts{count_of(decal::BlobId::dyn_line_props), "dyn_line_props",
                               t.dynamic_lines, "dynamic_lines"}}) {
    if (!why.empty()) break;
    if (k.got != k.want)
      why = "the package holds " + std::to_string(k.got) + " " + k.what + ", tileset.json " +
            where + ".counts." + k.field + " = " + std::to_string(k.want);
  }
  if (!why.empty()) return why;
  const json* manifest = at(meta, "manifest");
  const json* layers = manifest ? at(*manifest, "layers") : nullptr;
  json want = json::array();
  for (const prep::LayerCounts& c : t.layers) want.push_back(prep::layer_counts_json(c));
  return differs("manifest.layers", layers, want, where + ".layers");
}

// A tileset: the index (read_tileset_index checks its fields, ranges and
// its manifest against its tiles' counts), manifest.json's and every
// tile's bytes and XXH64 against the index, every tile as a package, and
// what each tile's package says of itself against its index entry.
// Each failure goes to `found`.
void verify_tileset(const std::string& dir, Findings& found) {
  prep::TilesetIndex ix;
  try {
    ix = prep::read_tileset_index(dir);
  } catch (const prep::error& e) {
    found.failed(dir, e.what());
    return;
  }
  bool good = true;
  auto check_file = [&](const std::string& rel, uint64_t bytes, uint64_t hash) {
    const std::string path = dir + "/" + rel;
    std::string why;
    const std::optional<prep::FileDigest> d = prep::file_digest(path, &why);
    if (!d)
      why = why.empty() ? "missing" : why;
    else if (d->bytes != bytes)
      why = std::to_string(d->bytes) + " bytes, tileset.json says " + std::to_string(bytes);
    else if (d->xxh64 != hash)
      why = "xxh64 " + prep::hex64(d->xxh64) + ", tileset.json says " + prep::hex64(hash);
    if (why.empty()) return true;
    found.failed(path, why);
    good = false;
    return false;
  };
  check_file(prep::kTilesetManifestName, ix.manifest_bytes, ix.manifest_xxh64);
  auto check_tiles = [&](const std::vector<prep::TileEntry>& tiles, int level, double size) {
    const std::string where =
        level ? "levels[" + std::to_string(level - 1) + "].tiles" : std::string("tiles");
    for (size_t i = 0; i < tiles.size(); ++i) {
      const prep::TileEntry& t = tiles[i];
      if (!check_file(t.file, t.bytes, t.xxh64)) continue;
      std::string summary;
      nlohmann::json meta;
      decal::Package p;
      const std::string path = dir + "/" + t.file;
      if (const decal::Status s = verify_one(path, summary, &meta, &p); !s) {
        found.failed(path, s.message);
        good = false;
        continue;
      }
      const std::string w = where + "[" + std::to_string(i) + "]";
      if (const std::string why = tile_mismatch(ix, t, w, level, size, p, meta); !why.empty()) {
        found.failed(path, why);
        good = false;
      }
    }
  };
  check_tiles(ix.tiles, 0, ix.tile_size);
  // Overview levels: every level's tiles the same way.
  size_t level_tiles = 0;
  for (const prep::TileLevel& l : ix.levels) {
    check_tiles(l.tiles, l.level, l.tile_size);
    level_tiles += l.tiles.size();
  }
  if (!good) return;
  std::string summary = "tileset " + std::to_string(ix.major) + "." + std::to_string(ix.minor) +
                        ", " + std::to_string(ix.tiles.size()) + " tiles";
  if (!ix.levels.empty())
    summary += " and " + std::to_string(level_tiles) + " on " + std::to_string(ix.levels.size()) +
               " overview levels";
  found.ok(dir, summary + ", index and manifest hashes match");
}

constexpr decalprep::CommandHelp kVerifyHelp{
    "verify", "Check packages: checksums, structure and indices",
    "Prints '<path>: ok (...)' or '<path>: FAILED: <reason>' per package; with --json one\n"
    "object on stdout: {\"ok\", \"packages\": [{\"path\", \"ok\", \"summary\" or \"reason\",\n"
    "\"unreadable\"}]}.\n"
    "Exit code 0 when every package is good, 5 when any is corrupt, else 3 when a path\n"
    "could not be read (missing, not readable).\n"
    "A tileset directory: tileset.json (fields, ranges, its manifest's counts against its\n"
    "tiles'), the bytes and XXH64 of manifest.json and of every tile against it, then every\n"
    "tile as a package, its key, square, origin, CRS and counts against the index; the same\n"
    "for every overview level's tiles.\n"
    "Example:\n  decalprep verify city.decals roads.decals"};

const decalprep::CommandRegistrar kVerify(21, kVerifyHelp, [](CLI::App* cmd) {
  auto paths = std::make_shared<std::vector<std::string>>();
  auto as_json = std::make_shared<bool>(false);
  cmd->add_option("PACKAGE", *paths, "the .decals files, or tileset directories")->required();
  cmd->add_flag("--json", *as_json, "print one JSON object (what each path gave) on stdout");
  cmd->callback([paths, as_json] {
    Findings found;
    found.as_json = *as_json;
    for (const std::string& path : *paths) {
      if (prep::is_tileset(path)) {
        verify_tileset(path, found);
        continue;
      }
      std::string summary;
      const decal::Status s = verify_one(path, summary);
      if (s) {
        found.ok(path, summary);
      } else {
        // Reader messages usually start with the path already.
        const std::string& m = s.message;
        const bool has_path = m.compare(0, path.size() + 2, path + ": ") == 0;
        found.failed(path, has_path ? m.substr(path.size() + 2) : m,
                     ::access(path.c_str(), R_OK) != 0);
      }
    }
    if (found.as_json)
      std::printf("%s\n", nlohmann::json{{"ok", !found.corrupt && !found.unreadable},
                                         {"packages", found.entries}}
                              .dump(2)
                              .c_str());
    std::fflush(stdout);
    decalprep::set_exit_code(found.exit_code());
  });
});

}  // namespace
