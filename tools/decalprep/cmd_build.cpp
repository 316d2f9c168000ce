// decalprep build — SCENE.toml (or one GDAL source) -> .decals package.
// Thin: parses options into a SceneSpec and calls prep::run_build.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "command.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/pipeline.hpp"
#include "prep/progress.hpp"
#include "prep/scene_file.hpp"

namespace {

struct BuildArgs {
  std::string input, output, report;
  std::vector<std::string> inputs;  // as given; several (or a folder): batch mode
  unsigned jobs = 1;
  // file-less layer options
  std::string layer, where, sql, kind, corner, outline_mode, color;
  std::optional<double> width;
  bool dynamic = false;
  // scene-wide overrides
  std::string crs, assume_crs, extent, extent_crs, dem, grid;
  std::optional<double> resolution;
  std::string repair;
  std::optional<uint32_t> leaf_capacity, max_depth, threads;
  // terrain matching of dynamic lines (override the scene file's [build])
  std::optional<double> lmax, terrain_tolerance, z_scale, nodata_fill;
  int zstd_level = 3;
  std::string max_memory;  // --max-memory SIZE
  bool no_compress = false, dry_run = false, quiet = false, skip_failures = false;
  std::string progress;  // --progress MODE; empty: auto, or none with --quiet
};

// --progress as given, else auto (none with --quiet).
std::string progress_text(const BuildArgs& a) {
  return !a.progress.empty() ? a.progress : a.quiet ? "none" : "auto";
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

prep::Extent parse_extent(const std::string& text) {
  prep::Extent e;
  char c1 = 0, c2 = 0, c3 = 0;
  std::istringstream in(text);
  if (!(in >> e.xmin >> c1 >> e.ymin >> c2 >> e.xmax >> c3 >> e.ymax) || c1 != ',' || c2 != ',' ||
      c3 != ',' || e.empty()) {
    throw prep::usage_error("--extent: expected xmin,ymin,xmax,ymax with max > min, got \"" +
                            text + "\"");
  }
  return e;
}

void parse_grid(const std::string& text, prep::BuildOptions& b) {
  if (text == "auto") {
    b.grid_nx = b.grid_ny = 0;
    return;
  }
  unsigned nx = 0, ny = 0;
  char x = 0;
  std::istringstream in(text);
  if (!(in >> nx >> x >> ny) || (x != 'x' && x != 'X') || nx == 0 || ny == 0 || nx > 65536 ||
      ny > 65536) {
    throw prep::usage_error("--grid: expected NXxNY (e.g. 500x500) or auto, got \"" + text + "\"");
  }
  b.grid_nx = nx;
  b.grid_ny = ny;
}

int run(const BuildArgs& a) {
  prep::SceneSpec scene;
  const bool scene_file = ends_with(a.input, ".toml");
  if (scene_file) {
    if (!a.layer.empty() || !a.where.empty() || !a.sql.empty() || !a.kind.empty() ||
        a.width || !a.corner.empty() || !a.outline_mode.empty() || !a.color.empty() || a.dynamic) {
      throw prep::usage_error(
          "build: --layer/--where/--sql/--kind/--width/--corner/--outline-mode/--color/--dynamic "
          "describe the single layer of the file-less form; with a scene file set them in " +
          a.input);
    }
    scene = prep::load_scene_file(a.input);
  } else {
    prep::LayerSpec l;
    l.source = a.input;
    l.layer = a.layer;
    l.where = a.where;
    l.sql = a.sql;
    l.name = !a.layer.empty() ? a.layer : "layer0";
    l.kind = a.kind.empty() ? prep::DecalKind::polygon : prep::parse_kind(a.kind);
    l.dynamic = a.dynamic;
    if (!a.corner.empty()) l.style.corner = prep::parse_corner(a.corner);
    if (!a.outline_mode.empty()) l.style.outline = prep::parse_outline_mode(a.outline_mode);
    if (!a.color.empty()) l.style.color.rgba = prep::parse_color(a.color);
    if (a.width) {
      if (!(*a.width > 0)) throw prep::usage_error("--width: must be > 0");
      l.style.width = *a.width;
    } else if (l.dynamic) {
      l.style.width = 3.0;  // pixels
    }
    if (l.dynamic && l.kind == prep::DecalKind::polygon)
      throw prep::usage_error("--dynamic needs --kind line or outline");
    if (!l.sql.empty() && (!l.where.empty() || !l.layer.empty()))
      throw prep::usage_error("--sql replaces --layer and --where; give one or the other");
    if (l.style.outline != decal::OutlineMode::normal && l.style.corner != decal::CornerStyle::miter)
      throw prep::usage_error("--outline-mode inset/offset needs --corner miter");
    scene.layers.push_back(l);
  }
  // Command-line values override the scene file's.
  if (!a.crs.empty()) scene.crs = a.crs;
  if (!a.assume_crs.empty()) scene.assume_crs = a.assume_crs;
  if (!a.extent.empty()) scene.extent = parse_extent(a.extent);
  if (!a.extent_crs.empty()) scene.extent_crs = a.extent_crs;
  if (!a.extent_crs.empty() && !scene.extent)
    throw prep::usage_error("--extent-crs needs --extent");
  if (!a.dem.empty()) scene.dem = a.dem;
  if (a.resolution) {
    if (!(*a.resolution >= 0)) throw prep::usage_error("--resolution: must be >= 0 metres");
    scene.resolution = *a.resolution;
  }
  if (!a.repair.empty()) scene.repair = prep::parse_repair_method(a.repair);
  if (!a.grid.empty()) parse_grid(a.grid, scene.build);
  if (a.leaf_capacity) scene.build.qt_leaf_capacity = *a.leaf_capacity;
  if (a.max_depth) scene.build.qt_max_depth = *a.max_depth;
  if (a.threads) scene.build.threads = *a.threads;
  if (a.skip_failures) scene.skip_failures = true;
  if (a.lmax) {
    if (!(*a.lmax >= 0)) throw prep::usage_error("--lmax: must be >= 0 metres (0: half the DEM cell)");
    scene.build.lmax = *a.lmax;
  }
  if (a.terrain_tolerance) {
    if (!(*a.terrain_tolerance >= 0))
      throw prep::usage_error("--terrain-tolerance: must be >= 0 metres (0: uniform subdivision)");
    scene.build.terrain_tolerance = *a.terrain_tolerance;
  }
  if (a.z_scale) {
    if (!std::isfinite(*a.z_scale)) throw prep::usage_error("--z-scale: must be a finite number");
    scene.build.z_scale = *a.z_scale;
  }
  if (a.nodata_fill) {
    if (!std::isfinite(*a.nodata_fill)) throw prep::usage_error("--nodata-fill: must be a finite height");
    scene.build.nodata_fill = *a.nodata_fill;
  }

  if (!a.dry_run && a.output.empty()) throw prep::usage_error("build: -o OUT.decals is required (or --dry-run)");

  prep::BuildRequest req;
  req.output = a.output;
  req.report = a.report;
  req.dry_run = a.dry_run;
  req.compress = !a.no_compress;
  req.zstd_level = a.zstd_level;
  if (!a.max_memory.empty()) req.max_memory = prep::parse_memory_size(a.max_memory);
  prep::ProgressOptions po;
  po.mode = prep::parse_progress_mode(progress_text(a), isatty(STDERR_FILENO) != 0);
  const bool json = po.mode == prep::ProgressMode::json;
  prep::Progress progress(po);
  req.progress = &progress;
  prep::BuildResult result = prep::run_build(scene, req);

  if (json && !a.quiet) {
    // --progress json: stderr carries JSON objects only; the summary is one.
    nlohmann::json totals = {
        {"read", 0}, {"kept", 0}, {"repaired", 0}, {"clipped_away", 0}, {"dropped", 0}};
    for (const prep::LayerCounts& c : result.scene.manifest.layers) {
      totals["read"] = totals["read"].get<uint64_t>() + c.read;
      totals["kept"] = totals["kept"].get<uint64_t>() + c.kept;
      totals["repaired"] = totals["repaired"].get<uint64_t>() + c.repaired;
      totals["clipped_away"] = totals["clipped_away"].get<uint64_t>() + c.clipped_away;
      totals["dropped"] = totals["dropped"].get<uint64_t>() + c.dropped;
    }
    nlohmann::json summary = {{"event", "summary"},
                              {"features", totals},
                              {"frame", result.scene.frame.description},
                              {"package_written", result.package_written},
                              {"output", result.package_written ? a.output : ""},
                              {"report", a.report},
                              {"skipped_failures", result.skipped_failures}};
    progress.message(summary.dump());
  } else if (!a.quiet) {
    uint64_t read = 0, kept = 0, clipped = 0, dropped = 0, repaired = 0;
    for (const prep::LayerCounts& c : result.scene.manifest.layers) {
      read += c.read;
      kept += c.kept;
      clipped += c.clipped_away;
      dropped += c.dropped;
      repaired += c.repaired;
      std::fprintf(stderr, "  %-20s read %llu, kept %llu (repaired %llu), clipped away %llu, dropped %llu\n",
                   c.layer.c_str(), (unsigned long long)c.read, (unsigned long long)c.kept,
                   (unsigned long long)c.repaired, (unsigned long long)c.clipped_away,
                   (unsigned long long)c.dropped);
    }
    std::fprintf(stderr, "decalprep build: %llu features read, %llu kept, %llu clipped away, %llu dropped; frame %s\n",
                 (unsigned long long)read, (unsigned long long)kept, (unsigned long long)clipped,
                 (unsigned long long)dropped, result.scene.frame.description.c_str());
    if (result.package_written) std::fprintf(stderr, "wrote %s\n", a.output.c_str());
    if (a.dry_run) std::fprintf(stderr, "dry run: no package written\n");
    if (!a.report.empty()) std::fprintf(stderr, "report %s\n", a.report.c_str());
  }
  // --skip-failures: features that would have stopped the build (OGR
  // decode, PROJ, GEOS, out of the build's range: prep/feature_failure.hpp)
  // were dropped and recorded; the package is partial (ogr2ogr -skipfailures).
  if (scene.skip_failures) {
    const size_t skipped = result.skipped_failures;
    if (skipped > 0) {
      if (!a.quiet && !json)
        std::fprintf(stderr, "decalprep build: --skip-failures dropped %zu failing features (see the manifest)\n",
                     skipped);
      return static_cast<int>(prep::ExitCode::partial);
    }
  }
  return static_cast<int>(prep::ExitCode::ok);
}

// ------------------------------------------------------------ batch mode --
// Several scene files (or a folder of *.toml) -> OUTDIR/<stem>.decals each.
// Every scene builds in its own forked child (at most --jobs at once), so a
// crash or an out-of-memory kill in one leaves the others running and the
// kernel's rusage gives each package's peak memory. One summary JSON
// (--report, default OUTDIR/summary.json) lists status, exit code, error,
// counts, wall time and peak RSS per scene; the exit code is that of the
// first failed scene (input order), else 4 (partial) when --skip-failures
// dropped features in some scene, 0 when all built.

struct BatchItem {
  std::string scene, output, report, log;
  pid_t pid = -1;
  int exit_code = -1;
  double seconds = 0;
  long peak_rss_kb = 0;
  std::chrono::steady_clock::time_point start;
};

std::string last_line(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "r");
  if (!f) return "";
  std::string all, line, last;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0) all.append(buf, n);
  std::fclose(f);
  std::istringstream in(all);
  // The scene's error line ("decalprep: ..."), else the last line that is not
  // progress (plain: a '%' or "elapsed" at the end; json: an object), such as
  // the watchdog's naming of a feature a killed scene was stuck on.
  std::string error;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line.rfind("decalprep: ", 0) == 0) error = line;
    const bool progress = line.find('%') != std::string::npos || line.front() == '{' ||
                          (line.size() >= 8 && line.compare(line.size() - 8, 8, " elapsed") == 0);
    if (!progress) last = line;
  }
  return error.empty() ? last : error;
}

