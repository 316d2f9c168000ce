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
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include "decal/reader.hpp"
#include "prep/clean.hpp"
#include "prep/error.hpp"
#include "prep/feature_failure.hpp"
#include "prep/files.hpp"
#include "prep/manifest_json.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/model.hpp"
#include "prep/progress.hpp"
#include "prep/project.hpp"
#include "prep/read.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"
#include "prep/write.hpp"
#include "source_spill.hpp"
#include "tileset_dir.hpp"
#include "tileset_internal.hpp"
#include "tileset_work.hpp"

namespace prep::tiling {

namespace {

// The margin the min_width_px lines of a level need (formats/SPEC.md
// "Minimum widths"): their drawn half width at the pixel limit of a tile of
// that level (resolution, side, whole: min_width_pixel_limit), as far as a
// miter reaches; 0 without such layers.
double min_width_margin(const BuildSpec& spec, double resolution, double side, double whole) {
  double f = 0;
  for (const LayerSpec& l : spec.layers)
    if (l.min_width_px > 0 && !l.dynamic)
      f = std::max(f, l.min_width_px * (l.style.outline == decal::OutlineMode::normal ? 0.5 : 1.0));
  return f > 0 ? stroke_margin_of(f * min_width_pixel_limit(resolution, side, whole), spec.model)
               : 0.0;
}

// The longer side of a tileset's extent (0 when empty).
double whole_side(const Extent& e) {
  return e.xmax > e.xmin ? std::max(e.xmax - e.xmin, e.ymax - e.ymin) : 0.0;
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
      if (l.dash_start != 0) d.add(l.dash_start);
    }
  }
  return d.value();
}

// What a tile's package holds, as tileset.json counts it (formats/SPEC.md
// "Tilesets": a polygon part is an exterior ring; the build stage may drop
// a part that collapses at 1 mm, so the package, not the cut scene, says).
struct HeldParts {
  uint64_t polygons = 0, lines = 0, dynamic_lines = 0;
};
HeldParts held_parts(const std::vector<decal::PolyProps>& polys, size_t lines,
                     size_t dynamic_lines) {
  HeldParts h{0, lines, dynamic_lines};
  for (const decal::PolyProps& pp : polys) h.polygons += pp.exterior < 0 ? 1 : 0;
  return h;
}

// What `path` holds when it is a package that verifies and was built from
// `digest`; nullopt otherwise.
std::optional<HeldParts> reusable(const std::string& path, uint64_t digest) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) return std::nullopt;
  decal::Package p;
  decal::OpenOptions opt;
  opt.verify_checksums = true;
  if (!decal::Package::open(path, p, opt)) return std::nullopt;
  try {
    const nlohmann::json meta = nlohmann::json::parse(p.metadata_json());
    if (meta.at("tile").at("input_xxh64").get<std::string>() != hex64(digest)) return std::nullopt;
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
  auto count_of = [&](decal::BlobId id) -> size_t {
    const decal::BlobView* b = p.find(id);
    return b ? b->count : 0;
  };
  const auto polys = p.array<decal::BlobId::poly_props>();
  return held_parts({polys.begin(), polys.end()}, count_of(decal::BlobId::line_props),
                    count_of(decal::BlobId::dyn_line_props));
}

// How many overview levels a build makes: SceneSpec::levels, or for
// kLevelsAuto the first level whose grid covers the data's box (scene
// coordinates) with at most kAutoLevelTiles tiles
// (none when level 0 does), at most kMaxLevels and no tile above
// kMaxTileSize.
int level_count(const BuildSpec& spec, const Extent& data, const SceneFrame& frame) {
  if (spec.levels != kLevelsAuto) return spec.levels;
  for (int l = 0; l <= kMaxLevels; ++l) {
    const double size = std::ldexp(spec.tile_size, l);
    if (size > kMaxTileSize) return l - 1;
    const TileRange r = tile_range(data, 0, frame.origin_x, frame.origin_y, size);
    const double tiles = double(r.hi.x - r.lo.x + 1) * double(r.hi.y - r.lo.y + 1);
    if (tiles <= kAutoLevelTiles) return l;
  }
  return kMaxLevels;
}

}  // namespace

// ------------------------------------------------------------- prepare --

TilesetPreparer::TilesetPreparer(const BuildSpec& spec, const std::string& dir)
    : spec_(spec), paths_{dir} {
  check_tile_size(spec.tile_size);
  // The folder itself is held by the caller (TilesetDir).
  make_inner_dir(dir + "/tiles");
  renew_work_folder(paths_);
  parts_ = std::make_unique<PartWriter>(paths_);
  entries_ = std::make_unique<EntryWriter>(paths_.entries());
  read_entries_ = std::make_unique<EntryWriter>(paths_.read_entries());
}

TilesetPreparer::~TilesetPreparer() = default;

void TilesetPreparer::add_parts(const SceneFeatures& chunk) {
  parts_->add(chunk);
}
void TilesetPreparer::add_entry(const ManifestEntry& e) {
  entries_->add(e);
}
void TilesetPreparer::add_read_entry(const ManifestEntry& e) {
  read_entries_->add(e);
}

