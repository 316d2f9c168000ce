// decalprep build — SCENE.toml (or one GDAL source) -> .decals package, or a
// batch of scene files -> one package each. Thin: maps the options to
// prep::SceneRequest / prep::BuildRequest / prep::BatchRequest, calls
// prep::run_build or prep::run_batch (libprep/pipeline), and turns the
// results into messages and the exit code.
#include <sched.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>

#include "command.hpp"
#include "prep/files.hpp"
#include "prep/memory_estimate.hpp"
#include "prep/pipeline.hpp"
#include "prep/progress.hpp"
#include "prep/stage_error.hpp"

namespace {

struct BuildArgs {
  std::string input, output, report;
  std::vector<std::string> inputs;  // as given; several (or a folder): batch mode
  unsigned jobs = 0;                // --jobs; 0: not given (default_tile_jobs, or 1 in a batch)
  prep::FilelessLayer fileless;     // the file-less form's layer options
  // scene-wide overrides
  std::string crs, assume_crs, extent, extent_crs, grid;
  std::vector<std::string> dem;  // --dem, repeated for a mosaic
  std::optional<double> resolution, tile_size;
  std::string levels;
  std::string repair;
  std::optional<uint32_t> leaf_capacity, max_depth, threads;
  // terrain matching of dynamic lines (override the scene file's [build])
  std::optional<double> lmax, terrain_tolerance, z_scale, nodata_fill;
  int zstd_level = 2;
  std::string max_memory;  // --max-memory SIZE
  bool no_compress = false, dry_run = false, quiet = false, skip_failures = false;
  bool strict = false, allow_empty = false;
  std::string progress;  // --progress MODE; empty: auto, or none with --quiet
  // Tilesets as separate steps: --step prepare | tiles K/N | finalize, and
  // --plan N (write DIR/plan.json with the steps' command lines, N tile jobs).
  std::vector<std::string> step;
  std::optional<unsigned> plan;
};

// --progress as given, else auto (none with --quiet).
std::string progress_text(const BuildArgs& a) {
  return !a.progress.empty() ? a.progress : a.quiet ? "none" : "auto";
}

prep::SceneRequest scene_request(const BuildArgs& a, const std::string& input) {
  prep::SceneRequest r;
  r.input = input;
  r.layer = a.fileless;
  prep::SceneOverrides& o = r.overrides;
  o.crs = a.crs;
  o.assume_crs = a.assume_crs;
  o.extent = a.extent;
  o.extent_crs = a.extent_crs;
  o.dem = a.dem;
  o.grid = a.grid;
  o.repair = a.repair;
  o.resolution = a.resolution;
  o.tile_size = a.tile_size;
  o.levels = a.levels;
  o.leaf_capacity = a.leaf_capacity;
  o.max_depth = a.max_depth;
  o.threads = a.threads;
  o.lmax = a.lmax;
  o.terrain_tolerance = a.terrain_tolerance;
  o.z_scale = a.z_scale;
  o.nodata_fill = a.nodata_fill;
  o.skip_failures = a.skip_failures;
  o.allow_empty = a.allow_empty;
  return r;
}

// The tileset's tiles built side by side without --jobs: one per CPU this
// process may run on (its affinity mask: a Slurm step's cpuset, a taskset),
// or one with --max-memory (which checks each tile against the limit and
// stops rather than lowering). The bytes are the same either way.
unsigned default_tile_jobs(const BuildArgs& a) {
  if (!a.max_memory.empty()) return 1;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof set, &set) == 0 && CPU_COUNT(&set) > 0)
    return static_cast<unsigned>(CPU_COUNT(&set));
  return std::max(1u, std::thread::hardware_concurrency());
}

// Output, report and compression; max_memory and progress are the caller's.
prep::BuildRequest build_request(const BuildArgs& a) {
  prep::BuildRequest req;
  req.output = a.output;
  req.report = a.report;
  req.dry_run = a.dry_run;
  req.compress = !a.no_compress;
  req.zstd_level = a.zstd_level;
  req.jobs = a.jobs != 0 ? a.jobs : default_tile_jobs(a);
  req.strict = a.strict;
  return req;
}