constexpr int kPartial = static_cast<int>(prep::ExitCode::partial);

int run_batch(const BuildArgs& a) {
  namespace fs = std::filesystem;
  if (a.output.empty()) throw prep::usage_error("build: batch mode needs -o OUTDIR");
  std::vector<std::string> scenes;
  for (const std::string& in : a.inputs) {
    std::error_code ec;
    if (fs::is_directory(in, ec)) {
      std::vector<std::string> found;
      for (const auto& e : fs::directory_iterator(in))
        if (e.path().extension() == ".toml") found.push_back(e.path().string());
      std::sort(found.begin(), found.end());
      if (found.empty()) throw prep::usage_error("build: folder " + in + " has no *.toml scene files");
      scenes.insert(scenes.end(), found.begin(), found.end());
    } else if (ends_with(in, ".toml")) {
      scenes.push_back(in);
    } else {
      throw prep::usage_error("build: batch mode takes scene files (.toml) or folders of them; got " + in);
    }
  }
  std::error_code ec;
  fs::create_directories(a.output, ec);
  if (!fs::is_directory(a.output)) throw prep::output_error("build: cannot create output folder " + a.output);
  std::vector<BatchItem> items(scenes.size());
  std::set<std::string> stems;
  for (size_t i = 0; i < scenes.size(); ++i) {
    std::string stem = fs::path(scenes[i]).stem().string();
    if (!stems.insert(stem).second)
      throw prep::usage_error("build: two scenes would both write " + stem + ".decals; rename one");
    items[i].scene = scenes[i];
    items[i].output = (fs::path(a.output) / (stem + ".decals")).string();
    items[i].report = (fs::path(a.output) / (stem + ".report.json")).string();
    items[i].log = (fs::path(a.output) / (stem + ".log")).string();
  }
  // --progress json: the batch's own lines are JSON objects too (one per
  // scene as it ends, then the batch); the scenes' progress is in their logs.
  const bool json = progress_text(a) == "json";
  unsigned jobs = std::max(1u, a.jobs);
  // --max-memory is per scene: run no more scenes side by side than the
  // memory the kernel reports available holds at that limit each.
  if (!a.max_memory.empty()) {
    const uint64_t per_job = prep::parse_memory_size(a.max_memory);
    uint64_t available_kb = 0;
    std::ifstream meminfo("/proc/meminfo");
    std::string key;
    uint64_t value = 0;
    std::string unit;
    while (meminfo >> key >> value >> unit)
      if (key == "MemAvailable:") available_kb = value;
    if (available_kb > 0) {
      const uint64_t fit = std::max<uint64_t>(1, available_kb * 1024 / per_job);
      if (fit < jobs) {
        if (!a.quiet && !json)
          std::fprintf(stderr, "decalprep build: --jobs %u lowered to %llu: %.1f GiB available, --max-memory %s per scene\n",
                       jobs, (unsigned long long)fit, available_kb / 1048576.0, a.max_memory.c_str());
        jobs = unsigned(fit);
      }
    }
  }
  size_t next = 0, running = 0, finished = 0;
  std::fflush(nullptr);
  while (next < items.size() || running > 0) {
    while (running < jobs && next < items.size()) {
      BatchItem& it = items[next++];
      it.start = std::chrono::steady_clock::now();
      const pid_t pid = fork();
      if (pid < 0) throw prep::error("build: fork failed", prep::ExitCode::internal);
      if (pid == 0) {
        // Child: one ordinary single-scene build, its stderr in the log.
        if (std::FILE* log = std::freopen(it.log.c_str(), "w", stderr)) (void)log;
        int code = static_cast<int>(prep::ExitCode::internal);
        try {
          BuildArgs one = a;
          one.inputs.clear();
          one.input = it.scene;
          one.output = it.output;
          one.report = it.report;
          one.quiet = true;
          // The log gets the scene's progress (plain lines unless json),
          // and the watchdog's lines.
          const std::string mode = progress_text(a);
          one.progress = mode == "tty" || mode == "auto" ? "plain" : mode;
          code = run(one);
        } catch (const prep::error& e) {
          std::fprintf(stderr, "decalprep: %s\n", e.what());
          code = static_cast<int>(e.code());
        } catch (const std::bad_alloc&) {
          std::fprintf(stderr, "decalprep: out of memory\n");
          code = static_cast<int>(prep::ExitCode::resource);
        } catch (const std::exception& e) {
          std::fprintf(stderr, "decalprep: internal error: %s\n", e.what());
        }
        std::fflush(nullptr);
        _exit(code);
      }
      it.pid = pid;
      ++running;
    }
    int status = 0;
    struct rusage ru {};
    const pid_t done = wait4(-1, &status, 0, &ru);
    if (done < 0) break;
    for (BatchItem& it : items) {
      if (it.pid != done) continue;
      it.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - it.start).count();
      it.peak_rss_kb = ru.ru_maxrss;
      it.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      --running;
      ++finished;
      const char* outcome = it.exit_code == 0          ? "built"
                            : it.exit_code == kPartial ? "partial"
                                                       : "failed";
      if (json)
        std::fprintf(stderr, "%s\n",
                     nlohmann::json({{"event", "scene"},
                                     {"scene", it.scene},
                                     {"status", outcome},
                                     {"exit_code", it.exit_code},
                                     {"done", finished},
                                     {"total", items.size()},
                                     {"seconds", it.seconds},
                                     {"peak_rss_mib", it.peak_rss_kb / 1024.0},
                                     {"log", it.log}})
                         .dump()
                         .c_str());
      else if (!a.quiet)
        std::fprintf(stderr, "[%zu/%zu] %s: %s (%.2f s, peak %.1f MiB)\n", finished, items.size(),
                     it.scene.c_str(),
                     it.exit_code == 0          ? "built"
                     : it.exit_code == kPartial ? "built (partial)"
                                                : "FAILED",
                     it.seconds, it.peak_rss_kb / 1024.0);
    }
  }
  nlohmann::json summary;
  int first_fail = 0;
  size_t failed = 0, partial = 0;
  for (const BatchItem& it : items) {
    nlohmann::json e{{"scene", it.scene},
                     {"status", it.exit_code == 0 ? "built" : it.exit_code == kPartial ? "partial" : "failed"},
                     {"exit_code", it.exit_code},
                     {"seconds", it.seconds},
                     {"peak_rss_mib", it.peak_rss_kb / 1024.0}};
    // Partial: --skip-failures dropped features; the package was written.
    if (it.exit_code == kPartial) ++partial;
    if (it.exit_code == 0 || it.exit_code == kPartial) {
      e["output"] = it.output;
      e["report"] = it.report;
      std::ifstream rin(it.report);
      const nlohmann::json r = nlohmann::json::parse(rin, nullptr, false);
      if (r.is_object() && r.contains("manifest")) e["counts"] = r["manifest"].value("totals", nlohmann::json());
    } else {
      e["error"] = last_line(it.log);
      e["log"] = it.log;
      ++failed;
      if (first_fail == 0) first_fail = it.exit_code;
    }
    summary["packages"].push_back(e);
  }
  summary["built"] = items.size() - failed;
  summary["failed"] = failed;
  summary["partial"] = partial;
  summary["jobs"] = jobs;
  const std::string path = a.report.empty() ? (fs::path(a.output) / "summary.json").string() : a.report;
  std::ofstream out(path);
  out << summary.dump(2) << "\n";
  if (!out) throw prep::output_error("build: cannot write the batch summary " + path);
  if (json)
    std::fprintf(stderr, "%s\n",
                 nlohmann::json({{"event", "summary"},
                                 {"built", items.size() - failed},
                                 {"failed", failed},
                                 {"partial", partial},
                                 {"total", items.size()},
                                 {"summary", path}})
                     .dump()
                     .c_str());
  else if (!a.quiet)
    std::fprintf(stderr, "decalprep build: %zu of %zu scenes built; summary %s\n", items.size() - failed,
                 items.size(), path.c_str());
  return first_fail != 0 ? first_fail : partial > 0 ? kPartial : 0;
}