double TilesetPreparer::margin() const {
  return stroke_margin_of(parts_->half_width(), spec_.model);
}

void TilesetPreparer::finish(const SceneFrame& frame, const Manifest& counts_and_notes,
                             const nlohmann::json& provenance) {
  parts_->close();
  entries_->close();
  read_entries_->close();
  const Extent e = parts_->extent();
  // Overview levels (formats/SPEC.md "Overview levels"): each level's tiles
  // from the same boxes, on its own grid.
  const int nlevels =
      parts_->parts() == 0 && spec_.levels == kLevelsAuto ? 0 : level_count(spec_, e, frame);
  // The coarsest level keeps minimum widths down to the whole extent.
  const double whole = whole_side(e);
  TilePlan plan;
  plan.size = spec_.tile_size;
  plan.frame = frame;
  plan.margin = std::max(margin(), min_width_margin(spec_, spec_.resolution, spec_.tile_size,
                                                    nlevels == 0 ? whole : 0.0));
  plan.dynamic_margin = spec_.tile_size * 0.5;
  nlohmann::json keys = nlohmann::json::array();
  for (const TileKey& k : planned_tiles(paths_, plan)) keys.push_back({k.x, k.y});
  nlohmann::json levels = nlohmann::json::array();
  for (int l = 1; l <= nlevels; ++l) {
    TilePlan lp = plan;
    const TileLevel params = level_parameters(plan.size, l);
    lp.size = params.tile_size;
    lp.margin = std::max(plan.margin, min_width_margin(spec_, params.resolution, lp.size,
                                                       l == nlevels ? whole : 0.0));
    lp.dynamic_margin = lp.size * 0.5;
    nlohmann::json lk = nlohmann::json::array();
    for (const TileKey& k : planned_tiles(paths_, lp)) lk.push_back({k.x, k.y});
    levels.push_back({{"level", l}, {"margin", lp.margin}, {"tiles", std::move(lk)}});
  }
  const nlohmann::json j = {{"frame", frame_to_json(frame)},
                            {"extent", {e.xmin, e.ymin, e.xmax, e.ymax}},
                            {"tile_size", plan.size},
                            {"margin", plan.margin},
                            {"dynamic_margin", plan.dynamic_margin},
                            {"layers", counts_to_json(counts_and_notes.layers)},
                            {"notes", counts_and_notes.notes},
                            {"provenance", provenance},
                            {"entries", entries_->count()},
                            {"read_entries", read_entries_->count()},
                            {"parts", parts_->parts()},
                            {"resolution", spec_.resolution},
                            {"levels", std::move(levels)},
                            {"tiles", keys}};
  // Written last: a plan on disk means the intermediate is complete.
  write_text_file(paths_.plan(), j.dump(1) + "\n");
}

void discard_work(const std::string& dir, bool made_dir) {
  remove_tree(WorkPaths{dir}.work());
  if (!made_dir) return;
  ::rmdir((dir + "/tiles").c_str());  // only when empty
  ::rmdir(dir.c_str());
}

Extent TilesetPreparer::extent() const {
  return parts_->extent();
}
uint64_t TilesetPreparer::parts(int kind) const {
  return parts_->parts(static_cast<PartKind>(kind));
}
uint64_t TilesetPreparer::entries() const {
  return entries_->count() + read_entries_->count();
}

