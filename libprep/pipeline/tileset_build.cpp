// A tileset build (prep/tile.hpp, formats/SPEC.md "Tilesets"): the cleaned
// scene cut into tiles, each tile's package built and written atomically,
// then manifest.json, then tileset.json last, so that an index on disk
// always describes packages that are all there.
//
// Resume: every tile's package records the XXH64 of what it was built from
// (its cut scene, its metadata and the write options: "tile.input_xxh64").
// A package already at the tile's path that verifies (checksums) and records
// the same digest is kept, not rebuilt; so a build killed at any point and
// run again rebuilds only the tiles it had not finished.
#include <sys/stat.h>
#include <xxhash.h>

#include <dirent.h>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <exception>
#include <mutex>
#include <set>
#include <thread>

#include "decal/reader.hpp"
#include "pipeline_internal.hpp"
#include "prep/error.hpp"
#include "prep/manifest_json.hpp"
#include "prep/model.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"
#include "prep/tileset.hpp"
#include "prep/write.hpp"

namespace prep::pipeline_internal {

// The stage this file reports failures as (prep/stage_error.hpp).
constexpr std::string_view kTilesetStage = "tileset";

namespace {

void make_dir(const std::string& path) {
  if (mkdir(path.c_str(), 0777) == 0 || errno == EEXIST) {
    struct stat st {};
    if (stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) return;
    fail<output_error>(kTilesetStage, path + " exists and is not a directory");
  }
  fail<output_error>(kTilesetStage, "cannot create " + path + ": " + std::strerror(errno));
}

// XXH64 of what a tile's package is made from.
class Digest {
 public:
  Digest() : st_(XXH64_createState()) { XXH64_reset(st_, 0); }
  ~Digest() { XXH64_freeState(st_); }
  Digest(const Digest&) = delete;
  Digest& operator=(const Digest&) = delete;
  template <class T>
  void add(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    XXH64_update(st_, &v, sizeof v);
  }
  void add(const std::string& s) {
    add(uint64_t(s.size()));
    XXH64_update(st_, s.data(), s.size());
  }
  void add(const Ring& r) {
    add(uint64_t(r.size()));
    XXH64_update(st_, r.data(), r.size() * sizeof(Point2));
  }
  uint64_t value() const { return XXH64_digest(st_); }

 private:
  XXH64_state_t* st_;
};

uint64_t input_digest(const SceneFeatures& t, const std::string& metadata,
                      const BuildRequest& request) {
  static_assert(sizeof(Point2) == 2 * sizeof(double));
  Digest d;
  d.add(decal::kVersionMajor);
  d.add(decal::kVersionMinor);
  d.add(metadata);
  d.add(request.compress);
  d.add(request.zstd_level);
  d.add(t.frame.origin_x);
  d.add(t.frame.origin_y);
  for (const ScenePolygon& p : t.polygons) {
    d.add(p.layer), d.add(p.fid), d.add(p.part), d.add(p.area), d.add(p.order_value),
        d.add(p.color_value);
    d.add(p.shell);
    d.add(uint64_t(p.holes.size()));
    for (const Ring& h : p.holes) d.add(h);
  }
  for (const auto* lines : {&t.lines, &t.dynamic_lines}) {
    d.add(uint64_t(lines->size()));
    for (const SceneLine& l : *lines) {
      d.add(l.layer), d.add(l.fid), d.add(l.part), d.add(l.closed), d.add(l.length), d.add(l.width),
          d.add(l.order_value), d.add(l.color_value);
      d.add(l.points);
    }
  }
  return d.value();
}

// True when `path` holds a package that verifies and was built from `digest`.
bool reusable(const std::string& path, uint64_t digest) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) return false;
  decal::Package p;
  decal::OpenOptions opt;
  opt.verify_checksums = true;
  if (!decal::Package::open(path, p, opt)) return false;
  try {
    const nlohmann::json meta = nlohmann::json::parse(p.metadata_json());
    return meta.at("tile").at("input_xxh64").get<std::string>() == hex64(digest);
  } catch (const nlohmann::json::exception&) {
    return false;
  }
}

// Tile packages an earlier build left that this index no longer lists.
void remove_stale_tiles(const std::string& tiles_dir, const std::set<std::string>& keep) {
  DIR* d = opendir(tiles_dir.c_str());
  if (!d) return;
  while (const dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name.size() < 8 || name.compare(name.size() - 7, 7, ".decals") != 0) continue;
    if (name[0] != 'x' || keep.count(name)) continue;
    std::remove((tiles_dir + "/" + name).c_str());
  }
  closedir(d);
}

}  // namespace