// --step prepare | tiles K/N | finalize into the request.
void parse_step(const std::vector<std::string>& step, prep::BuildRequest& req) {
  using Step = prep::BuildRequest::Step;
  if (step.empty()) return;
  const std::string& name = step[0];
  if (name == "prepare" || name == "finalize") {
    if (step.size() != 1)
      prep::fail<prep::usage_error>(prep::kBuildStage,
                                    "--step " + name + " takes no part (" + step[1] + ")");
    req.step = name == "prepare" ? Step::prepare : Step::finalize;
    return;
  }
  unsigned k = 0, n = 0;
  char tail = 0;
  if (name != "tiles" || step.size() != 2 ||
      std::sscanf(step[1].c_str(), "%u/%u%c", &k, &n, &tail) != 2 || n == 0 || k >= n)
    prep::fail<prep::usage_error>(
        prep::kBuildStage, "--step is prepare, tiles K/N (0 <= K < N) or finalize, not '" + name +
                               (step.size() > 1 ? " " + step[1] : std::string()) + "'");
  req.step = Step::tiles;
  req.step_part = k;
  req.step_parts = n;
}

// --plan N: DIR/plan.json, the three steps of the tileset build with the
// exact command line of each (this command line without --plan, plus
// --step); the tile step's "{K}" is the job index 0..N-1. Runs nothing.
int write_plan(const BuildArgs& a, const prep::BuildSpec& scene) {
  if (scene.tile_size <= 0)
    prep::fail<prep::usage_error>(prep::kBuildStage, "--plan is for tilesets: give --tile-size");
  if (a.output.empty()) prep::fail<prep::usage_error>(prep::kBuildStage, "--plan needs -o DIR");
  if (*a.plan == 0)
    prep::fail<prep::usage_error>(prep::kBuildStage, "--plan N needs N >= 1 tile jobs");
  std::vector<std::string> base;
  const std::vector<std::string>& argv = decalprep::command_line();
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  base.push_back(ec ? argv.at(0) : self.string());
  for (size_t i = 1; i < argv.size(); ++i) {
    if (argv[i] == "--plan") {
      ++i;  // and its value
      continue;
    }
    if (argv[i].rfind("--plan=", 0) == 0) continue;
    base.push_back(argv[i]);
  }
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> c = base;
    c.insert(c.end(), extra.begin(), extra.end());
    return c;
  };
  const unsigned n = *a.plan;
  const nlohmann::json plan = {
      {"plan_version", 1},
      {"tileset", a.output},
      {"cwd", std::filesystem::current_path().string()},
      {"note",
       "Run in cwd on machines that see the tileset folder at the same path (a shared "
       "filesystem): prepare, then the N tiles jobs (in any order, side by side), then "
       "finalize. Each step may be run again."},
      {"steps",
       {{{"step", "prepare"}, {"command", with({"--step", "prepare"})}},
        {{"step", "tiles"},
         {"jobs", n},
         {"job_placeholder", "{K}"},
         {"command", with({"--step", "tiles", "{K}/" + std::to_string(n)})}},
        {{"step", "finalize"}, {"command", with({"--step", "finalize"})}}}}};
  std::filesystem::create_directories(a.output, ec);
  if (ec)
    prep::fail<prep::output_error>(prep::kBuildStage,
                                   "cannot create " + a.output + ": " + ec.message());
  const std::string path = a.output + "/plan.json";
  prep::check_output_file(path, "plan", {});
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << plan.dump(2) << "\n";
    if (!out) prep::fail<prep::output_error>(prep::kBuildStage, "cannot write " + tmp);
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec)
    prep::fail<prep::output_error>(prep::kBuildStage, "cannot write " + path + ": " + ec.message());
  if (!a.quiet)
    std::fprintf(stderr, "wrote %s (prepare, %u tiles jobs, finalize)\n", path.c_str(), n);
  return 0;
}