PreparedScene prepare_tileset_streaming(const BuildSpec& spec, const BuildRequest& request,
                                        const std::function<const nlohmann::json&()>& provenance) {
  using Clock = std::chrono::steady_clock;
  auto since = [](Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  PreparedScene out;
  TilesetPreparer prep(spec, request.output);
  const WorkPaths paths{request.output};

  // Pass 1: read every source once; each layer's features to its spill.
  auto t0 = Clock::now();
  std::vector<std::string> spill_paths;
  std::vector<std::unique_ptr<SpillWriter>> spills;
  for (size_t i = 0; i < spec.layers.size(); ++i) {
    spill_paths.push_back(paths.work() + "/source_" + std::to_string(i) + ".bin");
    spills.push_back(std::make_unique<SpillWriter>(spill_paths.back()));
  }
  ReadChunks chunks;
  chunks.take = [&](size_t layer, SourceLayer& chunk) { spills.at(layer)->write(chunk); };
  chunks.restart = [&](size_t layer) { spills.at(layer)->restart(); };
  ReadOptions ro;
  ro.progress = request.progress;
  ro.chunks = &chunks;
  FeatureSet read = read_scene(spec, ro);
  uint64_t parts = 0;
  for (auto& s : spills) {
    s->close();
    parts += s->parts();
  }
  out.read_s = since(t0);

  // The frame, from the whole data (as choose_frame sees it in memory).
  t0 = Clock::now();
  const SpillSource source(read.layers, spill_paths);
  const SceneFrame frame = choose_frame(source, spec.crs);
  const std::optional<Extent> clip = clip_extent(frame, spec, source);
  out.project_s = since(t0);

  // Pass 2, layer by layer: project, clean, write, a chunk at a time.
  ProgressStage stage(request.progress, "prepare", parts, "parts");
  CleanOptions co;
  co.threads = spec.model.threads;
  ChunkCleaner cleaner(spec, clip, co, &stage);
  SceneFeatures cleaned;
  cleaned.layers = spec.layers;
  for (size_t li = 0; li < read.layers.size(); ++li) {
    t0 = Clock::now();
    const LayerProjection projection(source, li, frame, spec);
    out.project_s += since(t0);
    cleaner.begin_layer(static_cast<uint32_t>(li), read.layers[li].spec, read.manifest);
    source.chunks(li, chunks.parts, chunks.vertices, [&](SourceLayer& chunk) {
      auto t1 = Clock::now();
      const std::vector<double> scale = projection.apply(chunk, nullptr);
      out.project_s += since(t1);
      t1 = Clock::now();
      cleaner.clean_chunk(chunk, scale, cleaned);
      prep.add_parts(cleaned);
      for (const ManifestEntry& e : cleaned.manifest.entries) {
        out.skipped_failures += is_skipped_failure(e) ? 1 : 0;
        prep.add_entry(e);
      }
      cleaned.polygons.clear();
      cleaned.lines.clear();
      cleaned.dynamic_lines.clear();
      cleaned.manifest.entries.clear();
      out.clean_s += since(t1);
    });
    t0 = Clock::now();
    out.manifest.layers.push_back(cleaner.end_layer());
    std::remove(spill_paths[li].c_str());
    out.clean_s += since(t0);
  }
  t0 = Clock::now();
  // Read-stage entries (parts of kept features the kind could not draw)
  // follow clean's, as clean() puts them.
  for (const ManifestEntry& e : read.manifest.entries) {
    out.skipped_failures += is_skipped_failure(e) ? 1 : 0;
    prep.add_read_entry(e);
  }
  out.manifest.notes = read.manifest.notes;
  prep.finish(frame, out.manifest, provenance());
  stage.finish();
  out.frame = frame;
  out.extent = prep.extent();
  for (const SourceLayer& l : read.layers) out.layers.push_back(l.spec);
  out.entry_count = prep.entries();
  out.polygons = prep.parts(0);
  out.lines = prep.parts(1);
  out.dynamic_lines = prep.parts(2);
  out.clean_s += since(t0);
  return out;
}

namespace {

struct PreparedPlan {
  TilePlan plan;  // tiles: the keys, members empty
  std::vector<TileKey> keys;
  double resolution = 0;  // level 0's (the build's --resolution)
  // Overview levels 1, 2, ...: the level's rule, its grid (plan.size the
  // level's tile size, the same margin) and its tile keys.
  struct Level {
    TileLevel params;
    TilePlan plan;
    std::vector<TileKey> keys;
  };
  std::vector<Level> levels;
  Extent extent;      // scene coordinates
  Manifest manifest;  // counts and notes (no entries)
  uint64_t entries = 0, read_entries = 0;
  nlohmann::json provenance;
};

PreparedPlan read_plan(const WorkPaths& paths) {
  std::ifstream in(paths.plan(), std::ios::binary);
  if (!in)
    fail<output_error>(kTilesetStage,
                       "cannot read " + paths.plan() + " (the prepare step has not finished)");
  PreparedPlan p;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    p.plan.frame = frame_from_json(j.at("frame"));
    p.plan.size = j.at("tile_size").get<double>();
    p.plan.margin = j.at("margin").get<double>();
    p.plan.dynamic_margin = j.at("dynamic_margin").get<double>();
    const nlohmann::json& e = j.at("extent");
    p.extent = {e.at(0).get<double>(), e.at(1).get<double>(), e.at(2).get<double>(),
                e.at(3).get<double>()};
    p.manifest.layers = counts_from_json(j.at("layers"));
    p.manifest.notes = j.at("notes").get<std::vector<std::string>>();
    p.provenance = j.at("provenance");
    p.entries = j.at("entries").get<uint64_t>();
    p.read_entries = j.at("read_entries").get<uint64_t>();
    for (const nlohmann::json& k : j.at("tiles"))
      p.keys.push_back({k.at(0).get<int64_t>(), k.at(1).get<int64_t>()});
    p.resolution = j.at("resolution").get<double>();
    for (const nlohmann::json& l : j.at("levels")) {
      PreparedPlan::Level lv;
      lv.params = level_parameters(p.plan.size, l.at("level").get<int>());
      lv.plan = p.plan;
      lv.plan.size = lv.params.tile_size;
      lv.plan.margin = l.at("margin").get<double>();  // with the level's minimum widths
      lv.plan.dynamic_margin = lv.plan.size * 0.5;
      for (const nlohmann::json& k : l.at("tiles"))
        lv.keys.push_back({k.at(0).get<int64_t>(), k.at(1).get<int64_t>()});
      p.levels.push_back(std::move(lv));
    }
  } catch (const nlohmann::json::exception& e) {
    fail<output_error>(kTilesetStage, paths.plan() + ": " + e.what());
  }
  return p;
}

nlohmann::json tile_record_json(const TileEntry& e, bool reused) {
  return {{"empty", false},
          {"reused", reused},
          {"file", e.file},
          {"bytes", e.bytes},
          {"xxh64", hex64(e.xxh64)},
          {"polygons", e.polygons},
          {"lines", e.lines},
          {"dynamic_lines", e.dynamic_lines},
          {"layers", counts_to_json(e.layers)}};
}

}  // namespace

