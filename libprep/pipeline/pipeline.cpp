// The pipeline of ARCHITECTURE.md, in order, with timings and the JSON report.
// Each stage hands the next its named type; nothing reaches back.
#include "prep/pipeline.hpp"

#include <cpl_vsi.h>
#include <tbb/global_control.h>
#include <xxhash.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "prep/clean.hpp"
#include "prep/error.hpp"
#include "prep/feature_failure.hpp"
#include "prep/files.hpp"
#include "prep/manifest_json.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/model.hpp"
#include "prep/project.hpp"
#include "prep/read.hpp"
#include "prep/stage_error.hpp"
#include "prep/tile.hpp"
#include "prep/write.hpp"

namespace prep {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

namespace {

// The build stage holds positions as int32 millimetres from the origin
// (decal/format.hpp): a vertex farther than ~2147 km cannot be stored in one
// package (a tileset has no such limit: each tile has its own origin).
constexpr double kRangeLimit = double(2147483647LL - 2) * decal::kQuantumMetres;

bool out_of_range(const Point2& p) {
  return !(std::fabs(p.x) <= kRangeLimit && std::fabs(p.y) <= kRangeLimit);
}

std::string out_of_range_reason(const Point2& p) {
  std::ostringstream m;
  m.precision(12);
  m << "vertex (" << p.x << ", " << p.y
    << ") m lies more than 2147 km from the package origin; int32 millimetre positions "
       "cannot hold it (build a tileset with --tile-size, or leave it out with --extent)";
  return m.str();
}

// As soon as the frame is known (after project, before a long clean): the
// first feature, in input order, with a vertex out of range that the clip
// extent keeps. Without skip_failures it would stop the build after clean;
// it stops it now, with the same message. (With skip_failures the check
// after clean drops such features.)
void check_range_early(const ProjectedFeatures& p) {
  for (const SourceLayer& layer : p.features.layers)
    for (const SourceFeature& f : layer.features) {
      if (!f.drop_reason.empty()) continue;
      // A vertex no frame can hold (non-finite, or 1e9 m out) fails the
      // feature in clean, with that message.
      const auto absurd = [](const Point2& q) {
        return !(std::fabs(q.x) <= 1e9 && std::fabs(q.y) <= 1e9);
      };
      if (std::any_of(f.rings.begin(), f.rings.end(),
                      [&](const Ring& r) { return std::any_of(r.begin(), r.end(), absurd); }))
        continue;
      for (const Ring& r : f.rings)
        for (const Point2& q : r) {
          if (!out_of_range(q)) continue;
          if (p.clip && !(q.x >= p.clip->xmin && q.x <= p.clip->xmax && q.y >= p.clip->ymin &&
                          q.y <= p.clip->ymax))
            continue;
          fail_feature(FailureStage::build, layer.spec.source, layer.spec.name, f.fid,
                       out_of_range_reason(q));
        }
    }
}

// The same check after clean, per feature, so that it is a per-feature
// failure like the others (feature_failure.hpp): without skip_failures the
// first such feature stops the build (input error), with it the feature is
// dropped and recorded. Polygons, then static lines, then dynamic lines,
// each in input order.
void check_build_range(SceneFeatures& s, bool skip_failures) {
  using Key = std::pair<uint32_t, int64_t>;  // (layer, fid)
  std::map<Key, std::string> failed;
  std::vector<Key> order;
  auto check_ring = [&](const Ring& ring, uint32_t layer, int64_t fid) {
    if (failed.count({layer, fid})) return;
    for (const Point2& p : ring) {
      if (!out_of_range(p)) continue;
      const std::string reason = out_of_range_reason(p);
      if (!skip_failures) {
        const LayerSpec& l = s.layers.at(layer);
        fail_feature(FailureStage::build, l.source, l.name, fid, reason);
      }
      failed[{layer, fid}] = reason;
      order.push_back({layer, fid});
      return;
    }
  };
  for (const ScenePolygon& p : s.polygons) {
    check_ring(p.shell, p.layer, p.fid);
    for (const Ring& h : p.holes) check_ring(h, p.layer, p.fid);
  }
  for (const SceneLine& l : s.lines) check_ring(l.points, l.layer, l.fid);
  for (const SceneLine& l : s.dynamic_lines) check_ring(l.points, l.layer, l.fid);
  if (failed.empty()) return;

  // Drop every part of a failed feature and move it from kept to dropped.
  std::map<Key, uint64_t> parts_removed;
  auto gone = [&](uint32_t layer, int64_t fid) {
    if (!failed.count({layer, fid})) return false;
    ++parts_removed[{layer, fid}];
    return true;
  };
  std::erase_if(s.polygons, [&](const ScenePolygon& p) { return gone(p.layer, p.fid); });
  std::erase_if(s.lines, [&](const SceneLine& l) { return gone(l.layer, l.fid); });
  std::erase_if(s.dynamic_lines, [&](const SceneLine& l) { return gone(l.layer, l.fid); });
  std::set<Key> was_repaired;
  std::erase_if(s.manifest.entries, [&](const ManifestEntry& e) {
    for (uint32_t li = 0; li < s.layers.size(); ++li) {
      if (s.layers[li].name != e.layer || !failed.count({li, e.fid})) continue;
      if (e.action == ManifestAction::repaired) was_repaired.insert({li, e.fid});
      return e.action == ManifestAction::repaired || e.action == ManifestAction::part_dropped;
    }
    return false;
  });
  for (const Key& k : order) {
    const std::string& name = s.layers[k.first].name;
    for (LayerCounts& c : s.manifest.layers) {
      if (c.layer != name) continue;
      --c.kept;
      ++c.dropped;
      if (was_repaired.count(k)) --c.repaired;
      c.parts -= parts_removed[k];
    }
    ManifestEntry e{name, k.second, -1, ManifestAction::dropped, failed[k]};
    e.failed_in = FailureStage::build;
    s.manifest.entries.push_back(std::move(e));
  }
  s.extent = kept_extent(s);
}

size_t count_skipped_failures(const Manifest& m) {
  size_t n = 0;
  for (const ManifestEntry& e : m.entries) n += is_skipped_failure(e) ? 1 : 0;
  return n;
}

}  // namespace

namespace {

// The report's memory part: peak RSS after each stage, every estimate with
// its basis, and the limit (prep/memory_estimate.hpp).
void add_memory_report(nlohmann::json& report,
                       const std::vector<std::pair<std::string, double>>& peaks,
                       const std::vector<MemoryEstimate>& estimates, const MemoryLimit& limit) {
  nlohmann::json pk = nlohmann::json::object();
  for (const auto& [stage, mib] : peaks) pk[stage] = mib;
  report["peak_rss_mib_after"] = pk;
  nlohmann::json est = nlohmann::json::object();
  constexpr double kMiB = 1024.0 * 1024.0;
  for (const MemoryEstimate& e : estimates) {
    est[e.point] = {{"mib", e.bytes / kMiB},
                    {"basis", e.basis},
                    {"polygon_vertices", e.polygon_vertices},
                    {"line_vertices", e.line_vertices},
                    {"polygon_parts", e.polygon_parts},
                    {"line_parts", e.line_parts},
                    {"source_bytes", e.source_bytes}};
    if (!e.tile.empty())
      est[e.point].update(
          {{"tile", e.tile}, {"jobs", e.jobs}, {"resident_mib", e.resident_bytes / kMiB}});
    if (e.grid_cells > 0)
      est[e.point].update({{"resident_mib", e.resident_bytes / kMiB},
                           {"grid_cells", e.grid_cells},
                           {"cell_mib", e.grid_cell_bytes / kMiB},
                           {"geometry_mib", e.geometry_bytes / kMiB}});
  }
  report["memory_estimate"] = est;
  if (limit) report["max_memory_mib"] = double(limit.bytes) / kMiB;
}

// The overview levels of a tileset build, for the report (all levels
// together; tileset.json has them level by level).
nlohmann::json levels_report(const tiling::TilesetOutcome& t) {
  return {{"levels", t.levels},       {"tiles", t.level_tiles}, {"built", t.level_built},
          {"reused", t.level_reused}, {"empty", t.level_empty}, {"bytes", t.level_bytes}};
}

// What a build has measured so far: the report's memory part, also when the
// build fails.
struct MemoryTrail {
  // Peak RSS after each stage (the process high-water mark so far), for the
  // report and the memory model (memory_estimate.hpp).
  std::vector<std::pair<std::string, double>> peaks;
  // Estimates of the peak, checked against --max-memory as soon as each is
  // known (and always reported, so the model can be checked).
  std::vector<MemoryEstimate> estimates;
  // The warnings given so far (the report's "warnings"), and the layer
  // counts once clean has made them (a failed build's report has them too).
  std::vector<std::string> warnings;
  nlohmann::json layer_counts;
};

// ------------------------------------------------ warnings, empty builds --

// One warning on stderr ("decalprep build: warning: ...", or with
// --progress json the object {"event": "warning", "text": ...}). Printed
// with -q too: it says the package is not what the scene asked for.
void print_warning(const BuildRequest& request, const std::string& text) {
  const ProgressMode mode = request.progress ? request.progress->mode() : ProgressMode::none;
  if (mode == ProgressMode::json)
    request.progress->message(nlohmann::json{{"event", "warning"}, {"text", text}}.dump());
  else if (mode != ProgressMode::none)
    request.progress->message("decalprep build: warning: " + text);
  else
    std::fprintf(stderr, "decalprep build: warning: %s\n", text.c_str());
}

// Gives `warnings` (recorded in the trail for the report); with --strict
// they stop the build instead (strict_error, exit 10), all of them named.
void give_warnings(const std::vector<std::string>& warnings, const BuildRequest& request,
                   MemoryTrail& trail) {
  if (warnings.empty()) return;
  trail.warnings.insert(trail.warnings.end(), warnings.begin(), warnings.end());
  if (!request.strict) {
    for (const std::string& w : warnings) print_warning(request, w);
    return;
  }
  std::string text;
  for (const std::string& w : warnings) text += (text.empty() ? "" : "; ") + w;
  fail<strict_error>(kBuildStage, "--strict makes this warning an error: " + text);
}

// A layer that read no feature: a `where` or `sql` that matches nothing, a
// wrong source layer, an empty source. Named with its source and filter
// (a casing layer shares its layer's read and is not named again).
std::vector<std::string> empty_layer_warnings(const BuildSpec& scene, const Manifest& manifest) {
  std::vector<std::string> out;
  for (const LayerCounts& c : manifest.layers) {
    if (c.read > 0) continue;
    const auto l = std::find_if(scene.layers.begin(), scene.layers.end(),
                                [&](const LayerSpec& s) { return s.name == c.layer; });
    if (l == scene.layers.end() || !l->casing_of.empty()) continue;
    std::string text = "layer '" + l->name + "' read no feature from " + l->source;
    if (!l->layer.empty()) text += " layer '" + l->layer + "'";
    if (!l->where.empty()) text += " where \"" + l->where + "\"";
    if (!l->sql.empty()) text += " sql \"" + l->sql + "\"";
    out.push_back(text);
  }
  return out;
}

// Widths no map means: a static width (or casing width) in ground metres
// below 1 mm (thinner than the package's quantum; no view shows it) or
// above 100 km, a dynamic width in pixels below 0.1 or above 1000 (a
// metre value given where pixels are meant, or the reverse). Named with
// the layer and the value; the build goes on (--strict stops it).
constexpr double kMinStaticWidthM = 1e-3, kMaxStaticWidthM = 1e5;
constexpr double kMinDynamicWidthPx = 0.1, kMaxDynamicWidthPx = 1000;

std::vector<std::string> width_warnings(const BuildSpec& scene) {
  std::vector<std::string> out;
  auto check = [&](const LayerSpec& l, const char* key, double w, double lo, double hi,
                   const char* unit) {
    if (w >= lo && w <= hi) return;
    char m[200];
    std::snprintf(m, sizeof m, ": %s %.6g %s is outside the plausible %.6g..%.6g %s of a %s line",
                  key, w, unit, lo, hi, unit, l.dynamic ? "dynamic" : "static");
    out.push_back("layer '" + l.name + "'" + layer_place(scene, l) + m);
  };
  for (const LayerSpec& l : scene.layers) {
    if (l.kind == DecalKind::polygon || !l.casing_of.empty()) continue;
    if (l.dynamic) {
      check(l, "width", l.style.width, kMinDynamicWidthPx, kMaxDynamicWidthPx, "pixels");
    } else {
      check(l, "width", l.style.width, kMinStaticWidthM, kMaxStaticWidthM, "m");
      if (l.casing_width > 0)
        check(l, "casing_width", l.casing_width, kMinStaticWidthM, kMaxStaticWidthM, "m");
    }
  }
  return out;
}

// Dynamic-line vertices whose heights came from beyond the DEM (its edge
// cell's value, not the terrain under them), counted by the build stage.
// `lines` is the count of dynamic lines, or 0 where it is not known (a
// tileset's lines are cut by its tiles).
std::vector<std::string> terrain_warnings(const BuildSpec& scene, uint64_t outside,
                                          uint64_t vertices, uint64_t lines_outside,
                                          uint64_t lines) {
  if (outside == 0) return {};
  return {std::to_string(outside) + " of " + std::to_string(vertices) +
          " dynamic-line vertices, on " + std::to_string(lines_outside) +
          (lines ? " of " + std::to_string(lines) : std::string()) + " lines" +
          (lines ? "" : " (counted per tile)") + ", lie outside the DEM " +
          dem_text(scene.dem, scene.dem_more) +
          ": their heights are its edge cells', not the terrain's (use a DEM that covers the "
          "scene, or an --extent within it)"};
}
std::vector<std::string> terrain_warnings(const BuildSpec& scene, const DecalModel& model) {
  return terrain_warnings(scene, model.dyn_vertices_outside_dem, model.dyn_vertices.size(),
                          model.dyn_lines_outside_dem, model.dyn_line_start.size());
}
std::vector<std::string> terrain_warnings(const BuildSpec& scene,
                                          const tiling::TileStepOutcome& t) {
  return terrain_warnings(scene, t.dyn_vertices_outside_dem, t.dyn_vertices,
                          t.dyn_lines_outside_dem, 0);
}

// A build that kept no feature from any layer stops (empty_error, exit 9)
// before it writes a package, unless allow_empty; `parts` are the parts
// clean kept. The message gives every layer's counts.
void check_not_empty(const BuildSpec& scene, const Manifest& manifest, size_t parts) {
  const LayerCounts total = manifest_totals(manifest);
  if (scene.allow_empty || (total.kept > 0 && parts > 0)) return;
  std::string layers;
  for (const LayerCounts& c : manifest.layers)
    layers += (layers.empty() ? "" : "; ") +
              ("'" + c.layer + "' read " + std::to_string(c.read) + ", clipped away " +
               std::to_string(c.clipped_away) + ", dropped " + std::to_string(c.dropped));
  fail<empty_error>(kBuildStage,
                    "no layer kept a feature (" + layers +
                        "), so no package was written; check the sources, their where/sql "
                        "filters and the extent, or give --allow-empty to write an empty package");
}

// The report of a build that failed with `e` (run_build): what was
// measured and estimated up to the failure, the warnings and counts so far.
nlohmann::json failed_report(const error& e, const BuildRequest& request,
                             const MemoryTrail& trail) {
  nlohmann::json failed = {{"report_version", 1},
                           {"package_written", false},
                           {"error", e.what()},
                           {"exit_code", static_cast<int>(e.code())}};
  add_memory_report(failed, trail.peaks, trail.estimates, MemoryLimit{request.max_memory});
  failed["warnings"] = trail.warnings;
  if (!trail.layer_counts.is_null()) failed["manifest"] = trail.layer_counts;
  return failed;
}

// --max-memory while the sources are read (RssWatch): the resident set is
// over the limit inside GDAL, which cannot be interrupted, so the build
// ends here as a resource_error would end it, from the watching thread:
// the report (if asked), the message, exit 6. No package exists yet.
[[noreturn]] void stop_reading(double rss, const BuildRequest& request, const MemoryTrail& trail) {
  const resource_error e(
      std::string(kMemoryStage) + ": the read stage's resident set reached " +
      format_memory_size(rss) + ", over --max-memory " +
      format_memory_size(double(request.max_memory)) +
      " (the source driver's own memory, e.g. GeoJSON parsed a feature at a time, each feature's "
      "JSON object whole: bench/memory/geojson_peak_rss.csv); stopped at the limit. Raise "
      "--max-memory, or convert the source to a format read feature by feature (ogr2ogr -f "
      "FlatGeobuf, or GeoJSONSeq), or split its large features");
  if (!request.report.empty()) {
    try {
      write_text_file(request.report, failed_report(e, request, trail).dump(2) + "\n");
    } catch (const error&) {
      // The memory stop matters more than the report.
    }
  }
  std::fprintf(stderr, "decalprep: %s\n", e.what());
  std::fflush(nullptr);
  std::_Exit(static_cast<int>(ExitCode::resource));
}

// The checks once clean has run: for a tileset (whose read runs inside its
// prepare step) the warnings of layers that read nothing, errors under
// --strict (a single build gives them right after read); then an empty
// result (not for a dry run, which writes no package anyway).
void check_cleaned(const BuildSpec& scene, const BuildRequest& request, const Manifest& manifest,
                   size_t parts, bool layer_warnings, MemoryTrail& trail) {
  nlohmann::json layers = nlohmann::json::array();
  for (const LayerCounts& c : manifest.layers) layers.push_back(layer_counts_json(c));
  trail.layer_counts = {{"layers", layers}, {"totals", totals_json(manifest)}};
  if (layer_warnings) give_warnings(empty_layer_warnings(scene, manifest), request, trail);
  if (!request.dry_run) check_not_empty(scene, manifest, parts);
}

// The estimate before read, with a tileset's advice: its sources are read
// as a single build's are, so tiles do not lower this part.
MemoryEstimate before_read(const BuildSpec& scene, const BuildRequest& request) {
  MemoryEstimate e = estimate_before_read(scene, request.dry_run);
  if (scene.tile_size > 0)
    e.advice =
        "Raise --max-memory, or thin the input (--extent or --where to keep less): a tileset "
        "reads its sources as a single build does";
  return e;
}

// --threads caps every stage's oneTBB work (the output does not depend on it).
std::unique_ptr<tbb::global_control> cap_threads(const BuildSpec& scene) {
  if (scene.model.threads <= 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                               scene.model.threads);
}

// A tileset's part of the report.
nlohmann::json tileset_report(const BuildSpec& scene, const tiling::TilesetOutcome& t) {
  nlohmann::json j = {{"tile_size_m", scene.tile_size},
                      {"margin_m", t.margin},
                      {"tiles", t.tiles},
                      {"built", t.built},
                      {"reused", t.reused},
                      {"empty", t.empty},
                      {"bytes", t.bytes}};
  if (t.levels > 0) j["levels"] = levels_report(t);
  return j;
}

// What a tileset build made, the overview levels' tiles and bytes apart
// and in the sum (they can outweigh full detail).
std::string tileset_summary(const tiling::TilesetOutcome& t) {
  std::string s = std::to_string(t.tiles) + " tiles (" + std::to_string(t.built) + " built, " +
                  std::to_string(t.reused) + " kept from an earlier run), " +
                  std::to_string(t.bytes) + " bytes";
  if (t.levels > 0)
    s += " at full detail; overview levels 1.." + std::to_string(t.levels) + ": " +
         std::to_string(t.level_tiles) + " tiles (" + std::to_string(t.level_built) + " built, " +
         std::to_string(t.level_reused) + " kept), " + std::to_string(t.level_bytes) + " bytes; " +
         std::to_string(t.tiles + t.level_tiles) + " tiles, " +
         std::to_string(t.bytes + t.level_bytes) + " bytes in all";
  // The progress counts candidate tiles; say how many held no part.
  const size_t empty = t.empty + t.level_empty;
  return s + "; " + std::to_string(t.tiles + t.level_tiles + empty) + " candidate tiles, " +
         std::to_string(empty) + " of them with no part";
}

// One step of a tileset build (BuildRequest::step), in a process of its own.
// The report says which step ran and what it did; the state for the next
// step is in the work folder only (prep/tile.hpp, namespace tiling).
BuildResult run_tileset_step(const BuildSpec& scene, const BuildRequest& request,
                             MemoryTrail& trail) {
  using Step = BuildRequest::Step;
  if (request.output.empty()) fail<usage_error>(kBuildStage, "no output path (-o)");
  if (scene.tile_size <= 0)
    fail<usage_error>(kBuildStage, "--step is a step of a tileset build: give --tile-size");
  if (request.dry_run) fail<usage_error>(kBuildStage, "--step and --dry-run exclude each other");
  if (request.step == Step::tiles &&
      (request.step_parts == 0 || request.step_part >= request.step_parts))
    fail<usage_error>(kBuildStage, "--step tiles K/N needs 0 <= K < N, not " +
                                       std::to_string(request.step_part) + "/" +
                                       std::to_string(request.step_parts));
  const std::unique_ptr<tbb::global_control> threads = cap_threads(scene);
  const auto t0 = Clock::now();
  BuildResult result;
  nlohmann::json report = {{"report_version", 1}, {"output", request.output}};
  auto say = [&](const std::string& line) {
    if (request.progress && request.progress->mode() != ProgressMode::none)
      request.progress->message(request.progress->mode() == ProgressMode::json
                                    ? nlohmann::json{{"event", "step"}, {"text", line}}.dump()
                                    : line);
  };
  // --max-memory: prepare is checked before it reads, each tile of a tiles
  // step as it is cut; the step's report has the memory part.
  const MemoryLimit limit{request.max_memory};
  std::vector<std::pair<std::string, double>>& peaks = trail.peaks;
  std::vector<MemoryEstimate>& estimates = trail.estimates;
  // The folder is held for the step: prepare and finalize alone, the tiles
  // steps of one job side by side. A prepare that SIGINT or SIGTERM stops
  // leaves no half work folder.
  tiling::TilesetDir tileset_dir(request.output,
                                 request.step == Step::tiles
                                     ? tiling::TilesetDir::Access::shared
                                     : tiling::TilesetDir::Access::exclusive,
                                 request.step == Step::prepare);
  std::optional<OnInterrupt> undo;
  if (request.step == Step::prepare)
    undo.emplace("the prepare step was stopped", [dir = request.output, made = tileset_dir.made()] {
      std::fprintf(stderr, "decalprep: %s\n", tiling::remove_after_interrupt(dir, made).c_str());
    });
  switch (request.step) {
    case Step::prepare: {
      give_warnings(width_warnings(scene), request, trail);
      estimates.push_back(before_read(scene, request));
      check_memory(limit, estimates.back());
      const nlohmann::json provenance = provenance_json(scene);
      tiling::PreparedScene p;
      try {
        // The sources' drivers may hold more than any estimate: watched.
        const RssWatch watch(limit, [&](double rss) {
          tiling::remove_after_interrupt(request.output, tileset_dir.made());
          stop_reading(rss, request, trail);
        });
        p = tiling::prepare_tileset_streaming(
            scene, request, [&]() -> const nlohmann::json& { return provenance; });
        check_cleaned(scene, request, p.manifest, p.polygons + p.lines + p.dynamic_lines, true,
                      trail);
      } catch (...) {
        tiling::discard_work(request.output, tileset_dir.made());
        throw;
      }
      report["step"] = "prepare";
      report["timings_s"] = {{"read", p.read_s}, {"project", p.project_s}, {"clean", p.clean_s}};
      report["output_counts"] = {
          {"polygons", p.polygons}, {"lines", p.lines}, {"dynamic_lines", p.dynamic_lines}};
      report["entry_count"] = p.entry_count;
      peaks.emplace_back("prepare", peak_rss_mib());
      result.skipped_failures = p.skipped_failures;
      say("step prepare: " + std::to_string(p.polygons + p.lines + p.dynamic_lines) + " parts in " +
          request.output + "/.work");
      break;
    }
    case Step::tiles: {
      const tiling::TileStepOutcome t =
          tiling::build_tiles(scene, request, request.step_part, request.step_parts, &estimates);
      give_warnings(terrain_warnings(scene, t), request, trail);
      peaks.emplace_back("tiles", peak_rss_mib());
      report["step"] = "tiles";
      report["part"] = request.step_part;
      report["parts"] = request.step_parts;
      report["tiles"] = {
          {"tiles", t.tiles}, {"built", t.built}, {"reused", t.reused}, {"empty", t.empty}};
      say("step tiles " + std::to_string(request.step_part) + "/" +
          std::to_string(request.step_parts) + ": " + std::to_string(t.tiles) + " tiles (" +
          std::to_string(t.built) + " built, " + std::to_string(t.reused) + " kept)");
      break;
    }
    case Step::finalize: {
      report["step"] = "finalize";
      const bool work = std::filesystem::exists(request.output + "/.work");
      const bool index = std::filesystem::exists(request.output + "/" + kTilesetIndexName);
      if (!work && index) {
        // Finalized by an earlier run: nothing to do (the step is idempotent).
        report["already_finalized"] = true;
        say("step finalize: " + request.output + " was finalized already");
        result.package_written = true;
        break;
      }
      const tiling::TilesetOutcome t = tiling::finalize_tileset(scene, request);
      report["tileset"] = tileset_report(scene, t);
      result.package_written = true;
      say("step finalize: " + tileset_summary(t) + "; in " + request.output);
      break;
    }
    case Step::all: break;
  }
  report["package_written"] = result.package_written;
  report["skipped_failures"] = result.skipped_failures;
  report["total_s"] = seconds_since(t0);
  if (request.step != Step::finalize) add_memory_report(report, peaks, estimates, limit);
  result.report_json = report.dump(2) + "\n";
  if (!request.report.empty()) write_text_file(request.report, result.report_json);
  return result;
}

// ------------------------------------------------ a build, stage by stage --

// The bookkeeping beside a build's stages: each stage's time and the peak
// RSS after it, and the memory estimates, each checked against --max-memory
// as soon as it is known. Peaks and estimates live in the trail, which a
// failed build reports too.
class StageLog {
 public:
  StageLog(const BuildRequest& request, MemoryTrail& trail)
      : limit_{request.max_memory}, trail_(trail) {}
  const MemoryLimit& limit() const { return limit_; }
  const std::vector<std::pair<std::string, double>>& timings() const { return timings_; }
  // A stage starts now (the clock of done()).
  void start() { t0_ = Clock::now(); }
  // A stage's time as measured elsewhere; since start(); the peak RSS now.
  void time(const std::string& stage, double seconds) { timings_.emplace_back(stage, seconds); }
  void time(const std::string& stage) { time(stage, seconds_since(t0_)); }
  void peak(const std::string& stage) { trail_.peaks.emplace_back(stage, peak_rss_mib()); }
  // Both, for a stage that ends now.
  void done(const std::string& stage) {
    time(stage);
    peak(stage);
  }
  void estimate(const MemoryEstimate& e) {
    trail_.estimates.push_back(e);
    if (limit_) check_memory(limit_, e);
  }