// --progress json: stderr carries JSON objects only; the summary is one.
void print_json_summary(const BuildArgs& a, const prep::BuildResult& result,
                        prep::Progress& progress) {
  const prep::LayerCounts t = prep::manifest_totals(result.scene.manifest);
  nlohmann::json totals = {{"read", t.read},
                           {"kept", t.kept},
                           {"repaired", t.repaired},
                           {"clipped_away", t.clipped_away},
                           {"dropped", t.dropped}};
  nlohmann::json summary = {{"event", "summary"},
                            {"features", totals},
                            {"frame", result.scene.frame.description},
                            {"package_written", result.package_written},
                            {"output", result.package_written ? a.output : ""},
                            {"report", a.report},
                            {"skipped_failures", result.skipped_failures}};
  progress.message(summary.dump());
}

void print_summary(const BuildArgs& a, const prep::BuildResult& result) {
  for (const prep::LayerCounts& c : result.scene.manifest.layers) {
    std::fprintf(stderr,
                 "  %-20s read %llu, kept %llu (repaired %llu), clipped away %llu, dropped %llu\n",
                 c.layer.c_str(), (unsigned long long)c.read, (unsigned long long)c.kept,
                 (unsigned long long)c.repaired, (unsigned long long)c.clipped_away,
                 (unsigned long long)c.dropped);
  }
  const prep::LayerCounts t = prep::manifest_totals(result.scene.manifest);
  std::fprintf(
      stderr,
      "decalprep build: %llu features read, %llu kept, %llu clipped away, %llu dropped; frame %s\n",
      (unsigned long long)t.read, (unsigned long long)t.kept, (unsigned long long)t.clipped_away,
      (unsigned long long)t.dropped, result.scene.frame.description.c_str());
  if (result.package_written) std::fprintf(stderr, "wrote %s\n", a.output.c_str());
  if (a.dry_run) std::fprintf(stderr, "dry run: no package written\n");
  if (!a.report.empty()) std::fprintf(stderr, "report %s\n", a.report.c_str());
}

// One scene.
int run(const BuildArgs& a) {
  // Before any thread starts: SIGINT and SIGTERM then undo what the build
  // made (prep/files.hpp) and exit 130 / 143.
  prep::watch_interrupts();
  const prep::BuildSpec scene = prep::scene_spec(scene_request(a, a.input));
  if (!a.dry_run && a.output.empty())
    prep::fail<prep::usage_error>(prep::kBuildStage, "-o OUT.decals is required (or --dry-run)");
  if (a.plan) return write_plan(a, scene);
  prep::BuildRequest req = build_request(a);
  parse_step(a.step, req);
  if (!a.max_memory.empty()) req.max_memory = prep::parse_memory_limit(a.max_memory);
  prep::ProgressOptions po;
  po.mode = prep::parse_progress_mode(progress_text(a), isatty(STDERR_FILENO) != 0);
  const bool json = po.mode == prep::ProgressMode::json;
  prep::Progress progress(po);
  req.progress = &progress;
  const prep::BuildResult result = prep::run_build(scene, req);

  if (req.step != prep::BuildRequest::Step::all) {
    // A step says what it did in its progress line; the counts are the
    // whole build's, in the tileset after finalize.
    if (!a.quiet && !json && !a.report.empty())
      std::fprintf(stderr, "report %s\n", a.report.c_str());
  } else if (json && !a.quiet) {
    print_json_summary(a, result, progress);
  } else if (!a.quiet) {
    print_summary(a, result);
  }
  const prep::ExitCode code = prep::build_exit_code(scene, result);
  if (code == prep::ExitCode::partial && !a.quiet && !json)
    std::fprintf(
        stderr,
        "decalprep build: --skip-failures dropped %zu failing features (see the manifest)\n",
        result.skipped_failures);
  return static_cast<int>(code);
}