// ----------------------------------------------------------------- tiles --

namespace {

// An overview level's treatment of each part of a tile's window
// (formats/SPEC.md "Overview levels"): parts below the level's min_area /
// min_length are dropped, the rest simplified to its tolerance. Each part
// is counted by one tile of the level only, the one whose square holds its
// box's lower-left corner (its owner, always one of the tiles it reaches),
// so that the tiles' counts add up to the level's.
class LevelFilter : public PartFilter {
 public:
  LevelFilter(const TileLevel& level, const TilePlan& plan, const TileKey& key,
              const std::vector<LayerSpec>& layers)
      : level_(level),
        plan_(plan),
        key_(key),
        layers_(layers),
        simplifier_(level_tolerance(level)),
        counts_(layers.size()) {
    for (size_t i = 0; i < layers.size(); ++i) counts_[i].layer = layers[i].name;
  }
  // A part whose area (shell minus holes) is below min_area is left out;
  // of a part kept, each hole below min_area is, before the part is
  // simplified (a polygon without some of its holes stays valid).
  bool polygon(ScenePolygon& p) override {
    const bool own = owns(p.shell);
    uint64_t in = p.shell.size() + 1;
    for (const Ring& h : p.holes) in += h.size() + 1;
    bool keep = part_area(p) >= level_.min_area;
    uint64_t holes_dropped = 0;
    if (keep) {
      holes_dropped =
          std::erase_if(p.holes, [&](const Ring& h) { return ring_area(h) < level_.min_area; });
      keep = simplifier_.polygon(p, what(p));
    }
    uint64_t out = 0;
    if (keep) {
      out = p.shell.size() + 1;
      for (const Ring& h : p.holes) out += h.size() + 1;
    }
    if (own) {
      count(p.layer, keep, in, out);
      if (keep && p.layer < counts_.size()) counts_[p.layer].holes_dropped_small += holes_dropped;
    }
    return keep;
  }
  bool line(SceneLine& l, bool dynamic) override {
    const bool own = owns(l.points);
    const uint64_t in = l.points.size() + (l.closed ? 1 : 0);
    const double tolerance = level_line_tolerance(level_, dynamic ? 0.0 : l.width);
    // A dot (a point layer's line) is a symbol: no level drops it for its length.
    const bool dot = l.layer < layers_.size() && layers_[l.layer].kind == DecalKind::point;
    const bool keep =
        dot || (part_length(l) >= level_.min_length && simplifier_.line(l, what(l), tolerance));
    const uint64_t out = keep ? l.points.size() + (l.closed ? 1 : 0) : 0;
    if (own) count(l.layer, keep, in, out);
    return keep;
  }
  // This tile's share of the level's per-layer counts.
  const std::vector<LayerCounts>& counts() const { return counts_; }

 private:
  bool owns(const Ring& r) const {
    return tile_range(ring_box(r), 0, plan_.frame.origin_x, plan_.frame.origin_y, plan_.size).lo ==
           key_;
  }
  template <class Part>
  std::string what(const Part& p) const {
    return "level " + std::to_string(level_.level) + " layer '" +
           (p.layer < layers_.size() ? layers_[p.layer].name : std::string("?")) + "' fid " +
           std::to_string(p.fid) + " part " + std::to_string(p.part);
  }
  void count(uint32_t layer, bool keep, uint64_t in, uint64_t out) {
    if (layer >= counts_.size()) return;
    LayerCounts& c = counts_[layer];
    ++c.read;
    c.vertices_in += in;
    if (keep) {
      ++c.kept;
      ++c.parts;
      c.vertices_out += out;
    } else {
      ++c.dropped_small;
    }
  }