 private:
  const MemoryLimit limit_;
  MemoryTrail& trail_;
  std::vector<std::pair<std::string, double>> timings_;
  Clock::time_point t0_ = Clock::now();
};

// The sources' hashes (provenance), computed once, beside the read: hashing
// a large source costs as much as a stage.
class SourceProvenance {
 public:
  explicit SourceProvenance(const BuildSpec& scene)
      : future_(std::async(std::launch::async, [&scene] { return provenance_json(scene); })) {}
  const nlohmann::json& get() {
    if (!value_) value_ = future_.get();
    return *value_;
  }

 private:
  std::future<nlohmann::json> future_;
  std::optional<nlohmann::json> value_;
};

// A tileset's read, project and clean, out of core (prep/tile.hpp, namespace tiling):
// they stream through the work folder chunk by chunk, and each tile later
// reads its window of the intermediate; nothing holds the whole scene. A
// failure removes the work folder (and the tileset folder if `made_dir`).
tiling::PreparedScene prepare_streamed(const BuildSpec& scene, const BuildRequest& request,
                                       bool made_dir, SourceProvenance& provenance, StageLog& log,
                                       MemoryTrail& trail, BuildResult& result) {
  tiling::PreparedScene p;
  try {
    const RssWatch watch(log.limit(), [&](double rss) {
      tiling::remove_after_interrupt(request.output, made_dir);
      stop_reading(rss, request, trail);
    });
    p = tiling::prepare_tileset_streaming(
        scene, request, [&]() -> const nlohmann::json& { return provenance.get(); });
  } catch (...) {
    tiling::discard_work(request.output, made_dir);
    throw;
  }
  log.time("read", p.read_s);
  log.time("project", p.project_s);
  log.time("clean", p.clean_s);
  log.peak("clean");
  result.scene.frame = p.frame;
  result.scene.extent = p.extent;
  result.scene.layers = p.layers;
  result.scene.manifest = p.manifest;
  try {
    check_cleaned(scene, request, result.scene.manifest, p.polygons + p.lines + p.dynamic_lines,
                  true, trail);
  } catch (...) {
    tiling::discard_work(request.output, made_dir);
    throw;
  }
  return p;
}

// Read, project and clean in memory (a single package, or a tileset's dry
// run) into result.scene; the projected features are freed before the
// build stage.
void read_project_clean(const BuildSpec& scene, const BuildRequest& request, StageLog& log,
                        MemoryTrail& trail, BuildResult& result) {
  const bool tiled = scene.tile_size > 0;
  ReadOptions ro;
  ro.progress = request.progress;
  std::optional<FeatureSet> read;
  {
    const RssWatch watch(log.limit(), [&](double rss) { stop_reading(rss, request, trail); });
    read = read_scene(scene, ro);
  }
  FeatureSet features = std::move(*read);
  read.reset();
  log.done("read");
  give_warnings(empty_layer_warnings(scene, features.manifest), request, trail);
  log.estimate(estimate_after_read(scene, features, request.dry_run));

  log.start();
  SceneFrame frame = choose_frame(features, scene.crs);
  ProjectedFeatures projected = project(std::move(features), frame, scene, request.progress);
  log.done("project");
  if (!tiled && !scene.skip_failures) check_range_early(projected);

  log.start();
  CleanOptions co;
  co.threads = scene.model.threads;
  co.progress = request.progress;
  result.scene = clean(std::move(projected), scene, co);
  if (!tiled) check_build_range(result.scene, scene.skip_failures);
  log.time("clean");
  check_cleaned(
      scene, request, result.scene.manifest,
      result.scene.polygons.size() + result.scene.lines.size() + result.scene.dynamic_lines.size(),
      false, trail);
  log.peak("clean");
}

// A tileset's tiles, each checked against --max-memory as it is cut, then
// tileset.json; the progress line says which tiles this run built (a
// resumed build says how many it kept).
tiling::TilesetOutcome build_tileset(const BuildSpec& scene, const BuildRequest& request,
                                     bool made_dir, StageLog& log, MemoryTrail& trail) {
  log.start();
  tiling::TilesetOutcome tileset;
  try {
    const tiling::TileStepOutcome t = tiling::build_tiles(scene, request, 0, 1, &trail.estimates);
    give_warnings(terrain_warnings(scene, t), request, trail);
    tileset = tiling::finalize_tileset(scene, request);
  } catch (...) {
    tiling::discard_work(request.output, made_dir);
    throw;
  }
  log.done("tiles");
  if (request.progress && request.progress->mode() != ProgressMode::none) {
    const nlohmann::json j = {{"event", "tileset"},
                              {"tiles", tileset.tiles},
                              {"built", tileset.built},
                              {"reused", tileset.reused},
                              {"bytes", tileset.bytes},
                              {"levels", tileset.levels},
                              {"level_tiles", tileset.level_tiles},
                              {"level_built", tileset.level_built},
                              {"level_reused", tileset.level_reused},
                              {"level_bytes", tileset.level_bytes},
                              {"output", request.output}};
    request.progress->message(
        request.progress->mode() == ProgressMode::json
            ? j.dump()
            : stage_message(kTilesetStage, tileset_summary(tileset) + "; in " + request.output));
  }
  return tileset;
}

// The build stage (the model, checked against --max-memory once its grid
// is chosen) and the write stage of a single package.
void build_and_write(const BuildSpec& scene, const BuildRequest& request,
                     SourceProvenance& provenance, StageLog& log, MemoryTrail& trail,
                     BuildResult& result) {
  log.start();
  ModelOptions model_options = scene.model;
  model_options.dem_assume_crs = scene.assume_crs;  // a DEM is a source too
  model_options.dem_more = scene.dem_more;
  model_options.min_width_resolution = scene.resolution;
  model_options.progress = request.progress;
  model_options.on_grid = [&](const GridFootprint& grid) {
    log.estimate(estimate_after_grid(grid, result.scene));
  };
  DecalModel model = build_model(result.scene, model_options, scene.dem);
  give_warnings(terrain_warnings(scene, model), request, trail);
  log.done("build");

  log.start();
  // build_model carries the manifest; make sure the package has it.
  if (model.manifest.layers.empty()) model.manifest = result.scene.manifest;
  // The report carries what the build stage added too (quad-tree depth
  // cap / leaf overflow notes, dynamic-line notes), not only clean's part.
  result.scene.manifest = model.manifest;
  record_manifest_paths(scene, model.manifest);  // the report keeps them as given
  nlohmann::json extra = package_metadata(scene, model.manifest, provenance.get(), request.output);
  if (model.min_width_pixel_m > 0) extra["min_width_pixel_m"] = model.min_width_pixel_m;
  WriteOptions wo;
  wo.codec = request.compress ? Codec::zstd : Codec::none;
  wo.zstd_level = request.zstd_level;
  wo.progress = request.progress;
  write_model(request.output, std::move(model), extra.dump(), wo);  // frees as it goes
  log.done("write");
  result.package_written = true;
}

// The report of a whole build, into result.report_json (and --report).
void finish_report(const BuildSpec& scene, const BuildRequest& request,
                   const std::optional<tiling::PreparedScene>& streamed,
                   const std::optional<tiling::TilesetOutcome>& tileset,
                   SourceProvenance& provenance, const StageLog& log, const MemoryTrail& trail,
                   BuildResult& result) {
  nlohmann::json report = report_object(result.scene, request.dry_run ? "" : request.output,
                                        log.timings(), result.package_written);
  report["provenance"] = provenance.get();
  if (tileset) report["tileset"] = tileset_report(scene, *tileset);
  report["dry_run"] = request.dry_run;
  report["warnings"] = trail.warnings;
  add_memory_report(report, trail.peaks, trail.estimates, log.limit());
  if (streamed) {
    // The entries are in manifest.json, not in memory.
    report["manifest"].erase("entries");
    report["manifest"]["entry_count"] = streamed->entry_count;
    report["manifest"]["entries_file"] = kTilesetManifestName;
    report["output_counts"] = {{"polygons", streamed->polygons},
                               {"lines", streamed->lines},
                               {"dynamic_lines", streamed->dynamic_lines}};
  }
  result.skipped_failures =
      streamed ? streamed->skipped_failures : count_skipped_failures(result.scene.manifest);
  report["skipped_failures"] = result.skipped_failures;
  result.report_json = report.dump(2) + "\n";
  if (!request.report.empty()) write_text_file(request.report, result.report_json);
}

// A whole build: read, project, clean, then build and write one package, or
// cut and write a tileset's tiles; a dry run stops after clean. The stages
// in order; the bookkeeping (times, peaks, estimates, the report) in the
// helpers above.
BuildResult run_stages(const BuildSpec& scene, const BuildRequest& request, MemoryTrail& trail) {
  if (request.step != BuildRequest::Step::all) return run_tileset_step(scene, request, trail);
  const auto t_all = Clock::now();
  if (!request.dry_run && request.output.empty())
    fail<usage_error>(kBuildStage, "no output path (-o)");
  const bool tiled = scene.tile_size > 0 && !request.dry_run;
  give_warnings(width_warnings(scene), request, trail);
  const std::unique_ptr<tbb::global_control> threads = cap_threads(scene);
  SourceProvenance provenance(scene);
  StageLog log(request, trail);
  log.estimate(before_read(scene, request));
  log.start();
  BuildResult result;
  // The tileset folder, held for the whole build; a build that fails
  // before its first tile removes only what it made, and SIGINT or SIGTERM
  // removes the work folder and the tileset folder if the build made it.
  std::optional<tiling::TilesetDir> tileset_dir;
  std::optional<OnInterrupt> undo;
  if (tiled) {
    tileset_dir.emplace(request.output, tiling::TilesetDir::Access::exclusive, true);
    undo.emplace("the tileset build was stopped", [dir = request.output,
                                                   made = tileset_dir->made()] {
      std::fprintf(stderr, "decalprep: %s\n", tiling::remove_after_interrupt(dir, made).c_str());
    });
  }
  const bool made_dir = tileset_dir && tileset_dir->made();
  std::optional<tiling::PreparedScene> streamed;
  std::optional<tiling::TilesetOutcome> tileset;
  if (tiled) {
    streamed = prepare_streamed(scene, request, made_dir, provenance, log, trail, result);
    tileset = build_tileset(scene, request, made_dir, log, trail);
    result.package_written = true;
  } else {
    read_project_clean(scene, request, log, trail, result);
    if (!request.dry_run && scene.tile_size <= 0) {
      log.estimate(estimate_after_clean(scene, result.scene));
      build_and_write(scene, request, provenance, log, trail, result);
    }
  }
  log.time("total", seconds_since(t_all));
  finish_report(scene, request, streamed, tileset, provenance, log, trail, result);
  return result;
}

// The files a build reads: the scene file, each layer's source, the DEM.
std::vector<std::string> scene_inputs(const BuildSpec& scene) {
  std::vector<std::string> in = {scene.scene_path, scene.dem};
  in.insert(in.end(), scene.dem_more.begin(), scene.dem_more.end());
  for (const LayerSpec& l : scene.layers) in.push_back(l.source);
  return in;
}

// The one rule for a build's inputs and outputs (prep/files.hpp), checked before
// anything is read: the package and the report are regular files or
// absent, and none is an input or the other; a tileset folder is no input.
void check_build_outputs(const BuildSpec& scene, const BuildRequest& request) {
  // Nothing below may block on an input (the sources are hashed for the
  // provenance and sized for --max-memory before GDAL opens them).
  check_input_file(scene.scene_path, "scene file");
  check_input_file(scene.dem, "DEM");
  for (const std::string& dem : scene.dem_more) check_input_file(dem, "DEM");
  for (const LayerSpec& l : scene.layers)
    check_input_file(l.source, "layer '" + l.name + "' source", InputKind::file_or_directory);
  std::vector<std::string> inputs = scene_inputs(scene);
  if (!request.dry_run && !request.output.empty()) {
    if (scene.tile_size > 0) {
      const std::optional<FileId> out = file_id(request.output);
      for (const std::string& in : inputs)
        if (!in.empty() && out && file_id(in) == out)
          fail<output_error>(kBuildStage, "the tileset folder '" + request.output +
                                              "' is the input '" + in + "' itself");
    } else {
      check_output_file(request.output, "package", inputs);
      inputs.push_back(request.output);
    }
  }
  if (!request.report.empty()) {
    check_output_file(request.report, "report", inputs);
    // Neither exists yet: compare where they would be.
    std::error_code e1, e2;
    if (!request.dry_run && !request.output.empty() &&
        std::filesystem::weakly_canonical(request.report, e1) ==
            std::filesystem::weakly_canonical(request.output, e2) &&
        !e1 && !e2)
      fail<usage_error>(kBuildStage, "the report '" + request.report + "' and the output '" +
                                         request.output + "' are the same file");
  }
}

}  // namespace

BuildResult run_build(const BuildSpec& scene, const BuildRequest& request) {
  check_build_outputs(scene, request);
  MemoryTrail trail;
  try {
    return run_stages(scene, request, trail);
  } catch (const error& e) {
    // CI reads the report even when the build fails: say why, with what was
    // measured and estimated up to the failure (a --max-memory stop names
    // its estimate), then rethrow.
    if (!request.report.empty()) {
      try {
        write_text_file(request.report, failed_report(e, request, trail).dump(2) + "\n");
      } catch (const error&) {
        // The original failure matters more than the report's.
      }
    }
    throw;
  }
}

}  // namespace prep