// ------------------------------------------------------------ batch mode --
// Several scene files (or a folder of *.toml) -> OUTDIR/<stem>.decals each,
// every scene in its own process (prep::run_batch). The batch prints one
// line per scene as it ends and a closing line (--progress json: one object
// each); the scenes' progress is in their logs.

void print_scene_done(const BuildArgs& a, bool json, const prep::BatchScene& s, size_t done,
                      size_t total) {
  if (json)
    std::fprintf(stderr, "%s\n",
                 nlohmann::json({{"event", "scene"},
                                 {"scene", s.scene},
                                 {"status", s.status()},
                                 {"exit_code", s.exit_code},
                                 {"done", done},
                                 {"total", total},
                                 {"seconds", s.seconds},
                                 {"peak_rss_mib", s.peak_rss_kb / 1024.0},
                                 {"error", s.error},
                                 {"log", s.log}})
                     .dump()
                     .c_str());
  else if (!a.quiet && !s.failed())
    std::fprintf(stderr, "[%zu/%zu] %s: %s (%.2f s, peak %.1f MiB)\n", done, total, s.scene.c_str(),
                 s.partial() ? "built (partial)" : "built", s.seconds, s.peak_rss_kb / 1024.0);
  else if (!a.quiet)
    // Why it failed, on the line itself: the scene's error line (or how it
    // was killed), and the log that has the rest.
    std::fprintf(stderr, "[%zu/%zu] %s: FAILED, exit %d (%.2f s): %s; log %s\n", done, total,
                 s.scene.c_str(), s.exit_code, s.seconds,
                 s.error.empty() ? "no error line in the log" : s.error.c_str(), s.log.c_str());
}

int run_batch(const BuildArgs& a) {
  const std::string mode = progress_text(a);
  const bool json = mode == "json";
  prep::BatchRequest req;
  req.inputs = a.inputs;
  req.output_dir = a.output;
  req.summary = a.report;
  // Scenes side by side, and a tileset scene's tiles: as asked, else one.
  req.jobs = a.jobs != 0 ? a.jobs : 1;
  req.scene = scene_request(a, "");
  req.build = build_request(a);
  req.build.jobs = req.jobs;
  // Checked here, once, so that a bad size is a usage error of the batch,
  // not a failure of every scene.
  if (!a.max_memory.empty()) prep::parse_memory_limit(a.max_memory);
  req.max_memory = a.max_memory;
  // Each scene's log gets plain progress lines (json with --progress json).
  req.scene_progress =
      prep::parse_progress_mode(mode == "tty" || mode == "auto" ? "plain" : mode, false);
  req.on_jobs_lowered = [&](unsigned asked, unsigned jobs, double available_gib) {
    if (!a.quiet && !json)
      std::fprintf(stderr,
                   "decalprep build: --jobs %u lowered to %u: %.1f GiB available, --max-memory %s "
                   "per scene\n",
                   asked, jobs, available_gib, a.max_memory.c_str());
  };
  req.on_scene_done = [&](const prep::BatchScene& s, size_t done, size_t total) {
    print_scene_done(a, json, s, done, total);
  };
  const prep::BatchResult r = prep::run_batch(req);
  const size_t built = r.scenes.size() - r.failed;
  if (json)
    std::fprintf(stderr, "%s\n",
                 nlohmann::json({{"event", "summary"},
                                 {"built", built},
                                 {"failed", r.failed},
                                 {"partial", r.partial},
                                 {"total", r.scenes.size()},
                                 {"summary", r.summary}})
                     .dump()
                     .c_str());
  else if (!a.quiet)
    std::fprintf(stderr, "decalprep build: %zu of %zu scenes built; summary %s\n", built,
                 r.scenes.size(), r.summary.c_str());
  return r.exit_code;
}

constexpr decalprep::CommandHelp kBuildHelp{
    "build", "Build a .decals package from a scene file (SCENE.toml) or one GDAL source"};