  const TileLevel& level_;
  const TilePlan& plan_;
  TileKey key_;
  const std::vector<LayerSpec>& layers_;
  PartSimplifier simplifier_;
  std::vector<LayerCounts> counts_;
};

// A level's counts in a tile record: [parts_in, parts, dropped_small,
// vertices_in, vertices_out, holes_dropped_small] per layer.
nlohmann::json level_counts_record(const std::vector<LayerCounts>& counts) {
  nlohmann::json a = nlohmann::json::array();
  for (const LayerCounts& c : counts)
    a.push_back(
        {c.read, c.parts, c.dropped_small, c.vertices_in, c.vertices_out, c.holes_dropped_small});
  return a;
}

// One tile of the plan: level 0 (full detail) or an overview level.
struct TileItem {
  int level = 0;
  TileKey key;
};

std::string item_name(const TileItem& t) {
  if (t.level == 0) return tile_name(t.key);
  // (Written without operator+: GCC 12 -O3 warns on it here, wrongly.)
  char prefix[16];
  std::snprintf(prefix, sizeof prefix, "L%d/", t.level);
  std::string name(prefix);
  name.append(tile_name(t.key));
  return name;
}

// Every tile of the plan, level 0's first, then each level's, in key order.
std::vector<TileItem> plan_items(const PreparedPlan& p) {
  std::vector<TileItem> items;
  for (const TileKey& k : p.keys) items.push_back({0, k});
  for (const PreparedPlan::Level& l : p.levels)
    for (const TileKey& k : l.keys) items.push_back({l.params.level, k});
  return items;
}

// The metadata of a tile's package beside what write_model writes: the
// scene's, with paths as a package records them (the same bytes from any
// checkout), and the tile's key, square, size and overview level.
nlohmann::json tile_metadata(const BuildSpec& spec, const SceneFeatures& tile,
                             const nlohmann::json& provenance, const std::string& path,
                             const TilePlan& plan, const TileKey& key, const TileLevel* level) {
  Manifest recorded = tile.manifest;
  record_manifest_paths(spec, recorded);
  nlohmann::json extra = package_metadata(spec, recorded, provenance, path);
  const Extent sq = plan.square(key);
  extra["tile"] = {{"x", key.x},
                   {"y", key.y},
                   {"square", {sq.xmin, sq.ymin, sq.xmax, sq.ymax}},
                   {"tile_size_m", plan.size},
                   {"margin_m", plan.margin}};
  if (level) {
    extra["tile"]["level"] = level->level;
    extra["tile"]["resolution_m"] = level->resolution;
    extra["tile"]["min_area_m2"] = level->min_area;
    extra["tile"]["min_length_m"] = level->min_length;
  }
  return extra;
}

// Dynamic-line heights taken beyond the DEM, summed over the tiles built.
struct DemTally {
  std::atomic<uint64_t> outside{0}, lines_outside{0}, vertices{0};
};

// A tile's grid has at most one cell per two static vertices, and at least
// kTileMinCells. The size budget (prep/model.hpp) is relative to the thesis
// 500x500 grid on the same data, which suits a package of 10^5..10^7
// vertices; a 2 km tile of a few thousand vertices would get ~25 cells per
// vertex, a cell table larger than its geometry and a grid choice that costs
// more than the tile (bench/tileset_scale.py).
constexpr uint32_t kTileMinCells = 4096;

uint32_t tile_max_cells(const SceneFeatures& tile) {
  uint64_t vertices = 0;
  for (const ScenePolygon& p : tile.polygons) {
    vertices += p.shell.size();
    for (const Ring& h : p.holes) vertices += h.size();
  }
  for (const SceneLine& l : tile.lines) vertices += l.points.size();
  return uint32_t(std::clamp<uint64_t>(vertices / 2, kTileMinCells, UINT32_MAX));
}

// A file at a tile's path that no tileset build wrote (no index or work
// folder records it): output_error, the file left alone.
void refuse_foreign_file(const std::string& path) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) == 0)
    fail<output_error>(kTilesetStage,
                       path +
                           " exists and was not written by a decalprep tileset build "
                           "(no index or work folder records it); move it away");
}

// Builds a tile's model (on an overview level `level`, cells at least two
// of its pixels wide) and writes its package with `extra`; returns what the
// package holds and adds its DEM counts to `dem`.
HeldParts write_tile(const SceneFeatures& tile, const BuildSpec& spec, const BuildRequest& request,
                     const TileLevel* level, double side, double whole, const std::string& path,
                     nlohmann::json& extra, DemTally& dem) {
  ModelOptions mo = spec.model;
  mo.dem_assume_crs = spec.assume_crs;
  mo.dem_more = spec.dem_more;
  if (level) mo.min_cell_m = kLevelMinCellPixels * level->resolution;
  mo.min_width_resolution = level ? level->resolution : spec.resolution;
  mo.min_width_side = side;
  mo.min_width_whole = whole;
  mo.max_cells = std::min(mo.max_cells, tile_max_cells(tile));
  DecalModel model = build_model(tile, mo, spec.dem);
  if (model.min_width_pixel_m > 0) extra["min_width_pixel_m"] = model.min_width_pixel_m;
  if (model.manifest.layers.empty()) model.manifest = tile.manifest;
  record_manifest_paths(spec, model.manifest);
  const HeldParts held =
      held_parts(model.poly_props, model.line_props.size(), model.dyn_line_props.size());
  dem.outside += model.dyn_vertices_outside_dem;
  dem.lines_outside += model.dyn_lines_outside_dem;
  dem.vertices += model.dyn_vertices.size();
  WriteOptions wo;
  wo.codec = request.compress ? Codec::zstd : Codec::none;
  wo.zstd_level = request.zstd_level;
  // Dashed lines cut by the tile keep the whole line's phase.
  if (std::any_of(model.line_dash_start.begin(), model.line_dash_start.end(),
                  [](double s) { return s != 0; }))
    extra["line_dash_start"] = model.line_dash_start;
  write_model(path, std::move(model), extra.dump(), wo);
  return held;
}

}  // namespace