TilesetOutcome write_tileset(const SceneSpec& spec, const SceneFeatures& scene,
                             const BuildRequest& request, const nlohmann::json& provenance) {
  const std::string dir = request.output;
  make_dir(dir);
  make_dir(dir + "/tiles");

  const TilePlan plan = tile_plan(scene, spec.model, spec.tile_size);
  std::vector<TileKey> keys;
  for (const auto& [key, members] : plan.tiles) keys.push_back(key);

  ProgressStage stage(request.progress, "tiles", keys.size(), "tiles");
  std::vector<std::optional<TileEntry>> entries(keys.size());
  std::vector<char> reused(keys.size(), 0);
  std::atomic<size_t> next{0};
  std::atomic<bool> stop{false};
  std::exception_ptr first_error;
  size_t first_error_at = keys.size();
  std::mutex error_mutex;

  auto work = [&] {
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= keys.size() || stop.load()) return;
      try {
        const TileKey key = keys[i];
        const SceneFeatures tile = tile_scene(scene, plan, key);
        if (!tile.polygons.empty() || !tile.lines.empty() || !tile.dynamic_lines.empty()) {
          const std::string file = "tiles/" + tile_name(key) + ".decals";
          const std::string path = dir + "/" + file;
          nlohmann::json extra = package_metadata(spec, tile.manifest, provenance);
          const Extent sq = plan.square(key);
          extra["tile"] = {{"x", key.x},
                           {"y", key.y},
                           {"square", {sq.xmin, sq.ymin, sq.xmax, sq.ymax}},
                           {"tile_size_m", plan.size},
                           {"margin_m", plan.margin}};
          const uint64_t digest = input_digest(tile, extra.dump(), request);
          extra["tile"]["input_xxh64"] = hex64(digest);
          if (reusable(path, digest)) {
            reused[i] = 1;
          } else {
            ModelOptions mo = spec.model;
            mo.dem_assume_crs = spec.assume_crs;
            DecalModel model = build_model(tile, mo, spec.dem);
            if (model.manifest.layers.empty()) model.manifest = tile.manifest;
            WriteOptions wo;
            wo.codec = request.compress ? Codec::zstd : Codec::none;
            wo.zstd_level = request.zstd_level;
            write_model(path, model, extra.dump(), wo);
          }
          const std::optional<FileDigest> fd = file_digest(path);
          if (!fd) fail<output_error>(kTilesetStage, "cannot read back " + path);
          TileEntry e;
          e.key = key;
          e.square = sq;
          std::tie(e.origin_x, e.origin_y) = plan.origin(key);
          e.file = file;
          e.bytes = fd->bytes;
          e.xxh64 = fd->xxh64;
          e.polygons = tile.polygons.size();
          e.lines = tile.lines.size();
          e.dynamic_lines = tile.dynamic_lines.size();
          e.layers = tile.manifest.layers;
          entries[i] = std::move(e);
        }
        stage.add(1);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        // The first failing tile in key order, whatever the scheduling.
        if (i < first_error_at) {
          first_error_at = i;
          first_error = std::current_exception();
        }
        stop.store(true);
        return;
      }
    }
  };
  const unsigned jobs = std::max(1u, request.jobs);
  std::vector<std::thread> workers;
  for (unsigned j = 1; j < jobs; ++j) workers.emplace_back(work);
  work();
  for (std::thread& w : workers) w.join();
  if (first_error) std::rethrow_exception(first_error);
  stage.finish();

  TilesetOutcome out;
  out.margin = plan.margin;
  TilesetIndex index;
  index.generator = "decalprep (package format " + std::to_string(decal::kVersionMajor) + "." +
                    std::to_string(decal::kVersionMinor) + ")";
  index.frame = scene.frame;
  index.tile_size = plan.size;
  index.margin = plan.margin;
  index.dynamic_margin = plan.dynamic_margin;
  std::set<std::string> names;
  for (size_t i = 0; i < keys.size(); ++i) {
    if (!entries[i]) {
      ++out.empty;
      continue;
    }
    ++out.tiles;
    (reused[i] ? out.reused : out.built) += 1;
    out.bytes += entries[i]->bytes;
    names.insert(tile_name(entries[i]->key) + ".decals");
    index.tiles.push_back(std::move(*entries[i]));
  }
  const Extent& e = scene.extent;  // {} when empty
  const double ox = scene.frame.origin_x, oy = scene.frame.origin_y;
  index.extent =
      e.xmax >= e.xmin ? Extent{e.xmin + ox, e.ymin + oy, e.xmax + ox, e.ymax + oy} : Extent{};
  index.manifest.layers = scene.manifest.layers;
  index.manifest.notes = scene.manifest.notes;
  index.entry_count = scene.manifest.entries.size();

  // manifest.json: the scene's entries, each feature once.
  nlohmann::json entries_json = nlohmann::json::array();
  for (const ManifestEntry& me : scene.manifest.entries)
    entries_json.push_back(manifest_entry_json(me));
  const std::string manifest_path = dir + "/" + kTilesetManifestName;
  write_text_file(manifest_path, nlohmann::json{{"entries", entries_json}}.dump(1) + "\n");
  const std::optional<FileDigest> md = file_digest(manifest_path);
  if (!md) fail<output_error>(kTilesetStage, "cannot read back " + manifest_path);
  index.manifest_bytes = md->bytes;
  index.manifest_xxh64 = md->xxh64;

  remove_stale_tiles(dir + "/tiles", names);
  write_text_file(dir + "/" + kTilesetIndexName, tileset_index_json(index));
  return out;
}

}  // namespace prep::pipeline_internal