const decalprep::CommandRegistrar kBuild(10, [](CLI::App& app) {
  auto args = std::make_shared<BuildArgs>();
  CLI::App* cmd = app.add_subcommand(
      "build", "Build a .decals package from a scene file (SCENE.toml) or one GDAL source");
  cmd->add_option("input", args->inputs,
                  "Scene file (.toml) or any GDAL vector source; several scene files or folders "
                  "of them: batch mode, -o is then a folder")->required();
  cmd->add_option("--jobs", args->jobs, "Batch mode: scenes built side by side (default 1)");
  cmd->add_option("-o,--output", args->output, "Package to write (atomically)");
  cmd->add_option("--report", args->report, "Write the JSON report (counts, manifest, timings)");
  cmd->add_flag("--dry-run", args->dry_run, "Stop after clean: write the report, no package");
  cmd->add_flag("-q,--quiet", args->quiet,
                "No progress or summary on stderr (unless --progress is given)");
  cmd->add_option(
         "--progress", args->progress,
         "Progress on stderr: auto (default: tty on a terminal, else plain) | tty (one redrawn "
         "line per stage) | plain (a line per stage every 5 s and at its end) | json (one "
         "object per line) | none. A feature in GEOS for over 30 s is named. Batch mode: "
         "in each scene's log")
      ->check(CLI::IsMember({"auto", "tty", "plain", "json", "none"}));
  cmd->add_flag("--skip-failures", args->skip_failures,
                "Drop a failing feature (recorded in the manifest) and go on; exit code 4 (partial)");
  cmd->add_option("--max-memory", args->max_memory,
                  "Stop early (exit 6) when the estimated peak memory exceeds SIZE (e.g. 2G, 512M); "
                  "batch mode: per scene");
  auto* g = "File-less form (one layer)";
  cmd->add_option("--layer", args->layer, "Source layer name (default: the first)")->group(g);
  cmd->add_option("--where", args->where, "OGR attribute filter")->group(g);
  cmd->add_option("--sql", args->sql, "OGR SQL (replaces --layer/--where)")->group(g);
  cmd->add_option("--kind", args->kind, "polygon | line | outline")->group(g);
  cmd->add_option("--width", args->width, "Line width: ground metres, or pixels with --dynamic")->group(g);
  cmd->add_option("--corner", args->corner, "round | miter | bevel")->group(g);
  cmd->add_option("--outline-mode", args->outline_mode, "normal | inset | offset (needs miter)")->group(g);
  cmd->add_option("--color", args->color, "#rrggbb or #rrggbbaa")->group(g);
  cmd->add_flag("--dynamic", args->dynamic, "Dynamic lines: width in pixels, terrain-matched")->group(g);
  auto* s = "Scene (override the scene file)";
  cmd->add_option("--crs", args->crs, "Scene frame CRS (PROJ/EPSG/WKT); default local TM")->group(s);
  cmd->add_option("--assume-crs", args->assume_crs, "CRS for sources and a DEM that have none (otherwise an error)")->group(s);
  cmd->add_option("--extent", args->extent,
                  "Clip extent xmin,ymin,xmax,ymax, absolute coordinates of the frame CRS (as "
                  "render --extent)")
      ->group(s);
  cmd->add_option("--extent-crs", args->extent_crs, "CRS of --extent (default: the frame)")->group(s);
  cmd->add_option("--resolution", args->resolution, "Simplification tolerance, metres (0: keep all)")->group(s);
  cmd->add_option("--dem", args->dem, "DEM raster (GDAL path; its CRS, else --assume-crs); clips to its extent")->group(s);
  cmd->add_option("--repair", args->repair,
                  "Invalid polygons: linework (GEOS default, even-odd) | structure (every hole subtracted)")
      ->group(s);
  auto* t = "Terrain (dynamic lines; override the scene file)";
  cmd->add_option("--lmax", args->lmax, "Longest terrain-matched segment, metres (0: half the DEM cell)")->group(t);
  cmd->add_option("--terrain-tolerance", args->terrain_tolerance,
                  "Adaptive subdivision tolerance, metres (0: uniform)")->group(t);
  cmd->add_option("--z-scale", args->z_scale, "Height exaggeration (default 1)")->group(t);
  cmd->add_option("--nodata-fill", args->nodata_fill,
                  "Height for DEM no-data cells, raw DEM units (default: the nearest valid cell)")->group(t);
  auto* b = "Build";
  cmd->add_option("--grid", args->grid, "Decal grid NXxNY (500x500 = thesis) or auto")->group(b);
  cmd->add_option("--leaf-capacity", args->leaf_capacity, "Quad-tree leaf capacity (thesis: 8)")->group(b);
  cmd->add_option("--max-depth", args->max_depth, "Quad-tree max depth (thesis: 8)")->group(b);
  cmd->add_option("--threads", args->threads, "Worker threads (0: all); output is identical")->group(b);
  cmd->add_option("--zstd-level", args->zstd_level, "zstd level (default 3)")->group(b);
  cmd->add_flag("--no-compress", args->no_compress, "Store blobs uncompressed (memory-mappable)")->group(b);
  cmd->callback([args] {
    std::error_code ec;
    const bool batch = args->inputs.size() > 1 || std::filesystem::is_directory(args->inputs[0], ec);
    if (batch) {
      decalprep::set_exit_code(run_batch(*args));
      return;
    }
    args->input = args->inputs[0];
    decalprep::set_exit_code(run(*args));
  });
});

}  // namespace