// Progress counts candidate tiles: every tile of every level that a part's
// box (with its margin) reaches; one left with no part writes no package
// (the build's closing line says how many there were).
TileStepOutcome build_tiles(const BuildSpec& spec, const BuildRequest& request, size_t part,
                            size_t parts, std::vector<MemoryEstimate>* estimates) {
  const WorkPaths paths{request.output};
  const PreparedPlan prepared = read_plan(paths);
  const std::string& dir = request.output;
  // The plan's tiles of all levels, dealt round-robin to the steps.
  const std::vector<TileItem> all = plan_items(prepared);
  std::vector<TileItem> items;
  for (size_t i = 0; i < all.size(); ++i)
    if (parts <= 1 || i % parts == part) items.push_back(all[i]);
  for (const PreparedPlan::Level& l : prepared.levels)
    make_inner_dir(dir + "/tiles/L" + std::to_string(l.params.level));
  // A file at a tile's path is replaced only when a tileset build wrote it.
  const std::set<std::string> owned = owned_files(paths);

  ProgressStage stage(request.progress, "tiles", items.size(), "candidate tiles");
  TileStepOutcome out;
  std::atomic<size_t> built{0}, reused{0}, empty{0};
  DemTally dem;
  std::atomic<size_t> next{0};
  std::atomic<bool> stop{false};
  std::exception_ptr first_error;
  size_t first_error_at = items.size();
  std::mutex error_mutex;
  const unsigned jobs = std::max(1u, request.jobs);
  // --max-memory: every tile to build is checked once its window is cut
  // (prep/memory_estimate.hpp, estimate_tile). The report gets the largest
  // tile's estimate, or the one that stopped the build; ties go to the
  // first tile in plan order, whatever the scheduling.
  const MemoryLimit limit{request.max_memory};
  const double resident = current_rss_bytes();
  std::optional<std::pair<size_t, MemoryEstimate>> largest, stopped;
  auto note_estimate = [&](size_t i, const MemoryEstimate& e) {
    std::lock_guard<std::mutex> lock(error_mutex);
    if (!largest || e.bytes > largest->second.bytes ||
        (e.bytes == largest->second.bytes && i < largest->first))
      largest.emplace(i, e);
    if (limit && e.bytes > double(limit.bytes) && (!stopped || i < stopped->first))
      stopped.emplace(i, e);
  };

  auto work = [&] {
    std::unique_ptr<PartReader> reader;
    SceneFeatures window;
    window.frame = prepared.plan.frame;
    window.layers = spec.layers;
    window.manifest.notes = prepared.manifest.notes;
    for (;;) {
      const size_t i = next.fetch_add(1);
      if (i >= items.size() || stop.load()) return;
      try {
        const TileKey key = items[i].key;
        const int level = items[i].level;
        const PreparedPlan::Level* lv =
            level == 0 ? nullptr : &prepared.levels.at(size_t(level - 1));
        const TilePlan& plan = lv ? lv->plan : prepared.plan;
        if (!reader) reader = std::make_unique<PartReader>(paths);
        // The parts tile_plan would list for this tile, in scene order; on
        // an overview level, simplified and thinned as they are read.
        std::optional<LevelFilter> filter;
        if (lv) filter.emplace(lv->params, plan, key, spec.layers);
        reader->read_tile(plan, key, window, filter ? &*filter : nullptr);
        TilePlan one = plan;
        TilePlan::Members& m = one.tiles[key];
        for (uint32_t k = 0; k < window.polygons.size(); ++k) m.polygons.push_back(k);
        for (uint32_t k = 0; k < window.lines.size(); ++k) m.lines.push_back(k);
        for (uint32_t k = 0; k < window.dynamic_lines.size(); ++k) m.dynamic_lines.push_back(k);
        const SceneFeatures tile = tile_scene(window, one, key);
        window.polygons.clear();
        window.lines.clear();
        window.dynamic_lines.clear();
        nlohmann::json record;
        if (!tile.polygons.empty() || !tile.lines.empty() || !tile.dynamic_lines.empty()) {
          const std::string file = tile_file(level, key);
          const std::string path = dir + "/" + file;
          nlohmann::json extra = tile_metadata(spec, tile, prepared.provenance, path, plan, key,
                                               lv ? &lv->params : nullptr);
          const uint64_t digest = input_digest(tile, extra.dump(), request);
          extra["tile"]["input_xxh64"] = hex64(digest);
          std::optional<HeldParts> held = reusable(path, digest);
          const bool kept = held.has_value();
          if (!kept && !owned.count(file)) refuse_foreign_file(path);
          if (!kept) {
            const MemoryEstimate est = estimate_tile(tile, resident, jobs, file);
            note_estimate(i, est);
            check_memory(limit, est);
            // The coarsest level (level 0 without levels) keeps minimum
            // widths down to the whole extent.
            const bool coarsest = level == int(prepared.levels.size());
            held = write_tile(tile, spec, request, lv ? &lv->params : nullptr, plan.size,
                              coarsest ? whole_side(prepared.extent) : 0.0, path, extra, dem);
          }
          const std::optional<FileDigest> fd = file_digest(path);
          if (!fd) fail<output_error>(kTilesetStage, "cannot read back " + path);
          TileEntry e;
          e.file = file;
          e.bytes = fd->bytes;
          e.xxh64 = fd->xxh64;
          e.polygons = held->polygons;
          e.lines = held->lines;
          e.dynamic_lines = held->dynamic_lines;
          e.layers = tile.manifest.layers;
          record = tile_record_json(e, kept);
          (kept ? reused : built) += 1;
        } else {
          record = {{"empty", true}};
          empty += 1;
        }
        if (filter) record["level_counts"] = level_counts_record(filter->counts());
        write_text_file(paths.tile_record(key, level), record.dump() + "\n");
        stage.add(1);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        // The first failing tile in plan order, whatever the scheduling.
        if (i < first_error_at) {
          first_error_at = i;
          first_error = std::current_exception();
        }
        stop.store(true);
        return;
      }
    }
  };
  std::vector<std::thread> workers;
  for (unsigned j = 1; j < jobs; ++j) workers.emplace_back(work);
  work();
  for (std::thread& w : workers) w.join();
  if (estimates) {
    // The estimate that stopped the build when its tile failed first, else
    // the largest.
    if (first_error && stopped && stopped->first == first_error_at)
      estimates->push_back(stopped->second);
    else if (largest)
      estimates->push_back(largest->second);
  }
  if (first_error) std::rethrow_exception(first_error);
  stage.finish();
  out.tiles = items.size();
  out.built = built;
  out.reused = reused;
  out.empty = empty;
  out.dyn_vertices_outside_dem = dem.outside;
  out.dyn_lines_outside_dem = dem.lines_outside;
  out.dyn_vertices = dem.vertices;
  return out;
}

