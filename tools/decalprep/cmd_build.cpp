// decalprep build — SCENE.toml (or one GDAL source) -> .decals package.
// Thin: parses options into a SceneSpec and calls prep::run_build.
#include <unistd.h>

#include <cstdio>
#include <memory>
#include <sstream>

#include "command.hpp"
#include "prep/pipeline.hpp"
#include "prep/scene_file.hpp"

namespace {

struct BuildArgs {
  std::string input, output, report;
  // file-less layer options
  std::string layer, where, sql, kind, corner, outline_mode, color;
  std::optional<double> width;
  bool dynamic = false;
  // scene-wide overrides
  std::string crs, assume_crs, extent, extent_crs, dem, grid;
  std::optional<double> resolution;
  std::optional<uint32_t> leaf_capacity, max_depth, threads;
  int zstd_level = 3;
  bool no_compress = false, dry_run = false, quiet = false;
};

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
  if (!a.grid.empty()) parse_grid(a.grid, scene.build);
  if (a.leaf_capacity) scene.build.qt_leaf_capacity = *a.leaf_capacity;
  if (a.max_depth) scene.build.qt_max_depth = *a.max_depth;
  if (a.threads) scene.build.threads = *a.threads;

  if (!a.dry_run && a.output.empty()) throw prep::usage_error("build: -o OUT.decals is required (or --dry-run)");

  prep::BuildRequest req;
  req.output = a.output;
  req.report = a.report;
  req.dry_run = a.dry_run;
  req.compress = !a.no_compress;
  req.zstd_level = a.zstd_level;
  if (!a.quiet) req.progress = prep::make_console_progress();
  prep::BuildResult result = prep::run_build(scene, req);

  if (!a.quiet) {
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
  return static_cast<int>(prep::ExitCode::ok);
}

const decalprep::CommandRegistrar kBuild(10, [](CLI::App& app) {
  auto args = std::make_shared<BuildArgs>();
  CLI::App* cmd = app.add_subcommand(
      "build", "Build a .decals package from a scene file (SCENE.toml) or one GDAL source");
  cmd->add_option("input", args->input, "Scene file (.toml) or any GDAL vector source")->required();
  cmd->add_option("-o,--output", args->output, "Package to write (atomically)");
  cmd->add_option("--report", args->report, "Write the JSON report (counts, manifest, timings)");
  cmd->add_flag("--dry-run", args->dry_run, "Stop after clean: write the report, no package");
  cmd->add_flag("-q,--quiet", args->quiet, "No progress or summary on stderr");
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
  cmd->add_option("--assume-crs", args->assume_crs, "CRS for sources that have none")->group(s);
  cmd->add_option("--extent", args->extent, "Clip extent xmin,ymin,xmax,ymax")->group(s);
  cmd->add_option("--extent-crs", args->extent_crs, "CRS of --extent (default: the frame)")->group(s);
  cmd->add_option("--resolution", args->resolution, "Simplification tolerance, metres (0: keep all)")->group(s);
  cmd->add_option("--dem", args->dem, "DEM raster (GDAL path); clips to its extent")->group(s);
  auto* b = "Build";
  cmd->add_option("--grid", args->grid, "Decal grid NXxNY (500x500 = thesis) or auto")->group(b);
  cmd->add_option("--leaf-capacity", args->leaf_capacity, "Quad-tree leaf capacity (thesis: 8)")->group(b);
  cmd->add_option("--max-depth", args->max_depth, "Quad-tree max depth (thesis: 8)")->group(b);
  cmd->add_option("--threads", args->threads, "Worker threads (0: all); output is identical")->group(b);
  cmd->add_option("--zstd-level", args->zstd_level, "zstd level (default 3)")->group(b);
  cmd->add_flag("--no-compress", args->no_compress, "Store blobs uncompressed (memory-mappable)")->group(b);
  cmd->callback([args] { decalprep::set_exit_code(run(*args)); });
});

}  // namespace