const decalprep::CommandRegistrar kBuild(10, kBuildHelp, [](CLI::App* cmd) {
  auto args = std::make_shared<BuildArgs>();
  cmd->add_option("input", args->inputs,
                  "Scene file (.toml) or any GDAL vector source; several scene files or folders "
                  "of them: batch mode, -o is then a folder")
      ->required();
  cmd->add_option("--jobs", args->jobs,
                  "Batch mode: scenes built side by side (default 1); tileset: tiles built side "
                  "by side (default: one per CPU this process may use, 1 with --max-memory); "
                  "the bytes do not depend on it");
  cmd->add_option("-o,--output", args->output,
                  "Package to write (atomically); with --tile-size, the tileset directory");
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
  cmd->add_flag(
      "--skip-failures", args->skip_failures,
      "Drop a failing feature (recorded in the manifest) and go on; exit code 4 (partial)");
  cmd->add_option(
      "--max-memory", args->max_memory,
      "Stop early (exit 6) when the estimated peak memory exceeds SIZE, with its unit (2G, "
      "512M; 200B for bytes); batch mode: per scene");
  cmd->add_flag("--strict", args->strict,
                "Make a warning an error (exit 10): a layer that read no feature, dynamic-line "
                "heights taken outside the DEM; batch mode: every scene");
  cmd->add_flag("--allow-empty", args->allow_empty,
                "Write the package (exit 0) even when no layer kept a feature; without it such a "
                "build writes none and exits 9 (scene file: allow_empty = true)");
  cmd->add_option("--step", args->step,
                  "Tileset in steps (a cluster's jobs on a shared filesystem): prepare | tiles "
                  "K/N (the tiles i with i % N == K) | finalize; each may run again")
      ->expected(1, 2);
  cmd->add_option("--plan", args->plan,
                  "Tileset: write DIR/plan.json with the command lines of prepare, N tiles jobs "
                  "and finalize; build nothing");
  auto* g = "File-less form (one layer)";
  cmd->add_option("--layer", args->fileless.layer, "Source layer name (default: the first)")
      ->group(g);
  cmd->add_option("--where", args->fileless.where, "OGR attribute filter")->group(g);
  cmd->add_option("--sql", args->fileless.sql, "OGR SQL (replaces --layer/--where)")->group(g);
  cmd->add_option("--kind", args->fileless.kind, "polygon | line | outline | point")->group(g);
  cmd->add_option("--width", args->fileless.width,
                  "Line width: ground metres, or pixels with --dynamic")
      ->group(g);
  cmd->add_option("--corner", args->fileless.corner, "round | miter | bevel")->group(g);
  cmd->add_option("--outline-mode", args->fileless.outline_mode,
                  "normal | inset | offset (needs miter)")
      ->group(g);
  cmd->add_option("--color", args->fileless.color, "#rrggbb or #rrggbbaa")->group(g);
  cmd->add_option("--name", args->fileless.name, "Layer name (default: --layer, else layer0)")
      ->group(g);
  cmd->add_option("--color-attribute", args->fileless.color_attribute,
                  "Attribute whose value picks the colour from --color-ramp")
      ->group(g);
  cmd->add_option("--color-ramp", args->fileless.color_ramp,
                  "Colour ramp value:#rrggbb[aa],value:#rrggbb[aa],... (values increasing)")
      ->group(g);
  cmd->add_option("--dash", args->fileless.dash,
                  "Dash pattern on,off,... (metres; pixels with --dynamic); lines only")
      ->group(g);
  cmd->add_option("--casing-width", args->fileless.casing_width,
                  "A casing this much wider on each side of the lines (metres; pixels with "
                  "--dynamic)")
      ->group(g);
  cmd->add_option("--casing-color", args->fileless.casing_color,
                  "Casing colour #rrggbb[aa] (default: the line colour at 60% brightness)")
      ->group(g);
  cmd->add_flag("--dynamic", args->fileless.dynamic,
                "Dynamic lines: width in pixels, terrain-matched")
      ->group(g);
  auto* s = "Scene (override the scene file)";
  cmd->add_option("--crs", args->crs,
                  "Scene frame CRS (PROJ/EPSG/WKT); default chosen from the data's extent (local "
                  "TM, oblique stereographic or Equal Earth; docs/build.md \"The scene frame\")")
      ->group(s);
  cmd->add_option("--assume-crs", args->assume_crs,
                  "CRS for sources and a DEM that have none (otherwise an error)")
      ->group(s);
  cmd->add_option("--extent", args->extent,
                  "Clip extent xmin,ymin,xmax,ymax, absolute coordinates of the frame CRS (as "
                  "render --extent)")
      ->group(s);
  cmd->add_option("--extent-crs", args->extent_crs, "CRS of --extent (default: the frame)")
      ->group(s);
  cmd->add_option("--resolution", args->resolution,
                  "Simplification tolerance, metres (0: keep all)")
      ->group(s);
  cmd->add_option("--dem", args->dem,
                  "DEM raster (GDAL path; its CRS, else --assume-crs); clips to its extent; "
                  "repeat it to mosaic several")
      ->allow_extra_args(false)
      ->group(s);
  cmd->add_option(
         "--repair", args->repair,
         "Invalid polygons: linework (GEOS default, even-odd) | structure (every hole subtracted)")
      ->group(s);
  cmd->add_option("--tile-size", args->tile_size,
                  "Write a tileset: square tiles of this many frame metres, one package each "
                  "with its own origin, no span limit (scene file: [tiling] tile_size)")
      ->group(s);
  cmd->add_option("--levels", args->levels,
                  "Tileset overview levels: N (0-16) or auto (until one level covers the data "
                  "with <= 4 tiles); level L: tiles of tile-size*2^L simplified to "
                  "tile-size*2^L/1024 m (scene file: [tiling] levels; default 0)")
      ->group(s);
  auto* t = "Terrain (dynamic lines; override the scene file)";
  cmd->add_option("--lmax", args->lmax,
                  "Longest terrain-matched segment, metres (0: half the DEM cell)")
      ->group(t);
  cmd->add_option("--terrain-tolerance", args->terrain_tolerance,
                  "Adaptive subdivision tolerance, metres (0: uniform)")
      ->group(t);
  cmd->add_option("--z-scale", args->z_scale, "Height exaggeration (default 1)")->group(t);
  cmd->add_option("--nodata-fill", args->nodata_fill,
                  "Height for DEM no-data cells, raw DEM units (default: the nearest valid cell)")
      ->group(t);
  auto* b = "Build";
  cmd->add_option("--grid", args->grid, "Decal grid NXxNY (500x500 = thesis) or auto")->group(b);
  cmd->add_option("--leaf-capacity", args->leaf_capacity, "Quad-tree leaf capacity (thesis: 8)")
      ->group(b);
  cmd->add_option("--max-depth", args->max_depth, "Quad-tree max depth (thesis: 8)")->group(b);
  cmd->add_option("--threads", args->threads, "Worker threads (0: all); output is identical")
      ->group(b);
  cmd->add_option("--zstd-level", args->zstd_level, "zstd level (default 2)")->group(b);
  cmd->add_flag("--no-compress", args->no_compress, "Store blobs uncompressed (memory-mappable)")
      ->group(b);
  cmd->callback([args] {
    std::error_code ec;
    const bool batch =
        args->inputs.size() > 1 || std::filesystem::is_directory(args->inputs[0], ec);
    if (batch) {
      if (!args->step.empty() || args->plan)
        prep::fail<prep::usage_error>(prep::kBuildStage,
                                      "--step and --plan take one scene, not a batch");
      decalprep::set_exit_code(run_batch(*args));
      return;
    }
    args->input = args->inputs[0];
    decalprep::set_exit_code(run(*args));
  });
});

}  // namespace