// -------------------------------------------------------------- finalize --

namespace {

// Every tile of the plan, of every level, must have been built: names the
// missing ones (output_error).
void check_all_built(const WorkPaths& paths, const std::vector<TileItem>& items) {
  std::vector<std::string> missing;
  for (const TileItem& t : items)
    if (!std::filesystem::exists(paths.tile_record(t.key, t.level)))
      missing.push_back(item_name(t));
  if (missing.empty()) return;
  std::string list;
  for (size_t i = 0; i < missing.size() && i < 20; ++i) list += (i ? ", " : "") + missing[i];
  if (missing.size() > 20) list += ", ... (" + std::to_string(missing.size() - 20) + " more)";
  fail<output_error>(kTilesetStage, std::to_string(missing.size()) + " of " +
                                        std::to_string(items.size()) +
                                        " tiles have not been built: " + list +
                                        "; run their tiles steps, then finalize again");
}

// One level's tiles as its records count them.
struct LevelTally {
  size_t tiles = 0, built = 0, reused = 0, empty = 0;
  uint64_t bytes = 0;
};

// An overview tile's record's per-layer counts (its "level_counts") added
// to the level's `counts`.
void add_level_counts(const std::string& rpath, const nlohmann::json& r,
                      std::vector<LayerCounts>& counts) {
  const nlohmann::json& lc = r.at("level_counts");
  if (lc.size() != counts.size())
    fail<output_error>(kTilesetStage, rpath + ": level_counts has " + std::to_string(lc.size()) +
                                          " layers, not " + std::to_string(counts.size()));
  for (size_t k = 0; k < counts.size(); ++k) {
    LayerCounts& c = counts[k];
    const nlohmann::json& v = lc.at(k);
    c.read += v.at(0).get<uint64_t>();
    c.parts += v.at(1).get<uint64_t>();
    c.kept += v.at(1).get<uint64_t>();
    c.dropped_small += v.at(2).get<uint64_t>();
    c.vertices_in += v.at(3).get<uint64_t>();
    c.vertices_out += v.at(4).get<uint64_t>();
    if (v.size() > 5) c.holes_dropped_small += v.at(5).get<uint64_t>();
  }
}

// One level's records into its entries (and, for an overview level, its
// per-layer counts summed over its tiles); the tile files into `names`.
void read_level_records(const WorkPaths& paths, int level, const TilePlan& lplan,
                        const std::vector<TileKey>& keys, std::vector<TileEntry>& entries,
                        std::vector<LayerCounts>* counts, std::set<std::string>& names,
                        LevelTally& tally) {
  for (const TileKey& key : keys) {
    const std::string rpath = paths.tile_record(key, level);
    std::ifstream in(rpath, std::ios::binary);
    if (!in) fail<output_error>(kTilesetStage, "cannot read " + rpath);
    try {
      const nlohmann::json r = nlohmann::json::parse(in);
      if (counts) add_level_counts(rpath, r, *counts);
      if (r.at("empty").get<bool>()) {
        ++tally.empty;
        continue;
      }
      TileEntry e;
      e.key = key;
      e.square = lplan.square(key);
      std::tie(e.origin_x, e.origin_y) = lplan.origin(key);
      e.file = r.at("file").get<std::string>();
      e.bytes = r.at("bytes").get<uint64_t>();
      e.xxh64 = std::stoull(r.at("xxh64").get<std::string>(), nullptr, 16);
      e.polygons = r.at("polygons").get<uint64_t>();
      e.lines = r.at("lines").get<uint64_t>();
      e.dynamic_lines = r.at("dynamic_lines").get<uint64_t>();
      e.layers = counts_from_json(r.at("layers"));
      ++tally.tiles;
      (r.at("reused").get<bool>() ? tally.reused : tally.built) += 1;
      tally.bytes += e.bytes;
      names.insert(e.file);
      entries.push_back(std::move(e));
    } catch (const nlohmann::json::exception& e) {
      fail<output_error>(kTilesetStage, rpath + ": " + e.what());
    }
  }
}

// The overview levels (formats/SPEC.md "Overview levels") into the index,
// their tallies into `out`.
void read_overview_levels(const WorkPaths& paths, const PreparedPlan& prepared, TilesetIndex& index,
                          std::set<std::string>& names, TilesetOutcome& out) {
  for (const PreparedPlan::Level& l : prepared.levels) {
    TileLevel level = l.params;
    level.layers.resize(prepared.manifest.layers.size());
    for (size_t k = 0; k < level.layers.size(); ++k)
      level.layers[k].layer = prepared.manifest.layers[k].layer;
    LevelTally t;
    read_level_records(paths, l.params.level, l.plan, l.keys, level.tiles, &level.layers, names, t);
    out.level_tiles += t.tiles;
    out.level_built += t.built;
    out.level_reused += t.reused;
    out.level_empty += t.empty;
    out.level_bytes += t.bytes;
    index.levels.push_back(std::move(level));
  }
  out.levels = static_cast<int>(index.levels.size());
  if (!index.levels.empty()) index.minor = kTilesetMinorLevels;
}

// Each level's drops as a note too, so that no reader of the manifest
// misses them (the per-layer counts are the level's `layers`).
void add_level_notes(TilesetIndex& index) {
  for (const TileLevel& l : index.levels) {
    uint64_t dropped = 0, parts_in = 0, holes = 0;
    for (const LayerCounts& c : l.layers)
      dropped += c.dropped_small, parts_in += c.read, holes += c.holes_dropped_small;
    char note[320];
    std::snprintf(note, sizeof note,
                  "overview level %d: %llu of %llu parts dropped_small (below %.10g m2 or %.10g m, "
                  "or collapsed at %.10g m or an eighth of a line's width); %llu holes of kept "
                  "parts dropped_small (below %.10g m2)",
                  l.level, static_cast<unsigned long long>(dropped),
                  static_cast<unsigned long long>(parts_in), l.min_area, l.min_length,
                  level_tolerance(l), static_cast<unsigned long long>(holes), l.min_area);
    index.manifest.notes.emplace_back(note);
  }
}

}  // namespace

TilesetOutcome finalize_tileset(const BuildSpec& spec, const BuildRequest& request,
                                Manifest* manifest) {
  const WorkPaths paths{request.output};
  const PreparedPlan prepared = read_plan(paths);
  const TilePlan& plan = prepared.plan;
  const std::string& dir = request.output;

  TilesetOutcome out;
  out.margin = plan.margin;
  TilesetIndex index;
  index.generator = "decalprep (package format " + std::to_string(decal::kVersionMajor) + "." +
                    std::to_string(decal::kVersionMinor) + ")";
  index.frame = plan.frame;
  index.tile_size = plan.size;
  index.margin = plan.margin;
  index.dynamic_margin = plan.dynamic_margin;
  check_all_built(paths, plan_items(prepared));
  std::set<std::string> names;
  LevelTally tally0;
  read_level_records(paths, 0, plan, prepared.keys, index.tiles, nullptr, names, tally0);
  out.tiles = tally0.tiles;
  out.built = tally0.built;
  out.reused = tally0.reused;
  out.empty = tally0.empty;
  out.bytes = tally0.bytes;
  index.resolution = prepared.resolution;
  read_overview_levels(paths, prepared, index, names, out);
  const Extent& e = prepared.extent;  // {} when empty
  const double ox = plan.frame.origin_x, oy = plan.frame.origin_y;
  index.extent =
      e.xmax >= e.xmin ? Extent{e.xmin + ox, e.ymin + oy, e.xmax + ox, e.ymax + oy} : Extent{};
  index.manifest = prepared.manifest;
  record_manifest_paths(spec, index.manifest);
  add_level_notes(index);
  index.entry_count = prepared.entries + prepared.read_entries;

  // manifest.json: the scene's entries, each feature once (clean's, then read's).
  const std::string manifest_path = dir + "/" + kTilesetManifestName;
  // An index the reader would refuse stops the build before manifest.json
  // or any stale tile is touched (tileset_index_json checks it again).
  if (const std::string problem = tileset_index_problem(index); !problem.empty())
    fail<output_error>(kTilesetStage, dir + "/" + kTilesetIndexName +
                                          " would not verify, so nothing was replaced: " + problem);
  write_manifest_from({paths.entries(), paths.read_entries()}, index.entry_count, manifest_path);
  const std::optional<FileDigest> md = file_digest(manifest_path);
  if (!md) fail<output_error>(kTilesetStage, "cannot read back " + manifest_path);
  index.manifest_bytes = md->bytes;
  index.manifest_xxh64 = md->xxh64;

  // Only files the index on disk or the work folder recorded go (read
  // before the new index replaces the old).
  remove_stale(dir, owned_files(paths), names, static_cast<int>(index.levels.size()));
  write_text_file(dir + "/" + kTilesetIndexName, tileset_index_json(index));
  if (manifest) *manifest = index.manifest;
  // The work folder is not part of the tileset (formats/SPEC.md "Tilesets").
  remove_tree(paths.work());
  return out;
}

}  // namespace prep::tiling
